"""The analysis layer every case uses: run records as frames, selection, pivots, convergence
orders, dt-halving comparisons, declarative bounds and the formatting of numbers.

Nothing here knows a case's physics: a case passes column names and values in.  Numerical
uncertainty from refinement sets is :mod:`mpsbench.cases.refinement`; gates and claims are
:mod:`mpsbench.cases.checks`; figure helpers :mod:`mpsbench.cases.plotting`.

Records are the dicts of :mod:`mpsbench.results.records` (parameters, metrics, ``status``,
``run_id``, ``solver``); :func:`completed` keeps those whose status is ``completed``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases.checks import CaseCheck
from mpsbench.physics.gradients import GRADIENTS
from mpsbench.physics.laplacians import LAPLACIANS
from mpsbench.physics.weights import WEIGHTS

# The built-in models in the order the tables list them (docs/method.md sections 1-3).
MODELS = ("koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic")
WFS = ("wf1", "wf2")
GRADIENT_MODELS = ("pgm1", "pgm2", "pgm3")


def _builtin_first(names: Iterable[str], builtin: Sequence[str]) -> tuple[str, ...]:
    names = list(names)
    return tuple([m for m in builtin if m in names] + sorted(n for n in names if n not in builtin))


def laplacian_names() -> tuple[str, ...]:
    """Registered Laplacians (built-ins first), so a plugin model is an allowed value."""
    return _builtin_first(LAPLACIANS.names(), MODELS)


def weight_names() -> tuple[str, ...]:
    return _builtin_first(WEIGHTS.names(), WFS)


def gradient_names() -> tuple[str, ...]:
    """Registered pressure-gradient models (pgm1-3 first), plugin models included."""
    return _builtin_first(GRADIENTS.names(), GRADIENT_MODELS)


def model_sort_key(model: str) -> tuple[int, str]:
    return (MODELS.index(model) if model in MODELS else len(MODELS), model)


# ---------------------------------------------------------------------- frames and selection
def is_completed(record: Mapping[str, Any]) -> bool:
    return record.get("status") == "completed"


def completed_records(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """The records of completed runs, in their order."""
    return [r for r in records if is_completed(r)]


def completed(records: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """Completed runs as a DataFrame (an empty frame when there are none)."""
    return pd.DataFrame.from_records(completed_records(records))


def several_solvers(df: pd.DataFrame) -> bool:
    return "solver" in df.columns and df["solver"].nunique() > 1


def num(value: Any) -> float:
    """A record value as a float (NaN for None, booleans, text)."""
    if isinstance(value, bool) or value is None:
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def matches(record: Mapping[Any, Any], where: Mapping[str, Any]) -> bool:
    """``record`` has every value of ``where`` (floats to rounding, a tuple/list = any of)."""
    for key, want in where.items():
        options = want if isinstance(want, (tuple, list, set, frozenset)) else (want,)
        have = record.get(key)
        if not any(_equal(have, w) for w in options):
            return False
    return True


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool) or not isinstance(a, (int, float)) \
            or not isinstance(b, (int, float)):
        return bool(a == b)
    return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-15)


def select(df: pd.DataFrame, **where: Any) -> pd.DataFrame:
    """Rows of ``df`` matching ``where`` (see :func:`matches`); a missing column matches none."""
    if df.empty or not where:
        return df
    if any(k not in df.columns for k in where):
        return df.iloc[:0]
    mask = [matches(row, where) for row in df[list(where)].to_dict("records")]
    return df[np.asarray(mask, dtype=bool)]


def side_by_side(df: pd.DataFrame, flag: str, keys: Sequence[str]) -> pd.DataFrame:
    """Runs with boolean ``flag`` on next to the run with it off that matches on ``keys`` (the
    keys ``df`` has): columns ``<name>_on`` / ``<name>_off``; empty without such pairs."""
    if df.empty or flag not in df.columns:
        return pd.DataFrame()
    use = [k for k in keys if k in df.columns]
    on = df[df[flag].astype(bool)]
    off = df[~df[flag].astype(bool)]
    return on.merge(off, on=use, suffixes=("_on", "_off"))


def rows(df: pd.DataFrame) -> list[dict[str, Any]]:
    """The rows of a frame as records (column name -> value)."""
    return [{str(k): v for k, v in r.items()} for r in df.to_dict("records")]


def select_records(records: Iterable[dict[str, Any]], **where: Any) -> list[dict[str, Any]]:
    """Completed records matching ``where``."""
    return [r for r in completed_records(records) if matches(r, where)]


def row_min(df: pd.DataFrame, value: str) -> pd.Series:
    """The row with the smallest ``value`` (NaN rows ignored)."""
    return df.iloc[int(np.nanargmin(df[value].to_numpy(float)))]


def row_max(df: pd.DataFrame, value: str) -> pd.Series:
    """The row with the largest ``value`` (NaN rows ignored)."""
    return df.iloc[int(np.nanargmax(df[value].to_numpy(float)))]


def sort_models(df: pd.DataFrame, extra: Iterable[str] = ()) -> pd.DataFrame:
    """Sort by model (built-in order), solver, weight, then ``extra`` columns."""
    if df.empty:
        return df
    by = [c for c in ("solver", "weight", *extra) if c in df.columns]
    if "laplacian" not in df:
        return df.sort_values(by, kind="stable") if by else df
    df = df.assign(_m=df["laplacian"].map(lambda m: model_sort_key(m)[0]))
    return df.sort_values(["_m", *by], kind="stable").drop(columns="_m")


# ---------------------------------------------------------------------- tables
def row_label(model: str, weight: str) -> str:
    return f"{model} / {weight}"


def not_completed(records: list[dict[str, Any]],
                  label: Callable[[dict[str, Any]], str]) -> list[str]:
    """A findings line per run that did not complete: its label, status and reason."""
    return [f"- **{label(r)}**: {r.get('status')} ({r.get('reason', '')})." for r in records
            if r.get("status") != "completed"]


def run_table(records: list[dict[str, Any]], label: Callable[[dict[str, Any]], str],
              columns: Sequence[str], sort: Iterable[str] = ()) -> pd.DataFrame:
    """One row per run, completed or not (``status`` and ``reason`` among ``columns`` say
    which), indexed by ``label(record)`` (with the solver when there are several), sorted by
    model and ``sort``; columns a record set does not have are left out."""
    if not records:
        return pd.DataFrame()
    df = sort_models(pd.DataFrame(records), sort)
    several = several_solvers(df)
    out = pd.DataFrame({"configuration": [
        label(r) + (f" [{r['solver']}]" if several else "") for r in rows(df)]})
    for c in columns:
        if c in df.columns:
            out[c] = df[c].to_numpy()
    return out.set_index("configuration")


def pivot(
    df: pd.DataFrame, value: str, columns: str = "re_ratio", column_label: str = "r_e/l0 = {:g}",
    cell: Callable[[pd.Series], Any] | None = None,
) -> pd.DataFrame:
    """Rows model x WF (``laplacian / weight``, plus the solver when there are several),
    columns ``columns`` (r_e/l0), cells ``value`` (the first of duplicates) or ``cell(row)``
    (e.g. the value with its uncertainty as text)."""
    if df.empty or value not in df.columns:
        return pd.DataFrame()
    df = df[df[value].notna()]
    if df.empty:
        return pd.DataFrame()
    rows = df.apply(lambda r: row_label(r["laplacian"], r["weight"]), axis=1)
    if several_solvers(df):
        rows = df["solver"].astype(str) + ": " + rows
    cells = df.apply(cell, axis=1) if cell is not None else df[value]
    frame = pd.DataFrame({"row": rows, "col": df[columns], "value": cells})
    table = frame.pivot_table(index="row", columns="col", values="value", aggfunc="first")
    order = sorted(
        table.index,
        key=lambda s: (s.split(": ")[0] if ": " in s else "",
                       model_sort_key(s.split(": ")[-1].split(" / ")[0]), s),
    )
    table = table.loc[order]
    table.columns = [column_label.format(c) for c in table.columns]
    table.index.name = "model / WF"
    return table


def observed_orders(
    df: pd.DataFrame, value: str, keys: Sequence[str], resolution: str = "l0"
) -> pd.DataFrame:
    """Observed order of convergence of an error ``value`` in ``resolution`` per ``keys`` group.

    ``observed_order`` is the local order between the two finest resolutions,
    log(e_coarse / e_fine) / log(h_coarse / h_fine) (an error that tends to zero: no
    extrapolated limit is needed); ``order_fit`` the least-squares slope of log e against
    log h over all resolutions.  Groups with one resolution are left out.  For a metric whose
    limit is unknown use :func:`mpsbench.cases.uncertainty.convergence` instead.
    """
    cols = [*keys, "n_resolutions", "l0_coarse", "l0_fine", "error_coarse", "error_fine",
            "observed_order", "order_fit"]
    if df.empty or value not in df.columns:
        return pd.DataFrame(columns=cols)
    rows = []
    use = [k for k in keys if k in df.columns]
    for key, group in df[df[value].notna()].groupby(use, sort=False):
        g = group.sort_values(resolution, ascending=False).drop_duplicates(resolution)
        if len(g) < 2:
            continue
        h = g[resolution].to_numpy(float)
        e = g[value].to_numpy(float)
        ok = e > 0
        order = fit = math.nan
        if ok[-1] and ok[-2]:
            order = math.log(e[-2] / e[-1]) / math.log(h[-2] / h[-1])
        if ok.sum() >= 2:
            fit = float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0])
        key = key if isinstance(key, tuple) else (key,)
        rows.append([*key, len(g), h[0], h[-1], e[0], e[-1], order, fit])
    return pd.DataFrame(rows, columns=[*use, *cols[len(keys):]])


def dt_halving_table(
    df: pd.DataFrame, keys: Sequence[str], *, error: str = "l2_error",
    change: str = "dt_halving_change", against: str = "run", extra: Sequence[str] = (),
) -> pd.DataFrame:
    """Runs repeated at dt/2: forward Euler's time error (about twice ``change``) against an
    error of the same runs.

    ``against="run"``: each checked run against its own ``error`` (one row per run, ``extra``
    columns kept).  ``against="group-min"``: per ``keys`` group, the largest change against the
    smallest ``error`` of the group at any resolution (``smallest_<error>`` at ``at_l0``): the
    time error must stay below the finest spatial error.
    """
    if df.empty or change not in df or df[change].notna().sum() == 0:
        return pd.DataFrame()
    keys = [k for k in keys if k in df.columns]
    if against == "run":
        t = df[df[change].notna()][[*keys, *extra, error, change]]
        t = t.assign(time_error=2.0 * t[change])
        t = t.assign(time_error_share=t["time_error"] / t[error])
        return sort_models(t, [k for k in keys if k != "laplacian"]).reset_index(drop=True)
    rows = []
    for key, g in df.groupby(keys, sort=False):
        checked = g[g[change].notna()]
        if checked.empty:
            continue
        worst = float(checked[change].max())
        smallest = float(g[error].min())
        key = key if isinstance(key, tuple) else (key,)
        rows.append([*key, *(checked[c].max() for c in extra), worst, 2.0 * worst, smallest,
                     float(row_min(g, error)["l0"]),
                     2.0 * worst / smallest if smallest > 0 else math.inf])
    cols = [*keys, *extra, change, "time_error", f"smallest_{error}", "at_l0",
            "time_error_share"]
    t = pd.DataFrame(rows, columns=cols)
    return sort_models(t, [k for k in keys if k != "laplacian"]).reset_index(drop=True)


# ---------------------------------------------------------------------- declarative bounds
@dataclass(frozen=True)
class Bound:
    """A gate of the form "``metric`` of the runs matching ``where`` is below ``upper``
    (strictly) and/or above ``lower`` (strictly)".

    ``describe(row)`` names a run in the detail (default: laplacian / weight / r_e);
    ``fmt`` formats the values.  The check is undecided (None) when no run matches.
    """

    name: str
    metric: str
    where: Mapping[str, Any] = field(default_factory=dict)
    upper: float | None = None
    lower: float | None = None
    fmt: Callable[[float], str] = lambda v: f"{v:.4g}"
    describe: Callable[[Mapping[Any, Any]], str] | None = None

    def label(self, row: Mapping[Any, Any]) -> str:
        if self.describe is not None:
            return self.describe(row)
        parts = [str(row[k]) for k in ("laplacian", "weight") if k in row]
        if "re_ratio" in row:
            parts.append(f"{float(row['re_ratio']):g}")
        return "/".join(parts) or str(row.get("run_id", "?"))

    def check(self, df: pd.DataFrame) -> CaseCheck:
        sel = select(df, **self.where)
        if not sel.empty and self.metric in sel:
            sel = sel[sel[self.metric].notna()]
        if sel.empty or self.metric not in sel:
            return CaseCheck(self.name, None, "no such runs in this study")
        rows = sel.to_dict("records")
        bad = [r for r in rows if not self._inside(float(r[self.metric]))]
        values = [float(r[self.metric]) for r in rows]
        extreme = max(values) if self.upper is not None else min(values)
        what = "largest" if self.upper is not None else "smallest"
        detail = f"{plural(len(rows), 'run')}; {what} {self.fmt(extreme)}"
        if len(rows) <= 12:
            detail = f"{plural(len(rows), 'run')}: " + ", ".join(
                f"{self.label(r)} {self.fmt(float(r[self.metric]))}" for r in rows)
        if bad:
            detail += "; out of bounds: " + ", ".join(
                f"{self.label(r)} = {self.fmt(float(r[self.metric]))}" for r in bad)
        return CaseCheck(self.name, not bad, detail,
                         rule=self.rule(), runs=tuple(str(r.get("run_id", "")) for r in rows))

    def _inside(self, v: float) -> bool:
        if not math.isfinite(v):
            return False
        return (self.upper is None or v < self.upper) and (self.lower is None or v > self.lower)

    def rule(self) -> str:
        parts = []
        if self.lower is not None:
            parts.append(f"> {self.fmt(self.lower)}")
        if self.upper is not None:
            parts.append(f"< {self.fmt(self.upper)}")
        where = ", ".join(f"{k} = {v}" for k, v in self.where.items())
        return f"{self.metric} {' and '.join(parts)}" + (f" ({where})" if where else "")


# ---------------------------------------------------------------------- formatting
def fmt(value: Any, digits: int = 3) -> str:
    """A number with ``digits`` significant digits; text as is; ``n/a`` for None / NaN."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.{digits}g}"
    return str(value)


def pct(x: Any, digits: int = 2) -> str:
    """A fraction as a percentage for prose (``n/a`` for missing values)."""
    v = num(x)
    if not math.isfinite(v):
        return "n/a"
    return f"{100.0 * v:.{digits}f}%"


def plural(n: int, word: str) -> str:
    """``1 run``, ``3 runs``."""
    return f"{n} {word}" + ("" if n == 1 else "s")


def fraction(value: float, whole: float = 1.0, symbol: str = "1") -> str:
    """``1/40`` (or ``L/40``) when ``value`` is whole/N for an integer N, else ``%g``."""
    if value > 0:
        n = whole / value
        if abs(n - round(n)) < 1e-6 * n:
            return f"{symbol}/{round(n)}"
    return f"{value:g}"


def span(values: Any, fmt: Callable[[float], str], sep: str = "-") -> str:
    """``fmt(min)-fmt(max)``, or one value when they print the same."""
    lo, hi = fmt(float(np.min(values))), fmt(float(np.max(values)))
    return lo if lo == hi else f"{lo}{sep}{hi}"


def weight_ratio_line(df: pd.DataFrame, value: str, where: str) -> str:
    """Plain words: the WF1 / WF2 ratio of ``value`` per model at the same r_e/l0."""
    table = weight_ratios(df, value)
    if table.empty:
        return ""
    parts = []
    for model in sorted(table["laplacian"].unique(), key=model_sort_key):
        ratio = table[table["laplacian"] == model]["ratio"]
        parts.append(f"{model} {span(ratio, lambda v: f'{v:.2f}')}")
    return (f"- **WF1 / WF2** error ratio at the same r_e/l0 ({where}): " + "; ".join(parts)
            + " (1 = insensitive to the weighting function).")


def weight_ratios(df: pd.DataFrame, value: str) -> pd.DataFrame:
    """Per (laplacian, r_e/l0): ``value`` with WF1 (``wf1``), WF2 (``wf2``), their ratio and
    the two run ids."""
    if df.empty or "weight" not in df or not {"wf1", "wf2"} <= set(df["weight"]):
        return pd.DataFrame()
    keys = ["laplacian", "re_ratio"]
    cols = [value, "run_id"] if "run_id" in df else [value]
    w1 = df[df["weight"] == "wf1"].groupby(keys)[cols].first()
    w2 = df[df["weight"] == "wf2"].groupby(keys)[cols].first()
    both = pd.merge(w1, w2, left_index=True, right_index=True, how="inner",
                    suffixes=("_wf1", "_wf2")).dropna()
    both = both[both[f"{value}_wf2"] > 0]
    if both.empty:
        return pd.DataFrame()
    both = both.rename(columns={f"{value}_wf1": "wf1", f"{value}_wf2": "wf2"})
    both["ratio"] = both["wf1"] / both["wf2"]
    return both.reset_index()
