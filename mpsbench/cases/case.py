"""Declarative validation cases and their registry.

A case names its parameters (with defaults, units and allowed values), its tiers (parameter
grids), how to run one parameter set on a solver, its metrics, its refinement sets (for the
numerical uncertainty u_num, :mod:`mpsbench.cases.refinement`), its gates (``checks``: they
decide pass or fail) and claims (``claims``: a paper's statements tested as hypotheses,
:mod:`mpsbench.cases.checks`), its tables and its figures.  The study machinery
(:mod:`mpsbench.results.sweep`) expands the grid
and runs it; the reporting (:mod:`mpsbench.results.case_report`) writes the output folder.
The shared analysis helpers a case builds its tables and checks from are
:mod:`mpsbench.cases.analysis`.

Built-in cases live in :mod:`mpsbench.validations`; plugins add cases through the
``mpsbench.cases`` entry-point group (the object must be a :class:`Case` instance).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mpsbench.cases.checks import CaseCheck
from mpsbench.errors import ConfigError
from mpsbench.params import Param
from mpsbench.registry import Registry
from mpsbench.run.estimate import RunEstimate
from mpsbench.run.runner import RunLimits, RunResult

if TYPE_CHECKING:  # pandas is imported when a case analyses records, not when the CLI starts
    from mpsbench.cases.refinement import NumericalUncertainty, Refinement

TIERS = ("smoke", "quick", "paper")

TIER_LIMITS: dict[str, RunLimits] = {
    "smoke": RunLimits(max_steps=200_000, max_wall_s=600.0),
    "quick": RunLimits(max_steps=2_000_000, max_wall_s=3 * 3600.0),
    "paper": RunLimits(max_steps=20_000_000, max_wall_s=48 * 3600.0),
}
"""Default run limits per tier (``--max-steps`` / ``--max-wall`` override them): far above what
a healthy run of the tier takes (smoke runs take seconds, quick ones minutes), so they only
stop a run whose time step collapsed or a solver that hangs.  With an estimate of the run's
steps (``Case.estimate``) the step limit is ``STEP_FACTOR`` times that, if lower."""

STEP_FACTOR = 20
STEP_FLOOR = 2_000


def _signature(params: dict[str, Any]) -> tuple[tuple[str, str], ...]:
    return tuple(sorted((k, repr(v)) for k, v in params.items()))


@dataclass
class CaseRun:
    """What one run of a case produced: the solver run(s), scalar metrics and arrays for plots."""

    metrics: dict[str, Any]
    results: list[RunResult] = field(default_factory=list)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)


Grid = dict[str, Sequence[Any]]


class RefinementGrid(dict[str, Sequence[Any]]):
    """A grid of a tier that exists for a refinement set (docs/method.md section 9): its runs
    give u_num to the model grid's runs, and :meth:`Case.model_records` leaves them out of the
    tables and comparisons across models.  Written like a grid: ``RefinementGrid(l0=[L / 80])``
    or ``RefinementGrid({"l0": [L / 80]})``; ``grid | {...}`` is a refinement grid too (a
    plain dict's ``|`` would drop the kind, and the runs would count as the model grid's)."""

    def __or__(self, other: Any) -> RefinementGrid:  # type: ignore[override]
        return RefinementGrid({**self, **other})


class Case:
    """Base class for validation cases; subclasses set the attributes and implement ``execute``."""

    name: str = ""
    title: str = ""
    description: str = ""
    params: tuple[Param, ...] = ()
    tiers: dict[str, list[Grid]] = {}
    metrics: dict[str, str] = {}  # metric column -> description (with unit)
    # How ``mpsbench compare`` holds a metric against a baseline: metric -> (direction, rtol),
    # direction "lower" | "higher" (which way is better), "equal" (any change beyond rtol is a
    # regression) or "info" (shown, never a regression).  Metrics not listed get the defaults of
    # :func:`mpsbench.results.compare.metric_rule` (error-like names: lower, rtol 0.05; timings:
    # info).
    compare: dict[str, tuple[str, float]] = {}
    # The table shown in summary.md and first in index.html (default: the first of ``tables``).
    headline: str = ""
    # The figure shown first in index.html, a file stem (default: the first of ``figures``).
    headline_figure: str = ""
    # Parameters the case no longer has that older records still carry: neither parameters nor
    # metrics, so ``mpsbench compare`` holds nothing against them (identity ignores them anyway).
    retired_params: tuple[str, ...] = ()
    # The accuracy metrics of the cross-code table (:mod:`mpsbench.results.cross_code`: MPS
    # backends and an outside code side by side; default: the first three of ``metrics``).
    accuracy: tuple[str, ...] = ()
    # Where the case comes in reports and in ``validate all`` (lower first; equal: by name).
    # The built-ins use 10, 20, ...; a plugin case without one comes after them.
    order: float = 1000.0
    # Refinement sets in l0 and dt of the headline metrics (docs/method.md section 9): the
    # report gets a numerical_uncertainty table and ``uncertainty(records)`` gives u_num per run.
    refinements: tuple[Refinement, ...] = ()
    # A boolean parameter -> the parameters that do nothing while it is false
    # (``{"stabilization": ("alpha_s",)}``): :meth:`expand` puts those back to their defaults,
    # so such runs are not made twice under two names.
    inactive_without: dict[str, tuple[str, ...]] = {}

    # ---- parameters
    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise ConfigError(
            f"case {self.name!r} has no parameter {name!r}; known: "
            + ", ".join(p.name for p in self.params)
        )

    def defaults(self) -> dict[str, Any]:
        return {p.name: p.default for p in self.params}

    def expand(
        self, tier: str, overrides: dict[str, Sequence[Any]] | None = None, *, part: str = "all"
    ) -> list[dict[str, Any]]:
        """All parameter sets of a tier; ``overrides`` replace a parameter's values in each grid.

        ``part``: ``"all"``, ``"model"`` (the plain grids) or ``"refinement"`` (the
        :class:`RefinementGrid` ones)."""
        if tier not in self.tiers:
            raise ConfigError(f"tier = {tier!r} is not allowed: one of {', '.join(self.tiers)}")
        if part not in ("all", "model", "refinement"):
            raise ValueError(f"part = {part!r}: one of all, model, refinement")
        overrides = overrides or {}
        for key in overrides:
            self.param(key)
        out: list[dict[str, Any]] = []
        seen: set[tuple[Any, ...]] = set()
        for grid in self.tiers[tier]:
            if part != "all" and isinstance(grid, RefinementGrid) != (part == "refinement"):
                continue
            merged = {k: list(v) for k, v in grid.items()}
            merged.update({k: list(v) for k, v in overrides.items()})
            keys = list(merged)
            for combo in itertools.product(*(merged[k] for k in keys)):
                params = self.defaults()
                params.update(dict(zip(keys, combo, strict=True)))
                params = {k: self.param(k).check(v) for k, v in params.items()}
                for flag, names in self.inactive_without.items():
                    if not params.get(flag, True):
                        params.update({n: self.param(n).default for n in names})
                sig = _signature(params)
                if sig not in seen:
                    seen.add(sig)
                    out.append(params)
        return out

    def model_records(self, records: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """``records`` without the runs that only a :class:`RefinementGrid` of their tier asks
        for (they feed u_num; the model grid's tables and comparisons leave them out).  Runs
        made with ``--set`` or a study file match no refinement grid and are all kept."""
        extra: dict[str, set[tuple[Any, ...]]] = {}
        for tier in {str(r.get("tier")) for r in records}:
            if tier not in self.tiers or not any(
                    isinstance(g, RefinementGrid) for g in self.tiers[tier]):
                extra[tier] = set()
                continue
            model = {_signature(p) for p in self.expand(tier, part="model")}
            extra[tier] = {_signature(p) for p in self.expand(tier, part="refinement")} - model
        names = [p.name for p in self.params]
        return [r for r in records
                if _signature({k: r.get(k) for k in names}) not in extra[str(r.get("tier"))]]

    # ---- to implement
    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        raise NotImplementedError

    def estimate(self, params: dict[str, Any]) -> RunEstimate | None:
        """What one run will cost (particles, pairs, steps, a fixed dt's stability limit),
        from the parameters alone, in well under a millisecond: nothing may be built here.
        None (the default) means unknown; the size guard then only counts runs
        (:mod:`mpsbench.run.estimate`, :mod:`mpsbench.results.guard`)."""
        return None

    def run_limits(self, tier: str, params: dict[str, Any]) -> RunLimits:
        """The default limits of one run at ``tier`` (:data:`TIER_LIMITS`, the step limit
        tightened to ``STEP_FACTOR`` x the estimated steps when the case can estimate them)."""
        base = TIER_LIMITS.get(tier, RunLimits())
        try:
            est = self.estimate(params)
        except Exception:  # noqa: BLE001 - no estimate: the tier's limits
            est = None
        steps = base.max_steps
        if est is not None and est.steps:
            guess = max(STEP_FLOOR, STEP_FACTOR * int(est.steps))
            steps = guess if steps is None else min(steps, guess)
        return RunLimits(steps, base.max_wall_s)

    # Case parameters that only set a Problem field a backend may ignore
    # (mpsbench.run.protocol.IGNORED_FIELDS): parameter -> field.  A backend that ignores the
    # field runs one parameter set of those that differ only in such parameters, and reports
    # say the parameter does not apply to it.  The conventional names of the built-in cases;
    # a case with other names sets its own.
    model_params: dict[str, str] = {
        "laplacian": "models.laplacian",
        "weight": "models.weight",
        "gradient": "models.gradient",
        "re_ratio": "models.re_ratio",
        "re_ratio_laplacian": "models.re_ratio_laplacian",
        "gradient_correction": "models.gradient_correction",
        "cfl": "time_stepping.cfl",
        "c_nu": "time_stepping.c_nu",
    }

    def not_applicable(self, ignored_fields: set[str]) -> list[str]:
        """This case's parameters a backend ignoring ``ignored_fields`` does not use."""
        names = {p.name for p in self.params}
        return [k for k, f in self.model_params.items() if k in names and f in ignored_fields]

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        """The gates: pass/fail decisions that set the exit status of ``mpsbench validate``
        (a check returned here with ``kind="claim"`` counts as a claim)."""
        return []

    def claims(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        """The paper's statements tested on these records (``Claim.verdict``): supported,
        refuted or inconclusive.  They change the exit status only with --strict-claims."""
        return []

    def uncertainty(self, records: list[dict[str, Any]]) -> NumericalUncertainty:
        """The refinement sets of ``refinements`` in ``records`` and u_num per run."""
        from mpsbench.cases.refinement import NumericalUncertainty

        return NumericalUncertainty(records, self.refinements, [p.name for p in self.params])

    def tables(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        """Named pandas DataFrames written as CSV and Markdown."""
        return {}

    def figures(self, records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
                outdir: Path) -> list[Path]:
        """Write PNG figures into ``outdir``; ``arrays(run_id)`` loads a run's saved arrays."""
        return []

    def findings(self, records: list[dict[str, Any]]) -> str:
        """Plain-word Markdown: which model won where, and by how much."""
        return ""


def _validate_case(obj: Any) -> None:
    if not isinstance(obj, Case):
        raise TypeError(
            f"a case entry must be a mpsbench.cases.Case instance, got {type(obj).__name__}"
        )
    if not obj.name or not obj.tiers:
        raise TypeError("a case needs a name and at least one tier")


CASES: Registry[Case] = Registry("case", group="mpsbench.cases", validate=_validate_case)
"""Every case, built-in or plugin, comes through the ``mpsbench.cases`` entry-point group (the
built-ins are declared in mpsbench's own pyproject.toml)."""


def case_order(names: list[str]) -> list[str]:
    """Case names in report order: by each case's ``order`` (built-ins first), then name.

    A case that cannot be loaded sorts as a plugin case without an ``order`` (its error is
    reported where it is used).
    """

    def key(name: str) -> tuple[float, str]:
        try:
            return (float(get_case(name).order), name)
        except Exception:  # noqa: BLE001 - a broken plugin case still gets listed
            return (float(Case.order), name)

    return sorted(names, key=key)


def get_case(name: str | Case) -> Case:
    return CASES.get(name) if isinstance(name, str) else name
