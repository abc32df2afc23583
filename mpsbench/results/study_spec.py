"""Study files: a TOML description of a parameter study, checked in full before any run starts.

A study file names the case(s), the solver(s), the tier, the grid (lists per parameter and/or
explicit combinations) and optional tolerances (``docs/studies.md`` is the reference)::

    name = "couette-laplacians"
    case = "couette"
    solvers = ["reference"]
    tier = "smoke"

    [params]                  # fixed for every run
    l0 = 0.05

    [grid]                    # swept: the runs are the product of these lists
    laplacian = ["koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic"]
    weight = ["wf1", "wf2"]
    re_ratio = [2.1, 3.1, 4.0]

    [[runs]]                  # explicit combinations, added to the grid's runs
    laplacian = "xu-jin"
    weight = "wf2"
    re_ratio = 5.0

    [tolerances]              # every completed run must satisfy these (metric <= number)
    l2_error = 0.05
    linf_error = { max = 0.1 }

:func:`load_study` raises :class:`StudyFileError` naming the file, the key, the value and what
is allowed -- for every problem found, not only the first -- so a typo never costs a run.
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mpsbench.cases import CASES, TIERS, Case, CaseCheck, Param
from mpsbench.errors import ConfigError
from mpsbench.registry import PluginLoadError, UnknownNameError
from mpsbench.results.executors import EXECUTORS
from mpsbench.results.records import Task
from mpsbench.results.sweep import solver_tasks

DEFAULT_OUT = Path("reports") / "studies"
"""Studies write to ``reports/studies/<name>`` unless the file or ``--out`` says otherwise."""

TOP_KEYS: dict[str, str] = {
    "name": "a short name: letters, digits, '.', '_', '-' (default: the file name)",
    "description": "free text",
    "case": "a case name (see 'mpsbench validate --list')",
    "cases": "a list of case names",
    "solver": "a solver spec: a name, or NAME:key=value,... with its options (see "
              "'mpsbench solvers')",
    "solvers": "a list of solver specs (default [\"reference\"])",
    "tier": "one of smoke, quick, paper (default quick)",
    "out": "the output folder, relative to the current directory (default reports/studies/NAME)",
    "jobs": "an integer >= 1 (default 1)",
    "executor": "one of local, dask (default local)",
    "scheduler": "a dask scheduler address such as tcp://host:8786",
    "params": "a table: parameter = value, fixed for every run",
    "grid": "a table: parameter = [values], the runs are the product of the lists",
    "runs": "an array of tables ([[runs]]): explicit parameter combinations",
    "tolerances": "a table: metric = number (upper bound) or {max = number, min = number}",
}

# Case parameters whose values are registry names: checked against the registry even when the
# case does not list the choices, so a plugin's model is accepted and a typo is not.
MODEL_PARAMS = {"laplacian": "laplacians", "weight": "weights", "gradient": "gradients"}

_NAME_RE = re.compile(r"^[A-Za-z0-9._-]+$")


class StudyFileError(ConfigError):
    """A study file is invalid; ``problems`` lists every problem (``key: message``)."""

    def __init__(self, path: Path | str, problems: list[str]) -> None:
        self.path = Path(path)
        self.problems = problems
        head = f"{path}: {len(problems)} problem{'s' if len(problems) > 1 else ''}"
        super().__init__(head + "\n  " + "\n  ".join(problems) if len(problems) > 1
                         else f"{path}: {problems[0]}")


@dataclass(frozen=True)
class Tolerance:
    """Bounds on one metric; either bound may be None."""

    metric: str
    max: float | None = None
    min: float | None = None

    def describe(self) -> str:
        parts = []
        if self.min is not None:
            parts.append(f">= {self.min:g}")
        if self.max is not None:
            parts.append(f"<= {self.max:g}")
        return f"{self.metric} " + " and ".join(parts)


@dataclass(frozen=True)
class StudySpec:
    """A validated study file."""

    path: Path
    name: str
    cases: tuple[str, ...]
    solvers: tuple[str, ...] = ("reference",)
    tier: str = "quick"
    description: str = ""
    params: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list[Any]] = field(default_factory=dict)
    runs: tuple[dict[str, Any], ...] = ()
    tolerances: tuple[Tolerance, ...] = ()
    out: Path | None = None
    jobs: int | None = None
    executor: str | None = None
    scheduler: str | None = None
    source: str = ""  # the file's text, kept with the results

    def default_out(self) -> Path:
        return self.out if self.out is not None else DEFAULT_OUT / self.name

    def case_objects(self) -> list[Case]:
        return [CASES.get(name) for name in self.cases]

    def param_sets(self, case: Case) -> list[dict[str, Any]]:
        """Every parameter set of ``case``: the grid's product plus the explicit runs."""
        fixed = {k: [v] for k, v in self.params.items()}
        sets: list[dict[str, Any]] = []
        if self.grid or not self.runs:
            sets += case.expand(self.tier, {**fixed, **self.grid})
        for combo in self.runs:
            sets += case.expand(self.tier, {**fixed, **{k: [v] for k, v in combo.items()}})
        return sets

    def size(self) -> int:
        """Runs of the study before duplicates are removed, counted without expanding."""
        from mpsbench.results.guard import grid_size

        fixed = {k: [v] for k, v in self.params.items()}
        total = 0
        for case in self.case_objects():
            if self.grid or not self.runs:
                total += grid_size(case, self.tier, {**fixed, **self.grid})
            for combo in self.runs:
                total += grid_size(case, self.tier, {**fixed, **{k: [v] for k, v in combo.items()}})
        return total * len(self.solvers)

    def tasks(self) -> list[Task]:
        """Every run of the study (deduplicated), case by case, solver by solver."""
        out: list[Task] = []
        seen: set[str] = set()
        for case in self.case_objects():
            sets = self.param_sets(case)
            for solver in self.solvers:
                # an outside code's runs: the MPS settings it ignores at their defaults, one
                # run per physical set, the records say which settings do not apply
                for task in solver_tasks(case, solver, self.tier, sets):
                    if task.run_hash not in seen:  # the same run from the grid and [[runs]]
                        seen.add(task.run_hash)
                        out.append(task)
        return out


# --------------------------------------------------------------------------- loading


def load_study(path: str | Path, max_runs: int | None = None) -> StudySpec:
    """Read and validate a study file; raise :class:`StudyFileError` listing every problem.

    With ``max_runs``, a study planning more runs than that (counted from the grid, before it
    is expanded) is refused with a :class:`~mpsbench.errors.UsageError` (the ``--yes`` guard).
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise StudyFileError(path, ["no such file"]) from None
    except OSError as exc:
        raise StudyFileError(path, [f"cannot read: {exc.strerror or exc}"]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise StudyFileError(path, [f"not UTF-8 text ({exc.reason} at byte {exc.start}); "
                                    "a study file is TOML, which is UTF-8"]) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise StudyFileError(path, [f"not valid TOML: {exc}"]) from None
    except (ValueError, RecursionError) as exc:  # an integer of > 4300 digits, deep nesting
        raise StudyFileError(path, [f"not valid TOML: {type(exc).__name__}: {exc}"]) from None
    return parse_study(data, path, text, max_runs=max_runs)


def parse_study(data: dict[str, Any], path: str | Path = "<study>", text: str = "",
                max_runs: int | None = None) -> StudySpec:
    """Validate an already parsed study table (see :func:`load_study`)."""
    v = _Validator(Path(path), max_runs)
    spec = v.run(data, text)
    if v.problems:
        raise StudyFileError(path, v.problems)
    assert spec is not None
    return spec


def _suggest(word: str, options: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(options), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _fmt(value: Any) -> str:
    return repr(value) if not isinstance(value, str) else f'"{value}"'


class _Validator:
    """Collects every problem of a study file instead of stopping at the first."""

    def __init__(self, path: Path, max_runs: int | None = None) -> None:
        self.path = path
        self.max_runs = max_runs
        self.problems: list[str] = []

    def fail(self, key: str, message: str) -> None:
        self.problems.append(f"{key}: {message}")

    # ---- top level
    def run(self, data: dict[str, Any], text: str) -> StudySpec | None:
        for key in data:
            if key not in TOP_KEYS:
                self.fail(key, "unknown key" + _suggest(key, list(TOP_KEYS))
                          + "; allowed keys: " + ", ".join(TOP_KEYS))
        name = self._name(data)
        description = self._string(data, "description", "")
        case_names = self._names(data, "case", "cases", required=True)
        solver_names = self._names(data, "solver", "solvers", default=["reference"])
        tier = self._string(data, "tier", "quick")
        if tier not in TIERS:
            self.fail("tier", f"{_fmt(tier)} is not allowed: one of {', '.join(TIERS)}")
        jobs = data.get("jobs")
        if jobs is not None and (not isinstance(jobs, int) or isinstance(jobs, bool) or jobs < 1):
            self.fail("jobs", f"{_fmt(jobs)} is not allowed: an integer >= 1")
            jobs = None
        executor = data.get("executor")
        if executor is not None and executor not in EXECUTORS:
            self.fail("executor", f"{_fmt(executor)} is not allowed: one of {', '.join(EXECUTORS)}")
            executor = None
        scheduler = self._string(data, "scheduler", "") or None
        if scheduler and executor == "local":
            self.fail("scheduler", "a scheduler address only goes with executor = \"dask\"")
        out = self._string(data, "out", "") or None

        cases: list[Case] = self._load_named(
            case_names, "cases" if "cases" in data else "case", CASES, "case")
        solver_names = self._solvers(solver_names, "solvers" if "solvers" in data else "solver")
        for case in cases:
            if tier in TIERS and tier not in case.tiers:
                self.fail("tier", f"{_fmt(tier)} is not a tier of case {case.name!r}: one of "
                          + ", ".join(case.tiers))
        params = self._params_table(data, "params", cases, scalar=True)
        grid = self._params_table(data, "grid", cases, scalar=False)
        runs = self._runs(data, cases)
        tolerances = self._tolerances(data, cases)
        if self.problems:
            return None
        spec = StudySpec(
            path=self.path, name=name, cases=tuple(c.name for c in cases),
            solvers=tuple(solver_names), tier=tier, description=description,
            params=params, grid=grid, runs=tuple(runs), tolerances=tuple(tolerances),
            out=Path(out) if out else None, jobs=jobs, executor=executor, scheduler=scheduler,
            source=text,
        )
        if self.max_runs is not None:  # before the expansion, which a huge grid makes slow
            from mpsbench.results.guard import check_run_count

            check_run_count(spec.size(), False, f"{self.path}")
        try:  # the full expansion re-checks every combination
            if not spec.tasks():
                self.fail("grid", "the study has no runs")
        except (ConfigError, ValueError) as exc:
            self.fail("grid", str(exc))
        return spec

    def _string(self, data: dict[str, Any], key: str, default: str) -> str:
        value = data.get(key, default)
        if not isinstance(value, str):
            self.fail(key, f"{_fmt(value)} is not allowed: a string")
            return default
        return value

    def _name(self, data: dict[str, Any]) -> str:
        name = self._string(data, "name", self.path.stem)
        if not _NAME_RE.match(name):
            self.fail("name", f"{_fmt(name)} is not allowed: {TOP_KEYS['name']}")
        return name

    def _names(self, data: dict[str, Any], one: str, many: str, *, required: bool = False,
               default: list[str] | None = None) -> list[str]:
        if one in data and many in data:
            self.fail(one, f"give either {one!r} or {many!r}, not both")
            return []
        if one in data:
            value = data[one]
            if not isinstance(value, str) or not value:
                self.fail(one, f"{_fmt(value)} is not allowed: a name (string)")
                return []
            return [value]
        if many in data:
            value = data[many]
            if (not isinstance(value, list) or not value
                    or not all(isinstance(x, str) and x for x in value)):
                self.fail(many, f"{_fmt(value)} is not allowed: a non-empty list of names")
                return []
            return list(dict.fromkeys(value))
        if required:
            self.fail(one, f"missing: give {one!r} (one name) or {many!r} (a list)")
            return []
        return list(default or [])

    def _load_named(self, names: list[str], given: str, registry: Any, what: str) -> list[Any]:
        """Look each name up in ``registry``; an unknown or broken entry is reported under its
        key (``cases[1]`` for a list, ``case`` for a single name) and left out."""
        out = []
        for k, name in enumerate(names):
            key = f"{given}[{k}]" if given == f"{what}s" else given
            if name not in registry:
                self.fail(key, f"unknown {what} {name!r}" + _suggest(name, registry.names())
                          + f"; known {what}s: " + ", ".join(registry.names()))
                continue
            try:
                out.append(registry.get(name))
            except PluginLoadError as exc:
                self.fail(key, str(exc))
        return out

    def _solvers(self, specs: list[str], given: str) -> list[str]:
        """Check each solver spec (``numba``, ``numba:threads=1``): the name against the
        registry, the options against the backend's; return the canonical specs."""
        from mpsbench.run.protocol import SOLVERS
        from mpsbench.run.specs import solver_spec

        out = []
        for k, spec in enumerate(specs):
            key = f"{given}[{k}]" if given == "solvers" else given
            name = spec.partition(":")[0].strip()
            if not self._load_named([name], key, SOLVERS, "solver"):
                continue
            try:
                out.append(solver_spec(spec).text)
            except ConfigError as exc:
                self.fail(key, str(exc))
        return list(dict.fromkeys(out))

    # ---- parameters
    def _param_for(self, key: str, name: str, cases: list[Case]) -> list[Param] | None:
        """The parameter ``name`` of every case (reporting the cases that lack it)."""
        found = []
        for case in cases:
            known = [p.name for p in case.params]
            if name not in known:
                self.fail(key, f"unknown parameter of case {case.name!r}" + _suggest(name, known)
                          + "; allowed: " + ", ".join(known))
                return None
            found.append(case.param(name))
        return found

    def _value(self, key: str, params: list[Param], value: Any) -> Any:
        """One value checked against the parameter of every case (and the model registries)."""
        if isinstance(value, (list, dict)):
            self.fail(key, f"{_fmt(value)} is not allowed: a single value")
            return None
        out = value
        for param in params:
            try:
                if isinstance(value, str) and param.kind is not str:
                    out = param.parse(value)
                else:
                    out = param.check(value)
            except ConfigError:
                unit = f" ({param.unit})" if param.unit else ""
                hint = (_suggest(value, [str(c) for c in param.choices])
                        if isinstance(value, str) and param.choices else "")
                self.fail(key, f"{_fmt(value)} is not allowed{hint}: {param.allowed()}{unit}")
                return None
        registry = _model_registry(params[0].name) if params else None
        if registry is not None and isinstance(out, str):
            if out not in registry:
                names = registry.names()
                self.fail(key, f"unknown {registry.kind} {out!r}" + _suggest(out, names)
                          + "; known: " + ", ".join(names))
                return None
            try:
                registry.get(out)  # a plugin that does not load fails here, not in every run
            except PluginLoadError as exc:
                self.fail(key, str(exc))
                return None
        return out

    def _params_table(self, data: dict[str, Any], section: str, cases: list[Case], *,
                      scalar: bool) -> dict[str, Any]:
        table = data.get(section)
        if table is None:
            return {}
        if not isinstance(table, dict):
            self.fail(section, f"is not allowed as {_fmt(table)}: {TOP_KEYS[section]}")
            return {}
        out: dict[str, Any] = {}
        for name, raw in table.items():
            key = f"{section}.{name}"
            params = self._param_for(key, name, cases)
            if params is None:
                continue
            if scalar:
                value = self._value(key, params, raw)
                if value is not None:
                    out[name] = value
                continue
            values = raw if isinstance(raw, list) else [raw]
            if not values:
                self.fail(key, "an empty list: give at least one value")
                continue
            checked = []
            for k, item in enumerate(values):
                item_key = f"{key}[{k}]" if isinstance(raw, list) else key
                value = self._value(item_key, params, item)
                if value is not None:
                    checked.append(value)
            if len(checked) == len(values):
                out[name] = list(dict.fromkeys(checked))
        if section == "grid":
            fixed = data.get("params")
            both = sorted(set(out) & set(fixed if isinstance(fixed, dict) else ()))
            for name in both:
                self.fail(f"grid.{name}", "also set in [params]: give it in one place")
        return out

    def _runs(self, data: dict[str, Any], cases: list[Case]) -> list[dict[str, Any]]:
        runs = data.get("runs")
        if runs is None:
            return []
        if not isinstance(runs, list) or not all(isinstance(r, dict) for r in runs):
            self.fail("runs", f"is not allowed: {TOP_KEYS['runs']}")
            return []
        out = []
        for k, combo in enumerate(runs):
            if not combo:
                self.fail(f"runs[{k}]", "an empty combination")
                continue
            checked = {}
            for name, raw in combo.items():
                key = f"runs[{k}].{name}"
                params = self._param_for(key, name, cases)
                if params is None:
                    continue
                value = self._value(key, params, raw)
                if value is not None:
                    checked[name] = value
            if len(checked) == len(combo):
                out.append(checked)
        return out

    def _tolerances(self, data: dict[str, Any], cases: list[Case]) -> list[Tolerance]:
        table = data.get("tolerances")
        if table is None:
            return []
        if not isinstance(table, dict):
            self.fail("tolerances", f"is not allowed: {TOP_KEYS['tolerances']}")
            return []
        declared: dict[str, None] = {}
        for case in cases:
            declared.update(dict.fromkeys(case.metrics))
        out = []
        for metric, raw in table.items():
            key = f"tolerances.{metric}"
            if declared and metric not in declared:
                self.fail(key, "unknown metric" + _suggest(metric, list(declared))
                          + "; metrics of the case(s): " + ", ".join(declared))
                continue
            bounds = raw if isinstance(raw, dict) else {"max": raw}
            ok = True
            for bound, value in bounds.items():
                if bound not in ("max", "min"):
                    self.fail(f"{key}.{bound}", "unknown key; allowed: max, min")
                    ok = False
                elif (isinstance(value, bool) or not isinstance(value, (int, float))
                        or not math.isfinite(value)):
                    self.fail(f"{key}.{bound}" if isinstance(raw, dict) else key,
                              f"{_fmt(value)} is not allowed: a finite number")
                    ok = False
            if ok and not bounds:
                self.fail(key, "give max and/or min")
                ok = False
            if ok:
                tol = Tolerance(metric, _num(bounds.get("max")), _num(bounds.get("min")))
                if tol.max is not None and tol.min is not None and tol.min > tol.max:
                    self.fail(key, f"min {tol.min:g} is above max {tol.max:g}")
                    continue
                out.append(tol)
        return out


def _num(value: Any) -> float | None:
    return None if value is None else float(value)


def _model_registry(param_name: str) -> Any:
    category = MODEL_PARAMS.get(param_name)
    if category is None:
        return None
    from mpsbench.physics.gradients import GRADIENTS
    from mpsbench.physics.laplacians import LAPLACIANS
    from mpsbench.physics.weights import WEIGHTS

    return {"laplacians": LAPLACIANS, "weights": WEIGHTS, "gradients": GRADIENTS}[category]


# --------------------------------------------------------------------------- tolerances


def check_tolerances(
    spec: StudySpec, records: list[dict[str, Any]]
) -> list[CaseCheck]:
    """One check per tolerance: every completed run's metric lies within the bounds.

    A completed run without the metric (another case of the study) is not counted; a run that
    failed or diverged has no value to hold against the bound and is listed as a violation.
    """
    out = []
    for tol in spec.tolerances:
        bad: list[str] = []
        n = 0
        for rec in records:
            if rec.get("status") != "completed":
                if tol.metric in _case_metrics(rec.get("case", "")):
                    bad.append(f"{rec.get('run_id')} ({rec.get('status')})")
                continue
            if tol.metric not in rec:
                continue
            value = rec[tol.metric]
            n += 1
            if not isinstance(value, (int, float)) or value is None or (
                    tol.max is not None and value > tol.max) or (
                    tol.min is not None and value < tol.min):
                bad.append(f"{rec.get('run_id')} = {value!r}")
        name = f"tolerance: {tol.describe()}"
        if bad:
            shown = "; ".join(bad[:5]) + (f"; ... {len(bad) - 5} more" if len(bad) > 5 else "")
            out.append(CaseCheck(name, False, f"{len(bad)} run(s) outside: {shown}"))
        elif n == 0:
            out.append(CaseCheck(name, None, "no completed run has this metric"))
        else:
            out.append(CaseCheck(name, True, f"all {n} completed runs within"))
    return out


def _case_metrics(name: str) -> dict[str, str]:
    try:
        return dict(CASES.get(name).metrics)
    except (PluginLoadError, UnknownNameError):
        return {}
