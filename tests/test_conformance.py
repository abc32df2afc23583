"""The conformance kit (mpsbench.testing) on the reference backend, and on broken backends
that each check must catch."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mpsbench.solvers.reference import ReferenceSolver
from numpy.typing import NDArray

from mpsbench.cli import main
from mpsbench.physics.config import DiffusionPhysics
from mpsbench.physics.particles import Particles
from mpsbench.run.protocol import SOLVERS, Capabilities, Problem, Status
from mpsbench.testing import (
    ConformanceResult,
    SolverCheckError,
    all_checks,
    check_solver,
    parametrize_solver_checks,
    select_checks,
)

# --------------------------------------------------------------------------- the reference


@parametrize_solver_checks("reference")
def test_reference_conforms(solver: Any, check: Any) -> None:
    check(solver)


def test_reference_passes_every_check_quickly() -> None:
    results = check_solver("reference")
    assert {r.check for r in results} == {c.name for c in all_checks()}
    assert all(r.outcome == "pass" for r in results), results
    assert sum(r.seconds for r in results) < 20.0  # "the whole kit runs in seconds"


def test_the_kit_accepts_a_class_and_a_configured_instance() -> None:
    assert not any(r.failed for r in check_solver(ReferenceSolver, checks="momentum"))
    instance = ReferenceSolver()
    instance.skin_ratio = 0.5  # a configured instance is deep-copied for every run
    results = check_solver(instance, checks=["determinism", "rest"])
    assert [r.outcome for r in results] == ["pass", "pass"]
    assert instance.problem is None  # the instance itself was never set up


def test_parametrize_ids_and_marks() -> None:
    class Partial(ReferenceSolver):
        name = "partial"
        capabilities = Capabilities(gradients=frozenset({"pgm1", "pgm2"}))
        expected_failures = {"check_rest_periodic": "known drift"}

    mark = parametrize_solver_checks("reference", Partial).mark
    assert mark.args[0] == "solver, check"
    params = {p.id: p for p in mark.args[1]}
    assert "reference-check_momentum_pgm2" in params
    assert "partial-check_momentum_pgm3" in params
    skip = params["partial-check_momentum_pgm3"].marks[0]
    assert skip.name == "skip" and "gradient 'pgm3'" in skip.kwargs["reason"]
    xfail = params["partial-check_rest_periodic"].marks[0]
    assert xfail.name == "xfail" and xfail.kwargs["reason"] == "known drift"
    assert not params["reference-check_api_shape"].marks
    assert len(mark.args[1]) == 2 * len(all_checks())


def test_parametrize_an_unavailable_solver_gives_one_skip() -> None:
    SOLVERS.register("broken-import", "no_such_module_xyz:Solver", origin="user")
    try:
        (param,) = parametrize_solver_checks("broken-import").mark.args[1]
        assert param.id == "broken-import-unavailable" and param.marks[0].name == "skip"
    finally:
        SOLVERS.unregister("broken-import")


# --------------------------------------------------------------------------- broken backends


def _is_flow(solver: ReferenceSolver) -> bool:
    assert solver.problem is not None
    return not isinstance(solver.problem.physics, DiffusionPhysics)


class NoisySolver(ReferenceSolver):
    """Adds unseeded noise: not deterministic."""

    name = "noisy"

    def _advance(self, dt: float) -> None:
        super()._advance(dt)
        self.p.vel[self.p.kind == 0] += np.random.default_rng().normal(0.0, 1e-9, 2)


class LeakySolver(ReferenceSolver):
    """Drops the last particle after the first step of a flow."""

    name = "leaky"
    # the base's attributes, which this class reassigns
    p: Particles
    number_density: NDArray[np.float64]
    free_surface: NDArray[np.bool_]

    def _advance(self, dt: float) -> None:
        super()._advance(dt)
        if self.n_steps == 0 and _is_flow(self):
            self.p = self.p.subset(np.arange(self.p.n - 1))
            self.neigh.invalidate()
            self.number_density = self.number_density[:-1]
            self.free_surface = self.free_surface[:-1]


class PushySolver(ReferenceSolver):
    """A momentum source: every fluid particle is pushed by the same tiny amount."""

    name = "pushy"

    def _advance(self, dt: float) -> None:
        super()._advance(dt)
        if _is_flow(self):
            self.p.vel[self.p.kind == 0, 0] += 1e-6


class BiasedDiffusion(ReferenceSolver):
    """A Laplacian with a source term: a uniform field does not stay uniform."""

    name = "biased"

    def _advance(self, dt: float) -> None:
        super()._advance(dt)
        for ph_field in self.p.fields.values():
            ph_field += 1e-9


class StuckClock(ReferenceSolver):
    """Forgets to advance time."""

    name = "stuck"

    def step(self, dt: float) -> None:
        super().step(dt)
        self.time -= dt


class Mutator(ReferenceSolver):
    """Works on the problem's particles instead of a copy."""

    name = "mutator"

    def _setup(self, problem: Problem) -> None:
        super()._setup(problem)
        self.p = problem.particles


class Overclaimer(ReferenceSolver):
    """Declares no inflow but never checks: setup() accepts what it should reject."""

    name = "overclaimer"
    capabilities = Capabilities(
        boundaries=frozenset(
            {"periodic", "periodic-x", "periodic-y", "walls", "moving-walls", "outflow"}
        )
    )

    def setup(self, problem: Problem) -> None:
        self.problem = problem
        self.time, self.n_steps = 0.0, 0
        self._setup(problem)
        self.status = Status.RUNNING


class Crasher(ReferenceSolver):
    """Raises a plain exception when things go wrong instead of producing inf/NaN."""

    name = "crasher"

    def _advance(self, dt: float) -> None:
        super()._advance(dt)
        if np.abs(self.p.vel).max() > 2.0:
            raise RuntimeError("velocity too large, giving up")


class WrongTypes(ReferenceSolver):
    name = ""
    version: Any = 1  # deliberately not a str: the kit must reject it


@pytest.mark.parametrize(
    "solver, failing",
    [
        (NoisySolver, "check_determinism"),
        (LeakySolver, "check_particle_count"),
        (PushySolver, "check_momentum_pgm2"),
        (PushySolver, "check_momentum_pgm3"),
        (BiasedDiffusion, "check_uniform_diffusion_xu-jin"),
        (StuckClock, "check_lifecycle"),
        (Mutator, "check_lifecycle"),
        (Overclaimer, "check_capabilities_honoured"),
        (Crasher, "check_divergence_reported"),
        (WrongTypes, "check_api_shape"),
    ],
)
def test_each_check_catches_its_fault(solver: type, failing: str) -> None:
    (result,) = check_solver(solver, checks=[failing], on_fail="return")
    assert result.check == failing
    assert result.outcome == "fail", result
    assert result.reason


def test_failure_messages_say_what_went_wrong() -> None:
    (r,) = check_solver(Crasher, checks="divergence", on_fail="return")
    assert "'failed'" in r.reason and "giving up" in r.reason
    (r,) = check_solver(Overclaimer, checks="capabilities", on_fail="return")
    assert "inflow" in r.reason and "UnsupportedProblem" in r.reason
    (r,) = check_solver(Mutator, checks="lifecycle", on_fail="return")
    assert "must copy" in r.reason


def test_check_solver_raises_with_every_failure_listed() -> None:
    with pytest.raises(SolverCheckError) as info:
        check_solver(PushySolver, checks=["momentum", "api"])
    err = info.value
    assert "check_momentum_pgm2" in str(err) and "check_momentum_pgm3" in str(err)
    assert [r.outcome for r in err.results] == ["pass", "fail", "fail"]
    with pytest.raises(ValueError, match="on_fail"):
        check_solver("reference", on_fail="warn")  # type: ignore[arg-type]


def test_expected_failures_are_xfail_and_unexpected_passes_xpass() -> None:
    class Declared(PushySolver):
        expected_failures = {
            "check_momentum_pgm2": "pushes on purpose",
            "check_api_shape": "claimed but not true",
        }

    results = {r.check: r for r in check_solver(Declared, checks=["momentum_pgm2", "api"])}
    assert results["check_momentum_pgm2"].outcome == "xfail"
    assert "pushes on purpose" in results["check_momentum_pgm2"].reason
    assert "sum of velocities" in results["check_momentum_pgm2"].reason  # the real message too
    assert results["check_api_shape"].outcome == "xpass"
    assert "claimed but not true" in results["check_api_shape"].reason


def test_checks_a_solver_cannot_run_are_skipped_with_the_reason() -> None:
    class DiffusionOnly(ReferenceSolver):
        name = "diffusion-only"
        capabilities = Capabilities(
            physics=frozenset({"diffusion"}),
            boundaries=frozenset({"periodic"}),
            features=frozenset(),
            laplacians=frozenset({"xu-jin"}),
            weights=frozenset({"wf2"}),
            gradients=frozenset(),
        )

    results = {r.check: r for r in check_solver(DiffusionOnly)}
    assert results["check_momentum_pgm2"].outcome == "skip"
    assert "physics 'flow'" in results["check_momentum_pgm2"].reason
    assert results["check_uniform_diffusion_khayyer-gotoh"].outcome == "skip"
    assert "laplacian 'khayyer-gotoh'" in results["check_uniform_diffusion_khayyer-gotoh"].reason
    assert results["check_uniform_diffusion_xu-jin"].outcome == "pass"
    # it rejects the flow, wall, model... problems it does not declare
    assert results["check_capabilities_honoured"].outcome == "pass"
    assert results["check_lifecycle"].outcome == "pass"
    assert results["check_determinism"].outcome == "pass"


def test_select_checks_by_substring() -> None:
    names = [c.name for c in select_checks("uniform")]
    assert "check_uniform_diffusion_xu-jin" in names and "check_api_shape" not in names
    assert select_checks(["nothing-like-this"]) == []
    exact = select_checks("check_uniform_diffusion_xu-jin")  # not -analytic, not -corrected
    assert [c.name for c in exact] == ["check_uniform_diffusion_xu-jin"]


def test_check_result_as_dict() -> None:
    r = ConformanceResult("check_x", "fail", "why", 0.123456)
    assert r.failed and r.as_dict() == {
        "check": "check_x",
        "outcome": "fail",
        "reason": "why",
        "seconds": 0.1235,
    }


def test_the_kit_does_not_leak_numpy_error_settings() -> None:
    before = np.geterr()
    check_solver("reference", checks="api")
    assert np.geterr() == before


# --------------------------------------------------------------------------- mpsbench check


def test_cli_check_reference_exits_0() -> None:
    script = Path(sys.executable).with_name("mpsbench")  # the installed console script
    command = [str(script)] if script.exists() else [sys.executable, "-m", "mpsbench.cli"]
    out = subprocess.run(
        [*command, "check", "reference"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    lines = out.stdout.strip().splitlines()
    assert len(lines) == len(all_checks()) + 1
    assert all(line.startswith("PASS ") for line in lines[:-1])
    assert lines[-1].startswith("reference: ")


def test_cli_unknown_solver_exits_2_with_known_names(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "no-such-solver"]) == 2
    err = capsys.readouterr().err
    assert "no-such-solver" in err and "reference" in err


@pytest.fixture
def registered(request: pytest.FixtureRequest) -> Iterator[str]:
    cls = request.param
    SOLVERS.register(cls.name, cls, origin="user")
    try:
        yield cls.name
    finally:
        SOLVERS.unregister(cls.name)


@pytest.mark.parametrize("registered", [PushySolver], indirect=True)
def test_cli_failing_check_exits_1(registered: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", registered, "-k", "momentum", "-k", "api"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "PASS  check_api_shape"
    assert out[1].startswith("FAIL  check_momentum_pgm2: sum of velocities changed")
    assert "1 pass, 2 fail" in out[-1]


@pytest.mark.parametrize("registered", [PushySolver], indirect=True)
def test_cli_json(registered: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", registered, "--json", "-k", "momentum_pgm3"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["solver"] == "pushy" and doc["ok"] is False
    assert doc["counts"]["fail"] == 1
    assert doc["results"][0]["check"] == "check_momentum_pgm3"


def test_cli_skip_and_xfail_lines(capsys: pytest.CaptureFixture[str]) -> None:
    class Flagged(ReferenceSolver):
        name = "flagged"
        capabilities = Capabilities(gradients=frozenset({"pgm1", "pgm2"}))
        expected_failures = {"check_momentum_pgm2": "under investigation"}

    SOLVERS.register("flagged", Flagged, origin="user")
    try:
        assert main(["check", "flagged", "-k", "momentum"]) == 0
    finally:
        SOLVERS.unregister("flagged")
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "XPASS check_momentum_pgm2: expected to fail: under investigation"
    assert out[1].startswith("SKIP  check_momentum_pgm3: solver does not declare gradient")


def test_cli_no_matching_check_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "reference", "-k", "zzz"]) == 2
    assert "zzz" in capsys.readouterr().err


def test_particles_helper_is_importable() -> None:
    # the kit builds its problems from the public particle builders only
    from mpsbench.testing import problems

    p = problems.column_in_tank_problem()
    assert isinstance(p.particles, Particles) and p.requirements()["boundaries"] == {"walls"}
