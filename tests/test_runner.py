"""The runner: stopping rules, probe scheduling, failure and divergence reporting, counters."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from mpsbench.physics.config import FlowPhysics, Models, TimeStepping
from mpsbench.physics.particles import Box, Kind, Particles
from mpsbench.run.probes import Callback, Probe
from mpsbench.run.protocol import Capabilities, Problem, SolverBase, Status
from mpsbench.run.runner import DivergenceLimits, RunResult, run
from mpsbench.testing import problems


class ToySolver(SolverBase):
    """Particles drift at their velocity; faults can be injected at a given step."""

    name = "toy"
    version = "0.1"

    def __init__(self, fault: str | None = None, at_step: int = 3, dt: float = 0.1) -> None:
        super().__init__()
        self.fault = fault
        self.at_step = at_step
        self.dt = dt
        self.steps_taken: list[float] = []

    def _setup(self, problem: Problem) -> None:
        if self.fault == "setup":
            raise RuntimeError("cannot set up the toy")
        self.p = problem.particles.copy()

    def _advance(self, dt: float) -> None:
        self.steps_taken.append(dt)
        k = self.n_steps + 1
        if k == self.at_step:
            if self.fault == "raise":
                raise KeyError("boom")
            if self.fault == "nan":
                self.p.vel[0, 0] = np.nan
            if self.fault == "fpe":
                np.ones(1) / np.zeros(1)  # the runner raises on divide-by-zero
            if self.fault == "fast":
                self.p.vel[1] = (1e3, 0.0)
            if self.fault == "escape":
                self.p.pos[2] = (50.0, 0.5)
        self.p.pos += dt * self.p.vel

    def stable_dt(self) -> float:
        assert self.problem is not None
        return self.problem.time_stepping.dt or self.dt

    def state(self) -> Particles:
        return self.p


def toy_problem(n: int = 4, dt: float | None = None) -> Problem:
    p = Particles.from_positions(np.column_stack([np.linspace(0.1, 0.9, n), np.full(n, 0.5)]))
    p.vel[:, 0] = 0.01
    box = Box((0.0, 0.0), (1.0, 1.0))
    return Problem(
        p, box, 0.1, FlowPhysics(gravity=(0.0, 0.0), c0=10.0), Models(), TimeStepping(dt=dt)
    )


# --------------------------------------------------------------------------- stopping rules


def test_end_time_is_reached_exactly() -> None:
    result = run(ToySolver(dt=0.3), toy_problem(), end_time=1.0)
    assert result.status == Status.COMPLETED and result.ok and result.reason == ""
    assert result.time == 1.0
    # 0.3, 0.6, then 1.5 steps would overshoot: two halves of the rest instead of a sliver
    assert result.n_steps == 4


def test_max_steps_stops_after_that_many_steps_and_time_stays_finite() -> None:
    solver = ToySolver(dt=0.01)
    result = run(solver, toy_problem(), max_steps=7)
    assert result.status == Status.COMPLETED
    assert result.n_steps == 7
    assert math.isfinite(result.time)  # regression: time became inf without an end_time
    assert result.time == pytest.approx(0.07, rel=1e-12)
    assert solver.steps_taken == [0.01] * 7


def test_whichever_limit_comes_first_stops_the_run() -> None:
    assert run(ToySolver(dt=0.1), toy_problem(), end_time=1.0, max_steps=3).n_steps == 3
    result = run(ToySolver(dt=0.1), toy_problem(), end_time=0.25, max_steps=100)
    assert result.time == 0.25 and result.n_steps < 100


def test_fixed_dt_argument_overrides_the_solver() -> None:
    solver = ToySolver(dt=0.1)
    run(solver, toy_problem(), max_steps=3, dt=0.02)
    assert solver.steps_taken == [0.02] * 3


@pytest.mark.parametrize(
    "kwargs",
    [{}, {"end_time": 0.0}, {"end_time": -1.0}, {"end_time": math.inf}, {"end_time": math.nan}],
)
def test_bad_stopping_rules_raise(kwargs: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match="end_time"):
        run(ToySolver(), toy_problem(), **kwargs)


def test_a_problem_that_is_not_a_problem_is_named() -> None:
    """A case's build() returning (problem, extra) handed to run() as it is: a TypeError that
    says what was given, not an AttributeError from deep inside the runner."""
    with pytest.raises(TypeError, match="not tuple"):
        run(ToySolver(), (toy_problem(), None), max_steps=1)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- probes


def test_probes_land_exactly_on_requested_times() -> None:
    at = [0.0, 0.013, 0.05, 0.0711, 0.2]
    probe = Callback("t", lambda s: s.time, at=at)
    every = Callback("every", lambda s: s.n_steps, every=0.02)
    result = run(ToySolver(dt=0.01), toy_problem(), end_time=0.1, probes=[probe, every])
    assert result.ok
    assert probe.t == [0.0, 0.013, 0.05, 0.0711]  # exactly; 0.2 is past the end
    assert probe.values == probe.t
    assert every.t == [k * 0.02 for k in range(6)]
    assert result.probes == {"t": probe, "every": every}


def test_every_probe_on_a_step_count_run_records_each_step() -> None:
    probe = Callback("n", lambda s: s.n_steps, every=1.0)
    run(ToySolver(dt=0.01), toy_problem(), max_steps=4, probes=[probe])
    assert probe.values == [0, 1, 2, 3, 4]


def test_a_probe_reused_in_a_second_run_starts_afresh() -> None:
    probe = Callback("t", lambda s: s.time, every=0.05)
    run(ToySolver(dt=0.01), toy_problem(), end_time=0.1, probes=[probe])
    run(ToySolver(dt=0.01), toy_problem(), end_time=0.05, probes=[probe])
    assert probe.t == [0.0, 0.05]


def test_probe_needs_a_schedule() -> None:
    with pytest.raises(ValueError, match="every"):
        Probe("p")
    with pytest.raises(ValueError, match="> 0"):
        Probe("p", every=0.0)


# --------------------------------------------------------------------------- failures


def test_failed_setup_is_a_failed_run_with_the_reason() -> None:
    result = run(ToySolver(fault="setup"), toy_problem(), end_time=1.0)
    assert result.status == Status.FAILED
    assert "setup failed" in result.reason and "cannot set up the toy" in result.reason
    assert result.n_steps == 0 and result.solver_name == "toy"


def test_unsupported_problem_is_an_unsupported_run_with_the_reasons() -> None:
    class DiffusionOnly(ToySolver):
        capabilities = Capabilities(physics=frozenset({"diffusion"}))

    result = run(DiffusionOnly(), toy_problem(), end_time=1.0)
    assert result.status == Status.UNSUPPORTED and result.n_steps == 0
    assert "cannot run this problem" in result.reason and "'flow'" in result.reason


def test_missing_diffusion_field_is_a_failed_setup_of_the_reference() -> None:
    problem = problems.diffusion_problem()
    del problem.particles.fields["phi"]
    result = run("reference", problem, max_steps=1)
    assert result.status == Status.FAILED and "phi" in result.reason


def test_unknown_solver_name_is_a_failed_run() -> None:
    result = run("no-such-solver", toy_problem(), max_steps=1)
    assert result.status == Status.FAILED
    assert "no-such-solver" in result.reason and "reference" in result.reason


def test_exception_inside_a_step_is_a_failed_run_with_where_it_happened() -> None:
    solver = ToySolver(fault="raise", at_step=3)
    result = run(solver, toy_problem(), end_time=10.0)
    assert result.status == Status.FAILED
    assert "KeyError" in result.reason and "boom" in result.reason
    assert "test_runner.py" in result.reason and "step 2" in result.reason
    assert solver.status == Status.FAILED


@pytest.mark.parametrize(
    "fault, words",
    [
        ("nan", "non-finite"),
        ("fpe", "FloatingPointError"),
        ("fast", "exceeds the bound"),
        ("escape", "left the domain"),
    ],
)
def test_breakdowns_are_diverged_runs(fault: str, words: str) -> None:
    solver = ToySolver(fault=fault, at_step=3)
    result = run(solver, toy_problem(), end_time=10.0)
    assert result.status == Status.DIVERGED
    assert words in result.reason
    assert result.n_steps == (2 if fault == "fpe" else 3)
    assert solver.status == Status.DIVERGED
    assert result.final is not None


@pytest.mark.parametrize("fault", ["fast", "escape"])
def test_only_fluid_particles_count_for_speed_and_escape(fault: str) -> None:
    """A wall particle moving fast or sitting outside the box is the solver's business."""
    problem = toy_problem()
    problem.particles.kind[1:3] = Kind.WALL  # the particles the faults touch
    assert run(ToySolver(fault=fault, at_step=3), problem, end_time=1.0).ok
    assert not run(ToySolver(fault=fault, at_step=3), toy_problem(), end_time=1.0).ok


def test_divergence_limits_can_be_tightened() -> None:
    limits = DivergenceLimits(max_speed=0.001)
    result = run(ToySolver(), toy_problem(), end_time=1.0, limits=limits)
    assert result.status == Status.DIVERGED and "0.001" in result.reason
    loose = DivergenceLimits(leave_margin=100.0)
    assert run(ToySolver(fault="escape"), toy_problem(), end_time=1.0, limits=loose).ok


def test_diffusion_blowing_up_is_diverged() -> None:
    problem = problems.diffusion_problem(value=None, dt=1.0)  # far above the stability limit
    result = run("reference", problem, max_steps=50)
    assert result.status == Status.DIVERGED
    assert "grew beyond" in result.reason or "FloatingPointError" in result.reason


def test_run_restores_the_floating_point_error_state() -> None:
    before = np.geterr()
    run(ToySolver(fault="fpe"), toy_problem(), end_time=1.0)
    assert np.geterr() == before


# --------------------------------------------------------------------------- result


def test_result_counters_and_metadata() -> None:
    seen: list[tuple[float, int]] = []
    problem = problems.periodic_flow_problem(amplitude=0.05, models=Models(n0_from="lattice"))
    result = run("reference", problem, max_steps=5, progress=lambda t, n: seen.append((t, n)))
    assert isinstance(result, RunResult) and result.ok
    n = problem.particles.n
    assert result.particle_steps == 5 * n and result.n_particles == n
    assert result.particle_steps_per_s > 0 and result.wall_time_s > 0
    assert result.solver_name == "reference" and result.solver_version
    assert result.counters["neighbour_builds"] >= 1
    assert [k for _, k in seen] == [1, 2, 3, 4, 5]
    assert seen[-1][0] == result.time
    assert result.final is not None and result.final.n == n


def test_final_state_is_a_copy_or_absent() -> None:
    solver = ToySolver()
    result = run(solver, toy_problem(), max_steps=2)
    assert result.final is not None and result.final.pos is not solver.state().pos
    assert run(ToySolver(), toy_problem(), max_steps=2, keep_final=False).final is None
