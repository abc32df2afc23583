"""Conformance kit for solver backends, in the style of scikit-learn's ``check_estimator``.

Run every check on a solver (a registry name, a class or an instance)::

    from mpsbench.testing import check_solver
    results = check_solver("reference")          # raises SolverCheckError if a check fails
    results = check_solver(MySolver, on_fail="return")   # or just collect the outcomes

or get one pytest test per check in your own test suite::

    from mpsbench.testing import parametrize_solver_checks

    @parametrize_solver_checks(MySolver)
    def test_conformance(solver, check):
        check(solver)

Checks are chosen by the solver's declared :class:`~mpsbench.run.protocol.Capabilities`: a check
that needs something the solver does not declare is skipped with the reason.  A solver lists
the checks it is known to fail in a class attribute ``expected_failures: dict[str, str]``
(check name -> reason); those are reported as ``xfail`` (``xpass`` if they pass after all).

From the command line: ``mpsbench check NAME [--json]``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from mpsbench.errors import where

from .catalogue import all_checks
from .checks import (
    Check,
    SkipCheck,
    SolverSpec,
    capabilities_of,
    expected_failures,
    fresh_solver,
    solver_label,
)

Outcome = Literal["pass", "fail", "skip", "xfail", "xpass"]


@dataclass(frozen=True)
class ConformanceResult:
    """The outcome of one check: ``pass``, ``fail``, ``skip``, ``xfail`` or ``xpass``."""

    check: str
    outcome: Outcome
    reason: str = ""
    seconds: float = 0.0

    @property
    def failed(self) -> bool:
        return self.outcome == "fail"

    def as_dict(self) -> dict[str, Any]:
        return {
            "check": self.check,
            "outcome": self.outcome,
            "reason": self.reason,
            "seconds": round(self.seconds, 4),
        }


class SolverCheckError(AssertionError):
    """At least one check failed; ``results`` holds every outcome."""

    def __init__(self, solver: str, results: list[ConformanceResult]) -> None:
        self.results = results
        failed = [r for r in results if r.failed]
        lines = [f"{r.check}: {r.reason}" for r in failed]
        super().__init__(
            f"solver {solver!r} failed {len(failed)} of {len(results)} checks:\n  "
            + "\n  ".join(lines)
        )


def select_checks(select: Iterable[str] | str | None = None) -> list[Check]:
    """All checks, or the selected ones.

    A selector equal to a check name selects that check; otherwise it selects every check whose
    name contains it.
    """
    checks = all_checks()
    if select is None:
        return checks
    wanted = [select] if isinstance(select, str) else list(select)
    names = {c.name for c in checks}

    def chosen(name: str) -> bool:
        return any(name == w if w in names else w in name for w in wanted)

    return [c for c in checks if chosen(c.name)]


def run_check(
    check: Check, solver: SolverSpec, xfail_reason: str | None = None
) -> ConformanceResult:
    """Run one check and turn its outcome into a :class:`ConformanceResult` (never raises)."""
    t0 = time.perf_counter()
    try:
        check(solver)
    except SkipCheck as exc:
        return ConformanceResult(check.name, "skip", str(exc), time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - a crashing solver is a failed check
        if isinstance(exc, AssertionError):
            reason = str(exc) or "assertion failed"
        else:
            reason = f"{type(exc).__name__}: {exc}{where(exc)}"
        outcome: Outcome = "xfail" if xfail_reason is not None else "fail"
        if xfail_reason is not None:
            reason = f"{xfail_reason} [{reason}]"
        return ConformanceResult(check.name, outcome, reason, time.perf_counter() - t0)
    if xfail_reason is not None:
        return ConformanceResult(
            check.name, "xpass", f"expected to fail: {xfail_reason}", time.perf_counter() - t0
        )
    return ConformanceResult(check.name, "pass", "", time.perf_counter() - t0)


def check_solver(
    solver: SolverSpec,
    *,
    checks: Iterable[str] | str | None = None,
    on_fail: Literal["raise", "return"] = "raise",
    callback: Callable[[ConformanceResult], None] | None = None,
) -> list[ConformanceResult]:
    """Run the conformance checks on ``solver`` (a registry name, a class or an instance).

    ``checks`` keeps only the named checks, or those whose name contains a given substring.
    ``callback`` sees each result as soon as it is known (for progress output).
    With ``on_fail="raise"`` a :class:`SolverCheckError` listing the failures is raised after
    every check has run; with ``"return"`` the results are returned either way.
    """
    if on_fail not in ("raise", "return"):
        raise ValueError(f"check_solver: on_fail = {on_fail!r}: use 'raise' or 'return'")
    xfails = expected_failures(solver)
    results = []
    for check in select_checks(checks):
        result = run_check(check, solver, xfails.get(check.name))
        if callback is not None:
            callback(result)
        results.append(result)
    if on_fail == "raise" and any(r.failed for r in results):
        raise SolverCheckError(solver_label(solver), results)
    return results


class _PytestCheck:
    """A check as handed to a parametrized test: ``check(solver)``; skips become pytest skips."""

    def __init__(self, check: Check) -> None:
        self.check = check
        self.name = check.name

    def __call__(self, solver: SolverSpec) -> None:
        import pytest

        try:
            self.check(solver)
        except SkipCheck as exc:
            pytest.skip(str(exc))

    def __repr__(self) -> str:
        return self.name


@dataclass(frozen=True)
class PlannedCheck:
    """One (solver, check) test of the kit, before it runs: what ``parametrize_solver_checks``
    and the pytest plugin (:mod:`mpsbench.testing.pytest_plugin`) each turn into a test.

    ``check`` is None when the solver cannot be loaded (``unavailable`` says why); ``skip`` is
    the reason a check does not apply; ``xfail`` the reason the solver expects it to fail.
    """

    solver: SolverSpec
    id: str
    check: Check | None
    skip: str | None = None
    xfail: str | None = None
    unavailable: str | None = None


def plan_solver_checks(
    solvers: Iterable[SolverSpec], checks: Sequence[str] | str | None = None
) -> list[PlannedCheck]:
    """Every (solver, check) test, ids ``<solver>-<check>``; ``<solver>-unavailable`` for a solver
    that cannot be loaded (a missing optional dependency).  An unknown name raises the
    registry's error."""
    from mpsbench.registry import PluginLoadError

    planned = []
    for spec in solvers:
        label = solver_label(spec)
        try:
            caps = capabilities_of(spec)
            xfails = expected_failures(spec)
        except PluginLoadError as exc:
            planned.append(PlannedCheck(spec, f"{label}-unavailable", None, unavailable=str(exc)))
            continue
        for check in select_checks(checks):
            skip = check.skip_reason(caps)
            xfail = None if skip else xfails.get(check.name)
            planned.append(PlannedCheck(spec, f"{label}-{check.name}", check, skip, xfail))
    return planned


def parametrize_solver_checks(
    *solvers: SolverSpec, checks: Sequence[str] | str | None = None
) -> Any:
    """A ``pytest.mark.parametrize("solver, check", ...)`` decorator: one test per check.

    Test ids read ``<solver>-<check>`` (``reference-check_momentum_pgm2``).  Checks the solver
    cannot run are marked skip with the reason; its ``expected_failures`` are marked xfail.
    A solver that cannot be loaded (missing optional dependency) gives one skipped test.
    """
    import pytest

    if not solvers:
        raise ValueError("parametrize_solver_checks: give at least one solver")
    params = []
    for planned in plan_solver_checks(solvers, checks):
        marks = []
        if planned.check is None:
            marks.append(pytest.mark.skip(reason=str(planned.unavailable)))
        elif planned.skip:
            marks.append(pytest.mark.skip(reason=planned.skip))
        elif planned.xfail is not None:
            marks.append(pytest.mark.xfail(reason=planned.xfail, strict=False))
        check = _PytestCheck(planned.check) if planned.check is not None else None
        params.append(pytest.param(planned.solver, check, id=planned.id, marks=marks))
    return pytest.mark.parametrize("solver, check", params)


__all__ = [
    "Check",
    "ConformanceResult",
    "PlannedCheck",
    "SkipCheck",
    "SolverCheckError",
    "all_checks",
    "check_solver",
    "fresh_solver",
    "parametrize_solver_checks",
    "plan_solver_checks",
    "run_check",
    "select_checks",
]
