"""Throughput of the reference backend on a WC-MPS dam-break step (pytest-benchmark).

Run with ``pytest tests/benchmarks --benchmark-only``; the default test run skips benchmarks
(``--benchmark-skip`` in pyproject's addopts).

What is measured: particle-steps per second of consecutive ``step(stable_dt())`` calls on the
Koshizuka & Oka dam break (WF2, PGM1, ``xu-jin`` Laplacian, r_e = 2.1 l0 for number density and
gradient, 3.1 l0 for the Laplacian, stabilization on), counting every particle (fluid + wall +
dummy), neighbour upkeep included.

At t = 0 the column is at rest and the skinned neighbour list would never be rebuilt, which
flatters the figure.  So the fluid starts with the shear u = sqrt(2 g H) y / H (the speed scale
of the collapse, zero on the floor): particles then move about 0.02 l0 per step and the list is
rebuilt every several steps, as in a real run (the 0.5 s run at l0 = 1 cm rebuilds once every
11 steps).  Each round is ``STEPS`` consecutive steps, so the rebuild cost is amortised.

``benchmark.extra_info`` holds ``particle_steps_per_s`` (wall clock, mean round),
``particle_steps_per_cpu_s`` (process CPU time: less sensitive to a loaded machine), the
particle counts and the neighbour builds per step.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pytest

from mpsbench.physics.particles import Kind
from mpsbench.run.specs import make_solver
from mpsbench.testing import problems

STEPS = 20  # consecutive steps per round
TARGET = 300_000  # particle-steps/s the reference backend aims for (reported, not asserted)

# l0 [m] giving about 10,000 and 40,000 particles in the 0.584 m x 0.6 m tank
SIZES = {"10k": 0.0025, "40k": 0.0011}


def _solver(l0: float) -> Any:
    problem = problems.dam_break_problem(l0=l0, stabilization=True)
    p = problem.particles
    fluid = p.kind == Kind.FLUID
    height = p.pos[fluid, 1].max() + 0.5 * l0
    p.vel[fluid, 0] = math.sqrt(2 * 9.81 * height) * p.pos[fluid, 1] / height
    solver = make_solver("reference")
    solver.setup(problem)
    for _ in range(3):  # leave the start-up step out of the measurement
        solver.step(solver.stable_dt())
    return solver


@pytest.mark.parametrize("size", sorted(SIZES))
def test_dam_break_step_throughput(benchmark: Any, size: str) -> None:
    solver = _solver(SIZES[size])
    n = solver.state().n
    cpu: list[float] = []
    builds0 = solver.counters["neighbour_builds"]

    def steps() -> None:
        c0 = time.process_time()
        with np.errstate(all="raise", under="ignore"):
            for _ in range(STEPS):
                solver.step(solver.stable_dt())
        cpu.append(time.process_time() - c0)

    benchmark.pedantic(steps, rounds=3, iterations=1, warmup_rounds=1)
    assert solver.state().n == n
    mean = benchmark.stats.stats.mean
    n_steps = STEPS * (len(cpu))
    builds = solver.counters["neighbour_builds"] - builds0
    benchmark.extra_info.update(
        n_particles=n,
        n_fluid=int((solver.state().kind == Kind.FLUID).sum()),
        steps_per_round=STEPS,
        particle_steps_per_s=n * STEPS / mean,
        particle_steps_per_cpu_s=n * STEPS * len(cpu) / sum(cpu),
        neighbour_builds_per_step=builds / n_steps,
        target_particle_steps_per_s=TARGET,
    )
