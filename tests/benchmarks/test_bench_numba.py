"""Both backends on the benchmark dam break: one WC-MPS step and one neighbour rebuild (issue 8).

Run with ``pytest tests/benchmarks --benchmark-only`` (the default test run skips benchmarks);
the README gives the command that stores the results with machine and commit info.  The
workload, the sizes and the steps per round are those of ``mpsbench bench``
(:mod:`mpsbench.testing.bench`: ``workload``, ``SIZES``, ``DEFAULT_STEPS``): the dam break with l0
chosen for about 10k, 40k and 160k particles and the sheared start, so the neighbour list is
rebuilt every several steps.  A step round is ``STEPS`` consecutive ``step(stable_dt())``
calls, so the rebuilds are amortised at their natural rate; a rebuild round is one forced
rebuild of the skinned neighbour list (reference: cKDTree pair list + static-pair filter;
numba: cell-list CSR + the sub-list at r_e).  Unlike ``mpsbench bench`` the backends are not
interleaved: pytest-benchmark runs one test after the other.

``benchmark.extra_info``: ``particle_steps_per_s`` (wall, mean round), ``particle_steps_per_cpu_s``
(process CPU time, all threads: steadier on a loaded machine), ``threads``, ``n_particles``,
``neighbour_builds_per_step``, ``load_avg``.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
import pytest

from mpsbench.testing.bench import DEFAULT_STEPS, SIZES, new_solver, spacing_for, workload

STEPS = DEFAULT_STEPS
SOLVERS = ("reference", "numba")


def _solver(name: str, n: int) -> Any:
    if name == "numba":
        pytest.importorskip("numba")
    solver = new_solver(name)
    solver.setup(workload(l0=spacing_for(n)))
    for _ in range(3):  # compile / warm up; leave the start-up step out
        solver.step(solver.stable_dt())
    return solver


def _rebuild(solver: Any) -> None:
    if hasattr(solver, "rebuild_neighbours"):
        solver.rebuild_neighbours()
    else:  # the reference backend's skinned list (solvers/reference/neighbours.py)
        solver.neigh._build(solver.p, solver.weight, solver.re)


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("name", SOLVERS)
def test_step_throughput(benchmark: Any, name: str, size: str) -> None:
    solver = _solver(name, SIZES[size])
    n = solver.state().n
    cpu: list[float] = []
    builds0 = solver.counters["neighbour_builds"]

    def steps() -> None:
        c0 = time.process_time()
        with np.errstate(all="raise", under="ignore"):
            for _ in range(STEPS):
                solver.step(solver.stable_dt())
        cpu.append(time.process_time() - c0)

    rounds = 3 if name == "numba" or SIZES[size] <= 40_000 else 1
    benchmark.pedantic(steps, rounds=rounds, iterations=1, warmup_rounds=1)
    mean = benchmark.stats.stats.mean
    benchmark.extra_info.update(
        solver=name,
        n_particles=n,
        threads=getattr(solver, "threads", 1),
        steps_per_round=STEPS,
        particle_steps_per_s=n * STEPS / mean,
        particle_steps_per_cpu_s=n * STEPS * len(cpu) / sum(cpu),
        neighbour_builds_per_step=(solver.counters["neighbour_builds"] - builds0)
        / (STEPS * len(cpu)),
        load_avg=os.getloadavg()[0],
    )


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("name", SOLVERS)
def test_neighbour_rebuild(benchmark: Any, name: str, size: str) -> None:
    solver = _solver(name, SIZES[size])
    benchmark.pedantic(lambda: _rebuild(solver), rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info.update(
        solver=name,
        n_particles=solver.state().n,
        threads=getattr(solver, "threads", 1),
        load_avg=os.getloadavg()[0],
    )
