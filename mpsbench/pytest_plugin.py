"""pytest plugin: the conformance kit and validation cases as test items of a solver's own suite.

Installed with mpsbench (entry point ``pytest11``) and inert until asked for::

    pytest --mpsbench-solver example                     # adds one item per conformance check
    pytest --mpsbench-solver example --mpsbench-case diffusion --mpsbench-set laplacian=ko-local

or, in the solver's ``pyproject.toml``, the same as ini options::

    [tool.pytest.ini_options]
    mpsbench_solvers = ["example"]
    mpsbench_cases = ["diffusion"]          # optional
    mpsbench_set = ["laplacian=ko-local"]   # optional, applies to every case
    mpsbench_tier = "smoke"                 # the default

The items (each marked ``mpsbench``: ``-m mpsbench`` runs only them, ``-m "not mpsbench"`` the
rest)::

    mpsbench-conformance[example]::check_momentum_pgm2
        one per conformance check (:func:`mpsbench.testing.plan_solver_checks`): skipped when
        the solver does not declare what the check needs, xfail for its ``expected_failures``,
        failed with the check's message otherwise; a solver that cannot be loaded is one
        failed item (it was asked for by name)
    mpsbench-case[diffusion-example]::run <run id>
        one per run of the case at the tier: fails when the run diverged or failed, with the
        reason
    mpsbench-case[diffusion-example]::check <name>
        one per check of the case, mapped by :func:`mpsbench.results.junit.check_outcome`
        (did not hold: failed; undecided: skipped)

A case's runs happen while its items are collected, once per session (its checks are known only
from its records), so ``--collect-only`` runs them too; a case that cannot run (unknown name,
bad ``--mpsbench-set``, unknown tier) is a collection error with the reason.
``--mpsbench-out DIR`` keeps each case's folder (records, tables, figures, report.md) in
``DIR/<case>-<solver>/``.  ``--mpsbench-check SELECT`` keeps the checks whose name contains
SELECT (repeatable).

This module sits outside :mod:`mpsbench.testing` and imports it only inside the hooks: pytest
loads every ``pytest11`` plugin at start-up, and the kit pulls in numpy and scipy.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from mpsbench.cases import CaseCheck
    from mpsbench.testing import PlannedCheck

MARKER = "mpsbench"
DEFAULT_TIER = "smoke"


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("mpsbench", "mpsbench conformance kit and validation cases")
    group.addoption("--mpsbench-solver", action="append", default=None, metavar="NAME",
                    help="add the conformance kit's checks on this solver as test items "
                    "(repeatable; ini: mpsbench_solvers)")
    group.addoption("--mpsbench-check", action="append", default=None, metavar="SELECT",
                    help="only the checks whose name contains SELECT (repeatable; ini: "
                    "mpsbench_checks)")
    group.addoption("--mpsbench-case", action="append", default=None, metavar="CASE",
                    help="add a validation case's runs and checks on each solver as test items "
                    "(repeatable; ini: mpsbench_cases)")
    group.addoption("--mpsbench-tier", default=None, metavar="TIER",
                    help=f"tier of the cases (default {DEFAULT_TIER}; ini: mpsbench_tier)")
    group.addoption("--mpsbench-set", action="append", default=None,
                    metavar="KEY=VALUE[,VALUE...]",
                    help="fix (or, with a comma list, sweep) a parameter of every case "
                    "(repeatable; ini: mpsbench_set)")
    group.addoption("--mpsbench-out", default=None, metavar="DIR",
                    help="keep each case's folder under DIR/<case>-<solver>/ (default: a "
                    "temporary folder, removed; ini: mpsbench_out)")
    parser.addini("mpsbench_solvers", "solvers whose conformance checks become test items",
                  type="linelist", default=[])
    parser.addini("mpsbench_checks", "only the conformance checks whose name contains one of "
                  "these", type="linelist", default=[])
    parser.addini("mpsbench_cases", "validation cases whose runs and checks become test items",
                  type="linelist", default=[])
    parser.addini("mpsbench_tier", f"tier of the cases (default {DEFAULT_TIER})",
                  default=DEFAULT_TIER)
    parser.addini("mpsbench_set", "KEY=VALUE[,VALUE...] parameter overrides of every case",
                  type="linelist", default=[])
    parser.addini("mpsbench_out", "folder that keeps each case's outputs", default="")


def _setting(config: pytest.Config, option: str, ini: str) -> Any:
    value = config.getoption(option)
    return value if value is not None else config.getini(ini)


def _overrides(items: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise pytest.UsageError(f"--mpsbench-set {item!r}: expected KEY=VALUE[,VALUE...]")
        values = value.split(",")
        out[key.strip()] = values if len(values) > 1 else values[0]
    return out


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", f"{MARKER}: an item of the mpsbench pytest plugin "
                            "(conformance check, case run or case check)")
    solvers = list(_setting(config, "mpsbench_solver", "mpsbench_solvers"))
    cases = list(_setting(config, "mpsbench_case", "mpsbench_cases"))
    if cases and not solvers:
        raise pytest.UsageError("--mpsbench-case (mpsbench_cases) needs --mpsbench-solver "
                                "(mpsbench_solvers): the solver to run the case on")
    out = _setting(config, "mpsbench_out", "mpsbench_out")
    config.stash[_PLAN] = {
        "solvers": list(dict.fromkeys(solvers)),
        "checks": list(_setting(config, "mpsbench_check", "mpsbench_checks")) or None,
        "cases": list(dict.fromkeys(cases)),
        "tier": _setting(config, "mpsbench_tier", "mpsbench_tier") or DEFAULT_TIER,
        "set": _overrides(list(_setting(config, "mpsbench_set", "mpsbench_set"))),
        "out": Path(out) if out else None,
    }


_PLAN = pytest.StashKey[dict[str, Any]]()


@pytest.hookimpl(tryfirst=True)  # before -k / -m deselect, so they apply to these items too
def pytest_collection_modifyitems(session: pytest.Session, config: pytest.Config,
                                  items: list[pytest.Item]) -> None:
    plan = config.stash.get(_PLAN, None)
    if not plan or not plan["solvers"]:
        return
    collectors: list[pytest.Collector] = []
    for solver in plan["solvers"]:
        name = f"mpsbench-conformance[{solver}]"
        collectors.append(KitCollector.from_parent(session, name=name, nodeid=name,
                                                   solver=solver, checks=plan["checks"]))
    for case in plan["cases"]:
        for solver in plan["solvers"]:
            name = f"mpsbench-case[{case}-{solver}]"
            out = plan["out"] / f"{case}-{solver}" if plan["out"] is not None else None
            collectors.append(CaseCollector.from_parent(
                session, name=name, nodeid=name, case=case, solver=solver, tier=plan["tier"],
                overrides=plan["set"], out=out))
    for collector in collectors:
        items.extend(session.genitems(collector))


class ItemFailed(Exception):
    """A plugin item's failure: reported as its message, without a traceback."""


def _source(obj: Any) -> tuple[Path, int] | None:
    """Where ``obj`` (a function or class) is defined: skip and failure reports point there."""
    import inspect

    try:
        path = inspect.getsourcefile(obj)
        _, line = inspect.getsourcelines(obj)
    except (OSError, TypeError):
        return None
    return (Path(path), max(line - 1, 0)) if path else None


class _Item(pytest.Item):
    source: Any = None  # the function or class the item's outcome comes from

    def reportinfo(self) -> tuple[Path, int | None, str]:
        # a line number is needed: pytest's skip report asserts one
        where = _source(self.source) if self.source is not None else None
        path, line = where or (self.path, 0)
        return path, line, self.nodeid

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException],
                     style: Any = None) -> Any:
        if isinstance(excinfo.value, (ItemFailed, AssertionError)):
            return str(excinfo.value) or type(excinfo.value).__name__
        return super().repr_failure(excinfo, style=style)


class _Collector(pytest.Collector):
    def reportinfo(self) -> tuple[Path, int | None, str]:
        return self.path, 0, self.nodeid


class KitCollector(_Collector):
    """The conformance checks on one solver."""

    def __init__(self, *, solver: str, checks: list[str] | None, **kw: Any) -> None:
        super().__init__(**kw)
        self.solver, self.checks = solver, checks
        self.add_marker(MARKER)

    def collect(self) -> list[pytest.Item]:
        from mpsbench.registry import UnknownNameError
        from mpsbench.testing import plan_solver_checks

        try:
            planned = plan_solver_checks([self.solver], self.checks)
        except UnknownNameError as exc:
            raise self.CollectError(str(exc)) from None
        if not planned:
            raise self.CollectError(f"no conformance check matches {self.checks}")
        return [ConformanceItem.from_parent(self, name=p.id.removeprefix(f"{self.solver}-"),
                                            planned=p) for p in planned]


class ConformanceItem(_Item):
    def __init__(self, *, planned: PlannedCheck, **kw: Any) -> None:
        super().__init__(**kw)
        self.planned = planned
        self.source = planned.check.func if planned.check is not None else None
        if planned.skip:
            self.add_marker(pytest.mark.skip(reason=planned.skip))
        elif planned.xfail is not None:
            self.add_marker(pytest.mark.xfail(reason=planned.xfail, strict=False))

    def runtest(self) -> None:
        from mpsbench.testing import _PytestCheck

        if self.planned.check is None:
            raise ItemFailed(f"solver {self.planned.solver!r} cannot be loaded: "
                             f"{self.planned.unavailable}")
        _PytestCheck(self.planned.check)(self.planned.solver)


class CaseCollector(_Collector):
    """A case run on one solver at one tier: its runs and its checks."""

    def __init__(self, *, case: str, solver: str, tier: str, overrides: dict[str, Any],
                 out: Path | None, **kw: Any) -> None:
        super().__init__(**kw)
        self.case, self.solver, self.tier, self.overrides, self.out = (
            case, solver, tier, overrides, out)
        self.add_marker(MARKER)

    def collect(self) -> list[pytest.Item]:
        from mpsbench.cases import get_case
        from mpsbench.errors import MpsbenchError
        from mpsbench.registry import PluginLoadError, UnknownNameError
        from mpsbench.testing.plugins import run_case

        try:
            result = run_case(self.case, self.solver, tier=self.tier, out=self.out,
                              report=self.out is not None, **self.overrides)
        except (MpsbenchError, UnknownNameError, PluginLoadError) as exc:
            raise self.CollectError(f"case {self.case!r} on solver {self.solver!r}: {exc}") \
                from None
        if not result.records:
            raise self.CollectError(f"case {self.case!r}: no runs at tier {self.tier!r}")
        source = type(get_case(self.case))
        items: list[_Item] = [
            CaseRunItem.from_parent(self, name=f"run {rec.get('run_id')}", record=rec)
            for rec in result.records]
        items += [CaseCheckItem.from_parent(self, name=f"check {c.name}", check=c)
                  for c in result.checks]
        for item in items:
            item.source = source
        return list(items)


class CaseRunItem(_Item):
    def __init__(self, *, record: dict[str, Any], **kw: Any) -> None:
        super().__init__(**kw)
        self.record = record

    def runtest(self) -> None:
        status = self.record.get("status")
        if status != "completed":
            raise ItemFailed(f"{status}: {self.record.get('reason', '')}")


class CaseCheckItem(_Item):
    def __init__(self, *, check: CaseCheck, **kw: Any) -> None:
        from mpsbench.results.junit import check_outcome

        super().__init__(**kw)
        self.check = check
        self.outcome, self.message = check_outcome(check)
        if self.outcome == "skipped":  # known already: the case ran when it was collected
            self.add_marker(pytest.mark.skip(reason=self.message))

    def runtest(self) -> None:
        if self.outcome == "failed":
            raise ItemFailed(self.message)
