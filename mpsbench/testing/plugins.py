"""Run a validation case on your solver from your own tests.

The conformance kit (:mod:`mpsbench.testing`) checks that a backend behaves; this helper checks
that it gets the physics right, by running a case (diffusion, Couette, ...) through the same
study machinery as ``mpsbench validate`` and handing back the records and the case's checks::

    from mpsbench.testing.plugins import run_case

    def test_diffusion_on_my_solver(tmp_path):
        result = run_case("diffusion", MySolver, tier="smoke", laplacian="my-laplacian",
                          out=tmp_path)
        result.assert_ok()                      # every run completed, no case check failed
        assert max(result.metric("l2_error")) < 0.05

The solver may be a registry name, a solver class or an instance; the case a registry name or a
:class:`~mpsbench.cases.Case` instance (so a case under development needs no entry point).
Keyword arguments override the tier's parameters: a value fixes a parameter, a list sweeps it.
"""

from __future__ import annotations

import contextlib
import copy
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mpsbench.cases import CASES, Case, CaseCheck, get_case
from mpsbench.results.records import Task, run_ids
from mpsbench.results.sweep import run_tasks
from mpsbench.run.protocol import SOLVERS
from mpsbench.run.specs import get_solver_class


@dataclass
class CaseResult:
    """Records of every run of a case on a solver, and the case's checks (gates and claims)
    on them."""

    case: str
    solver: str
    tier: str
    records: list[dict[str, Any]]
    checks: list[CaseCheck] = field(default_factory=list)
    outdir: Path | None = None  # None when the runs were written to a deleted temp folder

    @property
    def failed_runs(self) -> list[dict[str, Any]]:
        """Runs that did not complete (failed or diverged)."""
        return [r for r in self.records if r.get("status") != "completed"]

    @property
    def failed_checks(self) -> list[CaseCheck]:
        """Gates that failed (a refuted claim of the paper is a finding, not listed here)."""
        return [c for c in self.checks if c.passed is False and not c.is_claim]

    @property
    def claims(self) -> list[CaseCheck]:
        """The case's claims with their verdicts (supported / refuted / inconclusive)."""
        return [c for c in self.checks if c.is_claim]

    def metric(self, name: str) -> list[Any]:
        """The values of one metric column, run by run (None where a run lacks it)."""
        return [r.get(name) for r in self.records]

    def assert_ok(self, *, allow_diverged: bool = False) -> None:
        """Raise ``AssertionError`` listing every failed run and failed case check."""
        bad = [r for r in self.failed_runs
               if not (allow_diverged and r.get("status") == "diverged")]
        lines = [f"run {r.get('run_id')}: {r.get('status')}: {r.get('reason', '')}" for r in bad]
        lines += [f"check {c.name}: {c.detail}" for c in self.failed_checks]
        if lines:
            raise AssertionError(
                f"case {self.case!r} on solver {self.solver!r} (tier {self.tier}): "
                f"{len(lines)} problem(s)\n  " + "\n  ".join(lines)
            )


def run_case(
    case: str | Case,
    solver: Any = "reference",
    *,
    tier: str = "smoke",
    out: str | Path | None = None,
    jobs: int = 1,
    report: bool = False,
    force: bool = True,
    **params: Any,
) -> CaseResult:
    """Run ``case`` on ``solver`` at ``tier``; return the records and the case's checks.

    ``params`` override the tier grid (a list sweeps the parameter); each value is validated
    like ``--set`` (an unknown name or a bad value raises
    :class:`~mpsbench.errors.ConfigError`
    before anything runs).  ``out``: keep the records (and with ``report=True`` the tables,
    figures and report.md) in this folder; default a temporary folder removed afterwards.
    ``force=False`` reuses records already in ``out``.  A solver or case that is not registered
    is registered for the duration of the call and runs in this process (``jobs`` is then 1).
    """
    with _registered_case(case) as case_obj, _registered_solver(solver) as solver_name:
        overrides = _overrides(case_obj, params)
        if not (isinstance(case, str) and isinstance(solver, str)):
            jobs = 1  # a temporary registration lives in this process only
        sets = case_obj.expand(tier, overrides)
        ids = run_ids(case_obj.name, solver_name, sets, case_obj.defaults())
        tasks = [Task(case_obj.name, solver_name, tier, p, rid)
                 for p, rid in zip(sets, ids, strict=True)]
        with _folder(out) as folder:
            records = run_tasks(tasks, folder, jobs=jobs, force=force)
            if report:
                from mpsbench.results.case_report import write_case_outputs

                checks = write_case_outputs(case_obj, records, folder)
            else:
                checks = (case_obj.checks(records) + case_obj.claims(records)) if records \
                    else []
        return CaseResult(case_obj.name, solver_name, tier, records, list(checks),
                          Path(out) if out is not None else None)


def _overrides(case: Case, params: dict[str, Any]) -> dict[str, Sequence[Any]]:
    out: dict[str, Sequence[Any]] = {}
    for name, value in params.items():
        param = case.param(name)  # ConfigError naming the known parameters
        values = list(value) if isinstance(value, (list, tuple)) else [value]
        out[name] = [
            param.parse(v) if isinstance(v, str) and param.kind is not str else param.check(v)
            for v in values
        ]
    return out


def _name_of(obj: Any) -> str:
    if isinstance(obj, str):
        return obj
    name = getattr(obj, "name", "")
    return name if isinstance(name, str) and name else type(obj).__name__


@contextlib.contextmanager
def _folder(out: str | Path | None) -> Iterator[Path]:
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        yield Path(out)
        return
    with tempfile.TemporaryDirectory(prefix="mpsbench-case-") as tmp:
        yield Path(tmp)


@contextlib.contextmanager
def _registered_case(case: str | Case) -> Iterator[Case]:
    if isinstance(case, str):
        yield get_case(case)
        return
    if not isinstance(case, Case):
        raise TypeError(f"run_case: case must be a name or a Case instance, got {case!r}")
    if case.name in CASES:
        try:
            same = CASES.get(case.name) is case
        except Exception:  # noqa: BLE001 - a broken registered entry: shadow it below
            same = False
        if same:
            yield case
            return
    previous = CASES._entries.get(case.name)
    CASES.register(case.name, case, origin="user", replace=True)
    try:
        yield case
    finally:
        CASES.unregister(case.name)
        if previous is not None:
            CASES._entries[case.name] = previous


class _InstanceFactory:
    """Stands for a solver class in the registry: calling it gives a fresh copy of an instance;
    other attributes (``name``, ``capabilities``, ...) are the instance's."""

    def __init__(self, template: Any) -> None:
        self._template = template

    def __call__(self) -> Any:
        return copy.deepcopy(self._template)

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._template, attr)


@contextlib.contextmanager
def _registered_solver(solver: Any) -> Iterator[str]:
    """A registry name for ``solver``: the name itself, or a temporary registration."""
    if isinstance(solver, str):
        get_solver_class(solver)  # unknown / broken: fail now, with the registry's message
        yield solver
        return
    if isinstance(solver, type):
        get_solver_class(solver)  # validates the class shape
        factory: Any = solver
    else:
        get_solver_class(type(solver))
        factory = _InstanceFactory(solver)

    name = _name_of(solver)
    if name in SOLVERS:
        try:
            if SOLVERS.get(name) is solver:
                yield name
                return
        except Exception:  # noqa: BLE001 - a broken entry of the same name: use another name
            pass
        name = f"{name}-under-test"
    SOLVERS.register(name, factory, origin="user", replace=True)
    try:
        yield name
    finally:
        SOLVERS.unregister(name)


__all__ = ["CaseResult", "run_case"]
