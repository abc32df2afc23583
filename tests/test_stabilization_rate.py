"""``FlowPhysics.stabilization_rate``: what the stabilization coefficient alpha_s is per.

``step`` (the paper's form) smooths the velocities by the same fraction every step, so its
added viscosity grows as 1/dt and a semi-implicit run, whose steps are 10-20 times the acoustic
one, is damped 10-20 times less than WC-MPS at the same alpha_s (docs/method.md sections 5 and
10).  ``acoustic`` makes alpha_s per acoustic step cfl l0 / c0.  The scheme applies it once for
every backend built on it; these tests hold the formula and that wiring.
"""

from __future__ import annotations

import importlib.util
import math
from typing import Any

import numpy as np
import pytest

from mpsbench.physics.config import FlowPhysics
from mpsbench.run.specs import make_solver
from mpsbench.testing import problems

BACKENDS = ["reference", pytest.param("numba", marks=pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba is not installed (extra fast)"))]


def test_step_is_alpha_s_and_acoustic_scales_with_the_step() -> None:
    step = FlowPhysics(alpha_s=0.01, c0=20.0)
    assert step.stabilization_rate == "step"
    assert step.stabilization_alpha(1e-3, 0.01, 0.2) == 0.01
    acoustic = FlowPhysics(alpha_s=0.01, c0=20.0, stabilization_rate="acoustic")
    # the acoustic step is 0.2 * 0.01 / 20 = 1e-4 s: a step of 1e-3 s is ten of them
    assert acoustic.stabilization_alpha(1e-3, 0.01, 0.2) == pytest.approx(0.1, rel=1e-12)
    assert acoustic.stabilization_alpha(1e-4, 0.01, 0.2) == pytest.approx(0.01, rel=1e-12)


def _run(backend: str, dt: float, steps: int, **physics: Any) -> np.ndarray:
    problem = problems.column_in_tank_problem(dt=dt, stabilization=True, **physics)
    s = make_solver(backend)
    s.setup(problem)
    for _ in range(steps):
        s.step(s.stable_dt())
    assert math.isfinite(s.stabilization_alpha)  # type: ignore[attr-defined]
    return s.state().vel.copy()


@pytest.mark.parametrize("backend", BACKENDS)
def test_an_acoustic_rate_is_the_step_rate_with_alpha_s_scaled(backend: str) -> None:
    """Three acoustic steps per step: alpha_s 0.01 per acoustic step is 0.03 per step."""
    probe = problems.column_in_tank_problem(stabilization=True)
    acoustic_dt = probe.time_stepping.cfl * probe.l0 / probe.physics.c0  # type: ignore[union-attr]
    dt = 3.0 * acoustic_dt
    scaled = _run(backend, dt, 30, alpha_s=0.01, stabilization_rate="acoustic")
    by_step = _run(backend, dt, 30, alpha_s=0.03)
    unscaled = _run(backend, dt, 30, alpha_s=0.01)
    scale = np.abs(by_step).max()
    assert np.abs(scaled - by_step).max() <= 1e-12 * scale
    # the stabilization matters here: ignoring the rate would be caught
    assert np.abs(unscaled - by_step).max() > 1e-6 * scale
