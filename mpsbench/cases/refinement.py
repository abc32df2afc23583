"""Refinement sets in a case's records, and the numerical uncertainty u_num of each run's metrics
(docs/method.md section 9; the formulas are :mod:`mpsbench.cases.uncertainty`).

A case declares its refinement sets with :class:`Refinement` (``Case.refinements``): which
parameter is refined (``l0``, or a time-step parameter such as ``dt``, ``cfl`` or ``c_nu``),
which metrics, the theoretical order used when only two levels exist, and the parameters that
do not change those metrics (``dt_check``, ``steady``...).  Its tiers hold the runs: every
group of runs of one solver that differ only in the refined parameter is a set (two levels or
more).  A set whose run at a finer level diverged or failed is "incomplete", so not converged:
at that step the model did not even run through (a run that fails only at a coarser step than
every completed one marks a stability limit and is left out).  :class:`NumericalUncertainty`
finds the sets and gives, for a run and a metric, u_num from each set the run belongs to (space
and time components added in quadrature), or says "not converged" or "not measured".
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from mpsbench.cases.analysis import completed_records, matches
from mpsbench.cases.uncertainty import (
    INCOMPLETE,
    Convergence,
    Validation,
    combine,
    convergence,
    validation,
)

SPACE, TIME = "l0", "dt"


@dataclass(frozen=True)
class Refinement:
    """A refinement set a case declares.

    ``over``: the parameter refined (smaller = finer, or with ``inverse`` larger = finer, the
    step being 1/value: a number of particles per side); ``kind``: what it refines, ``"l0"``
    (space) or ``"dt"`` (time); ``metrics``: the metrics measured; ``order``: the theoretical
    order of those metrics in the step (used only with two levels; None: two levels give no
    u_num); ``ignore``: parameters that do not change the metrics (runs differing only in them
    are the same point); ``where``: only runs matching these values (see
    :func:`mpsbench.cases.analysis.matches`).
    """

    over: str
    metrics: tuple[str, ...]
    kind: str = SPACE
    order: float | None = None
    ignore: tuple[str, ...] = ()
    where: Mapping[str, Any] = field(default_factory=dict)
    inverse: bool = False

    def step(self, value: float) -> float:
        return 1.0 / value if self.inverse else value

    def __post_init__(self) -> None:
        if self.kind not in (SPACE, TIME):
            raise ValueError(f"Refinement kind = {self.kind!r}: one of {SPACE!r}, {TIME!r}")


@dataclass(frozen=True)
class RefinementSet:
    """One set: the runs (finest first) of one metric and what their sequence says."""

    refinement: Refinement
    metric: str
    key: tuple[tuple[str, Any], ...]  # the parameters the runs share
    run_ids: tuple[str, ...]  # the completed runs, finest first
    convergence: Convergence
    note: str = ""  # why an incomplete set is incomplete

    @property
    def kind(self) -> str:
        return self.refinement.kind


@dataclass(frozen=True)
class UNum:
    """A run's metric with its numerical uncertainty (components by kind: l0, dt)."""

    value: float
    parts: Mapping[str, RefinementSet] = field(default_factory=dict)

    def component(self, kind: str) -> float | None:
        s = self.parts.get(kind)
        return None if s is None else s.convergence.u_num_at(self.value)

    @property
    def measured(self) -> bool:
        return bool(self.parts)

    @property
    def converged(self) -> bool:
        return self.measured and all(s.convergence.converged for s in self.parts.values())

    @property
    def u(self) -> float | None:
        """Combined u_num (None when not converged in some component or not measured)."""
        if not self.converged:
            return None
        return combine([self.component(k) for k in self.parts])

    @property
    def status(self) -> str:
        if not self.measured:
            return "not measured"
        return "measured" if self.converged else "not converged"

    def kinds(self) -> str:
        return "+".join(k for k in (SPACE, TIME) if k in self.parts)

    def text(self, fmt: Callable[[float], str] = lambda v: f"{v:.3g}") -> str:
        """``0.081 ± 0.013 (l0+dt)``, ``0.081 (not converged in dt)`` or
        ``0.081 (u_num not measured)``."""
        if not math.isfinite(self.value):
            return "n/a"
        if not self.measured:
            return f"{fmt(self.value)} (u_num not measured)"
        if not self.converged:
            bad = [k for k, s in self.parts.items() if not s.convergence.converged]
            notes = [s.note for s in self.parts.values() if s.note]
            return (f"{fmt(self.value)} (not converged in {'+'.join(bad)}"
                    + (f": {'; '.join(notes)}" if notes else "") + ")")
        u = self.u
        assert u is not None
        return f"{fmt(self.value)} ± {fmt(u)} ({self.kinds()})"

    def detail(self, fmt: Callable[[float], str] = lambda v: f"{v:.3g}") -> str:
        """Each component: the refined parameter, its levels and values, what the sequence
        says and the component of u_num (``l0: l0 = 2.5e-05, 5e-05 -> 0.0021, 0.0045:
        monotone, observed order 1.1, u = 0.0003``)."""
        parts = []
        for kind in (SPACE, TIME):
            s = self.parts.get(kind)
            if s is None:
                continue
            c = s.convergence
            u = self.component(kind)
            parts.append(
                f"{kind}: {s.refinement.over} = " + ", ".join(f"{h:.3g}" for h in c.steps)
                + " -> " + ", ".join(fmt(v) for v in c.values) + f": {c.kind}"
                + (f", {'observed' if c.order_observed else 'assumed'} order {c.order:.2g}"
                   if c.order is not None and c.kind != "unchanged" else "")
                + (f", u = {fmt(u)}" if u is not None else "")
                + (f" ({s.note})" if s.note else ""))
        return "; ".join(parts) if parts else "no refinement set"

    def u_text(self, fmt: Callable[[float], str] = lambda v: f"{v:.2g}") -> str:
        """The uncertainty alone: a number, ``not converged`` or ``not measured``."""
        u = self.u
        return fmt(u) if u is not None else self.status


def validate(u: UNum, data: float, u_data: float) -> Validation:
    """E = S - D of a run's metric against data with uncertainty ``u_data``, with the run's
    u_num (not converged: the verdict says so; no refinement set: u_val = u_D, and
    :attr:`Validation.u_num_measured` is False)."""
    return validation(u.value, data, u.u, u_data, u_num_measured=u.measured)


class NumericalUncertainty:
    """Every refinement set of ``refinements`` found in ``records`` (completed runs only).

    ``params``: the case's parameter names (the runs of a set share all of them except the
    refined one and the ignored ones).
    """

    def __init__(self, records: Iterable[dict[str, Any]], refinements: Sequence[Refinement],
                 params: Sequence[str]) -> None:
        records = list(records)
        self.records = completed_records(records)
        self.by_id = {str(r.get("run_id")): r for r in self.records}
        self.sets: list[RefinementSet] = []
        for ref in refinements:
            self.sets += _sets(records, ref, params)
        self._index: dict[tuple[str, str], dict[str, RefinementSet]] = {}
        for s in self.sets:
            for rid in s.run_ids:
                parts = self._index.setdefault((rid, s.metric), {})
                held = parts.get(s.kind)
                # a run in two sets of one kind: keep the set with more levels
                if held is None or len(s.run_ids) > len(held.run_ids):
                    parts[s.kind] = s

    def of(self, record: Mapping[Any, Any] | str, metric: str) -> UNum:
        """The metric of a run (a record or its run id) with its u_num."""
        rec = self.by_id.get(record) if isinstance(record, str) else record
        if rec is None:
            return UNum(math.nan)
        value = rec.get(metric)
        v = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
            else math.nan
        parts = self._index.get((str(rec.get("run_id")), metric), {})
        return UNum(v, dict(parts))

    def table(self) -> pd.DataFrame:
        """One row per set: shared parameters that vary between sets, metric, refined
        parameter, levels and values (finest first), convergence kind, R, order, f_ext, Fs,
        u_num and GCI of the finest value."""
        if not self.sets:
            return pd.DataFrame()
        keys = [dict(s.key) for s in self.sets]
        names = list(dict.fromkeys(k for key in keys for k in key))
        varying = [n for n in names if len({repr(k.get(n)) for k in keys}) > 1]
        rows = []
        for s, key in zip(self.sets, keys, strict=True):
            c = s.convergence
            row: dict[str, Any] = {n: key.get(n) for n in varying}
            row.update({
                "metric": s.metric, "refined": f"{s.refinement.over} ({s.kind})",
                "levels": ", ".join(f"{h:.4g}" for h in c.steps),
                "values": ", ".join(f"{v:.4g}" for v in c.values),
                "convergence": c.kind, "R": c.ratio,
                "order": c.order, "order_observed": c.order_observed if c.order else None,
                "extrapolated": c.extrapolated, "Fs": c.safety, "u_num": c.u_num,
                "gci_percent": 100.0 * c.gci if c.gci is not None else None,
                "note": s.note,
            })
            rows.append(row)
        return pd.DataFrame(rows)


def _sets(records: list[dict[str, Any]], ref: Refinement,
          params: Sequence[str]) -> list[RefinementSet]:
    skip = {ref.over, *ref.ignore}
    # one solver (and its options, e.g. numba threads) per set
    shared = ["solver", "solver_options", *(p for p in params if p not in skip)]
    groups: dict[tuple[tuple[str, Any], ...], dict[float, dict[str, Any]]] = {}
    broken: dict[tuple[tuple[str, Any], ...], dict[float, dict[str, Any]]] = {}
    for r in records:
        if not matches(r, ref.where):
            continue
        step = r.get(ref.over)
        if not isinstance(step, (int, float)) or isinstance(step, bool) or not step > 0:
            continue
        key = _hashable(tuple((p, r.get(p)) for p in shared if p in r))
        # runs that differ only in ignored parameters are one point
        target = groups if r.get("status") == "completed" else broken
        target.setdefault(key, {}).setdefault(ref.step(float(step)), r)
    out = []
    for key, levels in groups.items():
        coarsest = max(levels)
        failed = {h: r for h, r in broken.get(key, {}).items()
                  if h < coarsest and h not in levels}
        if failed:
            h, r = min(failed.items())
            note = f"the run at {ref.over} = {r.get(ref.over)} {r.get('status', 'failed')}"
            steps = sorted(levels)
            for metric in ref.metrics:
                pts = [(s, levels[s]) for s in steps if _finite(levels[s].get(metric))]
                if pts:
                    conv = Convergence(tuple(float(r[metric]) for _, r in pts),
                                       tuple(s for s, _ in pts), INCOMPLETE)
                    out.append(RefinementSet(ref, metric, key,
                                             tuple(str(r["run_id"]) for _, r in pts), conv, note))
            continue
        if len(levels) < 2:
            continue
        steps = sorted(levels)
        for metric in ref.metrics:
            pts = [(h, levels[h]) for h in steps if _finite(levels[h].get(metric))]
            if len(pts) < 2:
                continue
            conv = convergence([float(r[metric]) for _, r in pts], [h for h, _ in pts],
                               order=ref.order)
            out.append(RefinementSet(ref, metric, key, tuple(str(r["run_id"]) for _, r in pts),
                                     conv))
    return out


def _hashable(key: tuple[tuple[str, Any], ...]) -> tuple[tuple[str, Any], ...]:
    return tuple((k, v if isinstance(v, (str, int, float, bool, type(None))) else repr(v))
                 for k, v in key)


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
