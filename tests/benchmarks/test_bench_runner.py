"""Per-step cost of the runner around a solver (pytest-benchmark).

Run with ``pytest tests/benchmarks --benchmark-only -k runner``.  The runner checks every step
for divergence (finite state, fluid speed, particles leaving the box) and serves the probes;
on a fast backend and a small problem that bookkeeping can cost as much as the step.  Two
benchmarks on the same numba diffusion problem (6,400 particles, periodic unit square,
l0 = 1/80): ``bare`` calls ``step(dt)`` in a loop, ``runner`` lets :func:`mpsbench.run.runner.run`
drive the same number of steps (its set-up included, about 10 ms).  Their ratio is the
runner's overhead; ``extra_info`` holds the microseconds per step of each.
"""

from __future__ import annotations

from typing import Any

import pytest

from mpsbench.run.runner import run
from mpsbench.run.specs import make_solver

pytest.importorskip("numba")

STEPS = 2000


def _problem() -> Any:
    from mpsbench.validations.diffusion import CASE

    params = CASE.defaults()
    params["l0"] = 1 / 80
    return CASE.build(params)


def test_runner_bare_steps(benchmark: Any) -> None:
    problem = _problem()
    solver = make_solver("numba")
    solver.setup(problem)
    dt = solver.stable_dt()
    solver.step(dt)  # compile / load the kernels outside the measurement

    def steps() -> None:
        for _ in range(STEPS):
            solver.step(dt)

    benchmark.pedantic(steps, rounds=5, iterations=1)
    benchmark.extra_info["us_per_step"] = 1e6 * benchmark.stats.stats.mean / STEPS


def test_runner_driven_steps(benchmark: Any) -> None:
    problem = _problem()
    run("numba", problem, max_steps=2)  # compile / load the kernels outside the measurement

    def driven() -> None:
        result = run("numba", problem, max_steps=STEPS)
        assert result.ok and result.n_steps == STEPS

    benchmark.pedantic(driven, rounds=5, iterations=1)
    benchmark.extra_info["us_per_step"] = 1e6 * benchmark.stats.stats.mean / STEPS
