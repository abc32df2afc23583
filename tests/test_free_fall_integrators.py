"""check_free_fall with an outside code's own time integrator (issue 16): a lattice that falls
as one passes whether its positions take the MPS update, the trapezoidal rule of a
predictor-corrector (PySPH's) or forward Euler; gravity applied twice, particles that do not
fall as one, a displacement beyond the MPS update, or an MPS backend that moves its particles
with the trapezoidal rule fail."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from mpsbench.physics.config import FlowPhysics
from mpsbench.run.protocol import Capabilities, Health, Problem, Status
from mpsbench.testing.physics_checks import check_free_fall

OWN = Capabilities.own_kernels(physics=frozenset({"flow"}), boundaries=frozenset({"periodic"}))


class Falling:
    """One explicit step under gravity alone: u1 = u0 + k g dt, r1 = r0 + dt (u0 + theta k g dt)
    (+ ``jitter`` of g dt^2 on the first particle).  check_free_fall calls setup, step and
    state; the rest of the Solver protocol is there for its type."""

    name = "test-falling"
    version = "1"
    capabilities = OWN
    time = 0.0
    n_steps = 0
    status = Status.READY

    def __init__(self, theta: float, k: float = 1.0, jitter: float = 0.0) -> None:
        self.theta, self.k, self.jitter = theta, k, jitter

    def setup(self, problem: Problem) -> None:
        self.p = problem.particles.copy()
        assert isinstance(problem.physics, FlowPhysics)
        self.g = np.asarray(problem.physics.gravity, dtype=float)

    def step(self, dt: float) -> None:
        u0 = self.p.vel.copy()
        self.p.vel += self.k * self.g * dt
        self.p.pos += dt * (u0 + self.theta * self.k * self.g * dt)
        self.p.pos[0, 1] += self.jitter * float(np.abs(self.g).max()) * dt * dt

    def state(self) -> Any:
        return self.p

    def stable_dt(self) -> float:
        raise NotImplementedError("check_free_fall steps with its own dt")

    def health(self, margin: float) -> Health:
        raise NotImplementedError("check_free_fall does not run the runner's health check")

    def diagnostics(self) -> dict[str, Any]:
        return {}


@pytest.mark.parametrize("theta", [1.0, 0.5, 0.0])
def test_an_own_integrator_passes_when_the_lattice_falls_as_one(theta: float) -> None:
    check_free_fall(lambda: Falling(theta), OWN)


@pytest.mark.parametrize("solver, why", [
    (Falling(0.5, k=2.0), "u differs from g dt"),
    (Falling(0.5, jitter=1e-3), "moved by different amounts"),
    (Falling(1.5), r"1.5 g dt\^2 down"),
])
def test_an_own_integrator_fails_on_wrong_physics(solver: Falling, why: str) -> None:
    with pytest.raises(AssertionError, match=why):
        check_free_fall(lambda: solver, OWN)


def test_an_mps_backend_must_take_the_mps_update() -> None:
    from mpsbench.solvers.reference import ReferenceSolver

    caps = ReferenceSolver.capabilities
    check_free_fall(lambda: Falling(1.0), caps)
    with pytest.raises(AssertionError, match=r"off by 0.5 g dt\^2"):
        check_free_fall(lambda: Falling(0.5), caps)
