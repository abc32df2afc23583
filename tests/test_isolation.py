"""Crash isolation and run limits: a solver that segfaults is recorded ``crashed`` with the
signal, one that never returns from a step ``timed-out`` with the time it reached, one whose
runs go on too long ``timed-out`` by the step or wall-clock limit; the sweep goes on every time.

The fake solvers are the reference backend with one step changed; the case is a tiny periodic
flow (a few hundred particles, a few dozen steps) run through the runner as any case's.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mpsbench.solvers.reference import ReferenceSolver

from mpsbench.cases import Case, CaseCheck, CaseRun, Param
from mpsbench.cli import main
from mpsbench.results import supervise
from mpsbench.results.records import Task, load_records, task_limits
from mpsbench.results.sweep import run_tasks
from mpsbench.run.protocol import SOLVERS
from mpsbench.run.runner import RunLimits, run
from mpsbench.testing.problems import periodic_flow_problem
from tests.fake_cases import only_cases

STEPS = 12


class SegfaultSolver(ReferenceSolver):
    """Dies from SIGSEGV in its fourth step, as a native library would; declares isolation."""

    name = "fake-segfault"
    isolate = True

    def _advance(self, dt: float) -> None:
        if self.n_steps == 3:
            os.kill(os.getpid(), signal.SIGSEGV)
        super()._advance(dt)


class HangSolver(ReferenceSolver):
    """Its fourth step never returns (and declares nothing: isolation must be asked for)."""

    name = "fake-hang"

    def _advance(self, dt: float) -> None:
        if self.n_steps == 3:
            while True:
                time.sleep(0.05)
        super()._advance(dt)


class SlowSolver(ReferenceSolver):
    """Every step takes 0.2 s: a run the wall-clock limit stops between steps."""

    name = "fake-slow"

    def _advance(self, dt: float) -> None:
        time.sleep(0.2)
        super()._advance(dt)


FAKES = (SegfaultSolver, HangSolver, SlowSolver)


class TinyFlow(Case):
    """A few steps of a jittered periodic flow; the metric is the final time."""

    name = "tiny-flow"
    title = "Tiny periodic flow"
    params = (Param("steps", STEPS, "time steps", kind=int, minimum=1),)
    tiers = {"smoke": [{"steps": [STEPS]}]}
    metrics = {"t_end": "simulated time reached [s]"}

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        problem = periodic_flow_problem(n_side=8, velocity=0.05)
        res = run(solver, problem, max_steps=params["steps"])
        return CaseRun({"t_end": res.time}, [res])

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        done = [r for r in records if r["status"] == "completed"]
        return [CaseCheck("some run completed", bool(done), f"{len(done)} completed")]


@pytest.fixture()
def fakes() -> Iterator[None]:
    for cls in FAKES:
        SOLVERS.register(cls.name, cls, replace=True)
    try:
        with only_cases(TinyFlow()):
            yield
    finally:
        for cls in FAKES:
            SOLVERS.unregister(cls.name)


def tasks(*solvers: str, **limits: Any) -> list[Task]:
    return [Task("tiny-flow", s, "smoke", {"steps": STEPS}, f"tiny-{s}", **limits)
            for s in solvers]


def by_solver(records: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {r["solver"]: r for r in records}


def test_segfault_is_crashed_with_the_signal_and_the_sweep_goes_on(
        tmp_path: Path, fakes: None) -> None:
    # jobs=1: the segfaulting solver declares isolation, so the runs go to a child process
    recs = by_solver(run_tasks(tasks("reference", "fake-segfault"), tmp_path))
    crashed = recs["fake-segfault"]
    assert crashed["status"] == "crashed" and crashed["signal"] == "SIGSEGV"
    assert "SIGSEGV" in crashed["reason"] and "step 3" in crashed["reason"]
    assert crashed["n_steps"] == 3 and crashed["sim_time_s"] > 0
    assert recs["reference"]["status"] == "completed"
    assert recs["reference"]["n_steps"] == STEPS
    on_disk = by_solver(load_records(tmp_path))
    assert on_disk["fake-segfault"]["status"] == "crashed"


def test_hang_inside_a_step_is_killed_and_timed_out(
        tmp_path: Path, fakes: None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(supervise, "GRACE_MIN_S", 1.0)
    t0 = time.monotonic()
    recs = by_solver(run_tasks(tasks("fake-hang", "reference", max_wall_s=2.0, isolate=True),
                               tmp_path))
    took = time.monotonic() - t0
    hung = recs["fake-hang"]
    assert hung["status"] == "timed-out", hung["reason"]
    assert "killed" in hung["reason"] and "wall-clock limit is 2 s" in hung["reason"]
    assert hung["n_steps"] == 3 and hung["sim_time_s"] > 0
    assert recs["reference"]["status"] == "completed"
    assert took < 60


def test_pool_of_two_records_both_and_finishes(
        tmp_path: Path, fakes: None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(supervise, "GRACE_MIN_S", 1.0)
    recs = by_solver(run_tasks(tasks("fake-segfault", "fake-hang", "reference", max_wall_s=2.0),
                               tmp_path, jobs=2))
    assert {k: r["status"] for k, r in recs.items()} == {
        "fake-segfault": "crashed", "fake-hang": "timed-out", "reference": "completed"}


def test_step_limit_and_soft_wall_limit_in_process(tmp_path: Path, fakes: None) -> None:
    recs = run_tasks(tasks("reference", max_steps=5), tmp_path / "steps")
    (rec,) = recs
    assert rec["status"] == "timed-out" and "step limit of 5 steps" in rec["reason"]
    assert rec["n_steps"] == 5 and rec["sim_time_s"] > 0
    # in this process: the wall-clock limit stops the slow run between two steps
    (slow,) = run_tasks(tasks("fake-slow", max_wall_s=0.5), tmp_path / "wall")
    assert slow["status"] == "timed-out" and "wall-clock limit of 0.5 s" in slow["reason"]
    assert 1 <= slow["n_steps"] < STEPS


def test_default_limits_come_from_the_tier_and_zero_means_none() -> None:
    task = Task("diffusion", "reference", "smoke", {}, "d")
    assert task_limits(task).max_wall_s == 600.0
    assert task_limits(Task("diffusion", "reference", "quick", {}, "d", max_wall_s=0,
                            max_steps=0)) == RunLimits(None, None)
    with pytest.raises(ValueError, match="max_steps"):
        RunLimits(max_steps=0)


def test_cli_validate_records_crashed_and_timed_out(
        tmp_path: Path, fakes: None, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(supervise, "GRACE_MIN_S", 1.0)
    out = tmp_path / "out"
    code = main(["validate", "tiny-flow", "--tier", "smoke", "--solver", "fake-segfault",
                 "--solver", "fake-hang", "--solver", "reference", "--max-wall", "2",
                 "--isolate", "--out", str(out)])
    captured = capsys.readouterr()
    err = captured.err
    # the sweep finished: the reference passes, the two solvers without a completed run fail
    assert code == 1, err
    assert "PASS tiny-flow [reference]" in captured.out
    assert "FAIL tiny-flow [fake-segfault]" in captured.out
    assert "crashed" in err and "timed-out" in err
    status = {r["solver"]: r["status"] for r in load_records(out)}
    assert status == {"fake-segfault": "crashed", "fake-hang": "timed-out",
                      "reference": "completed"}
