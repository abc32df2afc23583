"""Hold the metrics of a run against a baseline run (``mpsbench compare``).

Records match by (case, solver, solver options, every parameter the case declares); a parameter
a record lacks (a baseline older than the parameter) takes its default, a record without solver
options has the backend's defaults.  For a case that cannot be loaded the run id, built from the
same things, is the key.

Per metric, a :class:`Rule` says which way is better and how far it may move:

* the case's ``Case.compare[metric] = (direction, rtol)`` when declared;
* timings (``wall_time_s``, ``particle_steps_per_s``, ``elapsed_s``): shown in a timing table,
  never a regression (machines are noisy);
* work counters (``n_particles``, ``n_steps``, ``n_solver_runs``): shown when they change,
  never a regression;
* names containing ``error``, ``noise`` or ``drift``: lower is better, rtol 0.05;
* any other number: must stay within rtol 0.05 either way.

A metric is unchanged when ``|current - baseline| <= rtol * |baseline| + atol``.  A record that
completed in the baseline but diverged or failed now, or a gated metric that is missing now, is
a regression too.  A gated metric the baseline has no value for (null) is listed as *unheld*:
nothing holds it.  Records only in one set are listed as appeared / vanished (not regressions).

Input that cannot be trusted is refused (:class:`CompareError`, exit 2), naming the file and
the record: unreadable or non-UTF-8 files, a CSV whose last row is cut short or whose rows
have the wrong number of fields, NaN or infinite values (a missing value is null, an empty
cell), records without case, solver or status, a broken record file in a ``runs/`` folder,
and a folder another mpsbench process is writing.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.cases import Case, Param, get_case
from mpsbench.errors import ConfigError, MpsbenchError
from mpsbench.results.escape import md_escape, md_frame
from mpsbench.results.identity import HASH_COLUMN, OPTIONS_COLUMN
from mpsbench.results.lock import held_by_other
from mpsbench.results.records import ENV_COLUMNS, load_records

REQUIRED = ("case", "solver", "status")
IDENTITY = ("case", "solver", "solver_version", "tier", "run_id", HASH_COLUMN, OPTIONS_COLUMN,
            "status", "reason")
TIMING = {"wall_time_s": "lower", "particle_steps_per_s": "higher", "elapsed_s": "lower"}
COUNTERS = ("n_particles", "n_steps", "n_solver_runs")
ERROR_WORDS = ("error", "noise", "drift")
DIRECTIONS = ("lower", "higher", "equal", "info")
DEFAULT_RTOL = 0.05
DEFAULT_ATOL = 1e-12
ORDER = {"regression": 0, "unheld": 1, "worse": 2, "better": 3, "info": 4, "appeared": 5,
         "vanished": 6}
NON_FINITE_TEXT = {"nan", "+nan", "-nan", "inf", "+inf", "-inf", "infinity", "+infinity",
                   "-infinity"}


class CompareError(MpsbenchError, ValueError):
    """A baseline or current result set that cannot be read or compared; the message says why."""


@dataclass(frozen=True)
class Rule:
    direction: str  # lower | higher | equal | info
    rtol: float
    atol: float = DEFAULT_ATOL
    gate: bool = True  # a change for the worse beyond tolerance is a regression

    def describe(self) -> str:
        if not self.gate or self.direction == "info":
            return "info"
        return f"{self.direction}, {self.rtol:.3g}"


def metric_rule(
    case: Case | None, metric: str, rtol: float | None = None, atol: float | None = None
) -> Rule:
    """The rule for ``metric`` of ``case``; ``rtol`` / ``atol`` override every gated rule."""
    a = DEFAULT_ATOL if atol is None else atol
    declared = dict(getattr(case, "compare", {}) or {}) if case is not None else {}
    if metric in declared:
        spec = declared[metric]
        try:
            direction, tol = str(spec[0]), float(spec[1])
        except (TypeError, ValueError, IndexError):
            direction, tol = "?", math.nan
        if direction not in DIRECTIONS or not (tol >= 0):
            raise CompareError(
                f"case {getattr(case, 'name', '?')!r}: compare[{metric!r}] = {spec!r} is not "
                f"allowed: (direction, rtol) with direction one of {', '.join(DIRECTIONS)} "
                "and rtol >= 0")
        gate = direction != "info"
        return Rule(direction, rtol if rtol is not None and gate else tol, a, gate)
    if metric in TIMING:
        return Rule(TIMING[metric], 0.10, a, gate=False)
    if metric in COUNTERS:
        return Rule("equal", 0.0, 0.0, gate=False)
    r = DEFAULT_RTOL if rtol is None else rtol
    if any(word in metric.lower() for word in ERROR_WORDS):
        return Rule("lower", r, a)
    return Rule("equal", r, a)


# ---------------------------------------------------------------- loading


def load_results(path: str | Path) -> list[dict[str, Any]]:
    """Records from a results folder, a results.json or a results.csv; CompareError if unusable."""
    p = Path(path)
    if not p.exists():
        raise CompareError(f"{p}: no such file or folder")
    if p.is_dir():
        holder = held_by_other(p)
        if holder is not None:
            raise CompareError(f"{p} is being written by another mpsbench process (pid "
                               f"{holder}); compare it when that has finished")
        for name in ("results.json", "results.csv"):
            if (p / name).is_file():
                p = p / name
                break
        else:
            if (p / "runs").is_dir() and (records := load_records(p)):
                return _validated(records, p)
            raise CompareError(f"{p}: not a results folder (no results.json, results.csv or "
                               "runs/ with records)")
    if p.suffix == ".json":
        try:
            data = json.loads(_text(p))
        except json.JSONDecodeError as exc:
            raise CompareError(f"{p}: truncated or corrupt JSON: {exc}") from None
        except RecursionError:
            raise CompareError(f"{p}: JSON nested too deeply") from None
        if isinstance(data, dict) and isinstance(data.get("records"), list):
            data = data["records"]
        if not isinstance(data, list) or not all(isinstance(r, dict) for r in data):
            raise CompareError(f"{p}: expected a JSON list of run records (objects with "
                               f"{', '.join(REQUIRED)}), got {type(data).__name__}")
        return _validated(data, p)
    if p.suffix == ".csv":
        text = _text(p)
        _check_csv(p, text)
        try:
            df = pd.read_csv(io.StringIO(text), keep_default_na=False, na_values=[""])
        except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
            raise CompareError(f"{p}: corrupt CSV: {exc}") from None
        missing = [c for c in REQUIRED if c not in df.columns]
        if missing:
            has = ", ".join(map(str, df.columns[:12]))
            raise CompareError(f"{p}: not a results table: lacks the column(s) "
                               f"{', '.join(missing)} (has: {has})")
        records = [{str(k): _from_csv(v) for k, v in row.items() if not _missing(v)}
                   for row in df.to_dict(orient="records")]
        return _validated(records, p)
    raise CompareError(f"{p}: expected a results folder, a .json or a .csv file")


def _text(p: Path) -> str:
    try:
        return p.read_bytes().decode("utf-8")
    except OSError as exc:
        raise CompareError(f"{p}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise CompareError(f"{p}: not a text file (not UTF-8: {exc.reason} at byte "
                           f"{exc.start})") from None


def _check_csv(p: Path, text: str) -> None:
    """A results table as mpsbench writes it: every row as long as the header, the file ending
    with a line end (a cut-off last row would otherwise read as a row of missing values), no
    NaN or infinite number (a missing value is an empty cell)."""
    if not text.strip():
        raise CompareError(f"{p}: empty file")
    if not text.endswith(("\n", "\r")):
        raise CompareError(f"{p}: truncated: the last line has no line end (a results table "
                           "written by mpsbench ends with one)")
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as exc:
        raise CompareError(f"{p}: corrupt CSV: {exc}") from None
    header = rows[0]
    rid = header.index("run_id") if "run_id" in header else None
    for k, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        label = f"row {k}" + (f" ({row[rid]})" if rid is not None and rid < len(row) else "")
        if len(row) != len(header):
            raise CompareError(f"{p}: {label} has {len(row)} fields, the header {len(header)}: "
                               "truncated or corrupt table")
        for col, cell in zip(header, row, strict=True):
            if cell.strip().lower() in NON_FINITE_TEXT:
                raise CompareError(f"{p}: {label}: {col} = {cell!r} is not a finite number (a "
                                   "missing value is an empty cell)")


def _missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))


def _from_csv(v: Any) -> Any:
    if hasattr(v, "item"):
        v = v.item()  # numpy scalar -> Python
    return v


def _validated(records: list[dict[str, Any]], p: Path) -> list[dict[str, Any]]:
    if not records:
        raise CompareError(f"{p}: holds no run records")
    for i, rec in enumerate(records):
        label = f"record {i} ({str(rec.get('run_id', 'no run_id'))[:120]})"
        missing = [c for c in REQUIRED if _missing(rec.get(c))]
        if missing:
            raise CompareError(f"{p}: {label} lacks {', '.join(missing)}; not a mpsbench "
                               "results file?")
        for key, value in rec.items():
            if isinstance(value, float) and not math.isfinite(value):
                raise CompareError(f"{p}: {label}: {key} = {value!r} is not a finite number "
                                   "(a missing value is null)")
            if isinstance(value, (list, dict)) and key not in (OPTIONS_COLUMN,):
                if _has_non_finite(value):
                    raise CompareError(f"{p}: {label}: {key} holds a NaN or infinite number")
    return records


def _has_non_finite(value: Any) -> bool:
    if isinstance(value, float):
        return not math.isfinite(value)
    if isinstance(value, list):
        return any(_has_non_finite(v) for v in value)
    if isinstance(value, dict):
        return any(_has_non_finite(v) for v in value.values())
    return False


# ---------------------------------------------------------------- matching


def _canon(param: Param, value: Any) -> str:
    if _missing(value):
        value = param.default
    if param.kind is str:
        return repr(str(value))  # a CSV may have read "2" as a number
    if isinstance(value, str):
        try:
            value = param.parse(value)
        except ConfigError:
            return repr(value)
    if isinstance(value, bool):
        return repr(value)
    if isinstance(value, (int, float)):
        return f"{float(value):.10g}"
    return repr(value)


class _Cases:
    """Case lookup with a cache; a case that cannot be loaded is None (run id is the key)."""

    def __init__(self) -> None:
        self._cache: dict[str, Case | None] = {}

    def __call__(self, name: str) -> Case | None:
        if name not in self._cache:
            try:
                self._cache[name] = get_case(name)
            except Exception:  # noqa: BLE001 - unknown case: fall back to run ids
                self._cache[name] = None
        return self._cache[name]


def record_key(rec: dict[str, Any], case: Case | None) -> tuple[Any, ...]:
    # a record older than solver options has none: the backend's defaults
    head = (str(rec["case"]), str(rec["solver"]), str(rec.get("solver_options") or ""))
    if case is None:
        if _missing(rec.get("run_id")):
            raise CompareError(f"record of unknown case {rec['case']!r} has no run_id to match by")
        return (*head, ("run_id", str(rec["run_id"])))
    return (*head, tuple((p.name, _canon(p, rec.get(p.name))) for p in case.params))


def _index(
    records: list[dict[str, Any]], cases: _Cases, label: str
) -> dict[tuple[Any, ...], dict[str, Any]]:
    out: dict[tuple[Any, ...], dict[str, Any]] = {}
    for rec in records:
        key = record_key(rec, cases(str(rec["case"])))
        if key in out:
            raise CompareError(f"{label}: two records with the same case, solver and parameters: "
                               f"{out[key].get('run_id')} and {rec.get('run_id')}")
        out[key] = rec
    return out


# ---------------------------------------------------------------- comparing


@dataclass
class Change:
    kind: str  # regression | worse | better | info | appeared | vanished
    record: str
    metric: str = ""
    baseline: Any = None
    current: Any = None
    rule: str = ""
    note: str = ""

    @property
    def relative(self) -> float | None:
        b, c = _number(self.baseline), _number(self.current)
        if b is None or c is None:
            return None
        if b == 0:
            return 0.0 if c == 0 else math.copysign(math.inf, c)
        return (c - b) / abs(b)


@dataclass
class Comparison:
    n_baseline: int
    n_current: int
    matched: int
    compared: int  # metric values held against a tolerance
    changes: list[Change] = field(default_factory=list)
    timing: pd.DataFrame = field(default_factory=pd.DataFrame)

    def count(self, kind: str) -> int:
        return sum(1 for c in self.changes if c.kind == kind)

    @property
    def regressions(self) -> list[Change]:
        return [c for c in self.changes if c.kind == "regression"]


def _number(v: Any) -> float | None:
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float)):
        f = float(v)
        return f if math.isfinite(f) else None
    return None


def _metric_names(b: dict[str, Any], c: dict[str, Any], case: Case | None) -> list[str]:
    skip = set(IDENTITY) | set(ENV_COLUMNS) | {p.name for p in (case.params if case else ())}
    skip |= set(getattr(case, "retired_params", ()))
    return [k for k in dict.fromkeys([*b, *c]) if k not in skip]


def compare(
    baseline: list[dict[str, Any]], current: list[dict[str, Any]], *,
    rtol: float | None = None, atol: float | None = None,
) -> Comparison:
    """Compare two sets of records; CompareError when they have no record in common."""
    cases = _Cases()
    base = _index(baseline, cases, "baseline")
    cur = _index(current, cases, "current")
    common = [k for k in base if k in cur]
    if not common:
        raise CompareError(
            "baseline and current have no record in common (same case, solver and parameters): "
            f"baseline {_describe(baseline)}; current {_describe(current)}")
    result = Comparison(len(base), len(cur), len(common), 0)
    timing_rows: list[dict[str, Any]] = []
    for key in common:
        b, c = base[key], cur[key]
        case = cases(str(c["case"]))
        rid = str(c.get("run_id") or b.get("run_id") or key)
        b_ok, c_ok = b.get("status") == "completed", c.get("status") == "completed"
        if b_ok != c_ok or b.get("status") != c.get("status"):
            kind = "regression" if b_ok and not c_ok else "better" if c_ok else "info"
            result.changes.append(Change(kind, rid, "status", b.get("status"), c.get("status"),
                                         note=str(c.get("reason") or b.get("reason") or "")))
        if not (b_ok and c_ok):
            continue
        timing_rows.append({"case": c["case"], "solver": c["solver"],
                            **{f"{m}_base": _number(b.get(m)) for m in TIMING},
                            **{f"{m}_cur": _number(c.get(m)) for m in TIMING}})
        for metric in _metric_names(b, c, case):
            if metric in TIMING:
                continue
            rule = metric_rule(case, metric, rtol, atol)
            change = _compare_value(rid, metric, b.get(metric), c.get(metric), rule)
            if change is None:
                result.compared += 1
            elif change.kind != "skip":
                result.compared += change.kind != "unheld"
                result.changes.append(change)
    for key in base:
        if key not in cur:
            result.changes.append(Change("vanished", str(base[key].get("run_id") or key)))
    for key in cur:
        if key not in base:
            result.changes.append(Change("appeared", str(cur[key].get("run_id") or key)))
    result.changes.sort(key=lambda ch: (ORDER.get(ch.kind, 9), ch.record, ch.metric))
    result.timing = _timing_table(timing_rows)
    return result


def _compare_value(rid: str, metric: str, bv: Any, cv: Any, rule: Rule) -> Change | None:
    """None when unchanged within tolerance; Change(kind='skip') when there is nothing to hold."""
    b, c = _number(bv), _number(cv)
    if b is None and c is None:
        if _missing(bv) and _missing(cv) or bv == cv:
            return Change("skip", rid)
        return Change("info", rid, metric, bv, cv, "info")
    if b is None:
        if rule.gate and rule.direction != "info":  # the gate is off for it: say so
            return Change("unheld", rid, metric, bv, cv, rule.describe(),
                          "no baseline value: not held")
        return Change("info", rid, metric, bv, cv, rule.describe(), "new metric")
    if c is None:
        kind = "regression" if rule.gate else "info"
        return Change(kind, rid, metric, bv, cv, rule.describe(), "metric missing now")
    diff = c - b
    if abs(diff) <= rule.rtol * abs(b) + rule.atol:
        return None
    if not rule.gate or rule.direction == "info":
        return Change("info", rid, metric, bv, cv, rule.describe())
    worse = rule.direction == "equal" or (diff > 0) == (rule.direction == "lower")
    kind = ("regression" if worse else "better")
    return Change(kind, rid, metric, bv, cv, rule.describe(),
                  "changed" if rule.direction == "equal" else "")


def _timing_table(rows: list[dict[str, Any]]) -> pd.DataFrame:
    if not rows:
        return pd.DataFrame()
    df = pd.DataFrame(rows)
    out = []
    for (case, solver), g in df.groupby(["case", "solver"], sort=False):
        wb, wc = g["wall_time_s_base"].sum(), g["wall_time_s_cur"].sum()
        ratio = (g["particle_steps_per_s_cur"] / g["particle_steps_per_s_base"]).replace(
            [math.inf, -math.inf], math.nan).dropna()
        out.append({"case": case, "solver": solver, "runs": len(g),
                    "wall time base [s]": round(float(wb), 2),
                    "wall time now [s]": round(float(wc), 2),
                    "wall time ratio": round(float(wc / wb), 3) if wb > 0 else None,
                    "median particle-steps/s ratio": round(float(ratio.median()), 3)
                    if len(ratio) else None})
    return pd.DataFrame(out)


def _describe(records: list[dict[str, Any]]) -> str:
    def values(key: str) -> str:
        return ", ".join(sorted({str(r.get(key)) for r in records}))

    return (f"{len(records)} records; cases {values('case')}; solvers {values('solver')}; "
            f"tiers {values('tier')}")


# ---------------------------------------------------------------- rendering


def fmt_value(v: Any) -> str:
    n = _number(v)
    if n is not None and not isinstance(v, bool):
        return f"{n:.4g}"
    return "" if v is None else str(v)


def _rel(ch: Change) -> str:
    r = ch.relative
    if r is None:
        return ""
    return f"{r:+.1%}" if math.isfinite(r) else ("+inf" if r > 0 else "-inf")


def changes_frame(cmp: Comparison) -> pd.DataFrame:
    rows = [{"change": ch.kind.upper() if ch.kind == "regression" else ch.kind,
             "record": ch.record, "metric": ch.metric, "baseline": fmt_value(ch.baseline),
             "current": fmt_value(ch.current), "rel. change": _rel(ch), "rule": ch.rule,
             "note": ch.note} for ch in cmp.changes]
    return pd.DataFrame(rows, columns=["change", "record", "metric", "baseline", "current",
                                       "rel. change", "rule", "note"])


def summary_line(cmp: Comparison) -> str:
    return (f"{cmp.matched} matched records ({cmp.n_baseline} in baseline, {cmp.n_current} now), "
            f"{cmp.compared} metric values held against their tolerance: "
            f"{cmp.count('regression')} regression(s), "
            + (f"{cmp.count('unheld')} not held (no baseline value), " if cmp.count("unheld")
               else "")
            + f"{cmp.count('better')} better, "
            f"{cmp.count('info')} informational change(s), {cmp.count('appeared')} appeared, "
            f"{cmp.count('vanished')} vanished.")


def render_markdown(cmp: Comparison, baseline: str, current: str,
                    meta: tuple[dict[str, Any], dict[str, Any]] | None = None) -> str:
    verdict = f"{len(cmp.regressions)} REGRESSION(S)" if cmp.regressions else "no regression"
    lines = [f"## mpsbench compare: {verdict}", ""]
    for label, path, rec in (("Baseline", baseline, meta[0] if meta else {}),
                             ("Current", current, meta[1] if meta else {})):
        bits = [f"**{label}**: `{str(path).replace('`', '')}`"]
        for key, name in (("tier", "tier"), ("mpsbench_version", "mpsbench"),
                          ("git_commit", "commit"), ("machine", "machine")):
            if rec.get(key):
                bits.append(f"{name} {md_escape(rec[key])}")
        lines.append(", ".join(bits) + "  ")
    lines += ["", summary_line(cmp), ""]
    df = changes_frame(cmp)
    if df.empty:
        lines += ["Every compared metric is within its tolerance.", ""]
    else:
        lines += [str(md_frame(df).to_markdown(index=False)), ""]
    if not cmp.timing.empty:
        lines += ["### Timing (informational; never a regression)", "",
                  str(md_frame(cmp.timing).to_markdown(index=False, floatfmt=".4g")), ""]
    if cmp.count("vanished") or cmp.count("appeared"):
        lines += ["Records appeared or vanished: if the case grids changed on purpose, refresh the "
                  "baseline (see validations/baselines/README.md).", ""]
    return "\n".join(lines)
