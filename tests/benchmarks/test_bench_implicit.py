"""The semi-implicit backend on the benchmark dam break: one step, split into its parts (issue 15).

Run with ``pytest tests/benchmarks --benchmark-only -k implicit``.  The workload is that of
``mpsbench bench`` (:func:`mpsbench.testing.bench.workload`: the dam break with l0 chosen for
about 10k and 40k particles, the sheared start); the solver steps at its own ``stable_dt()``
(the flow / gravity-wave / pressure limits, no sound speed), after warm-up steps past its
start-up (the first steps double from the acoustic one).  A round is one step.  Each linear
solver (``cg`` with Jacobi, and ``pyamg`` when installed) is its own benchmark.

``benchmark.extra_info`` splits the mean step: ``assembly_s`` (number density, free surface,
the PPE matrix and right-hand side), ``setup_s`` (preconditioner or multigrid hierarchy),
``solve_s`` (the Krylov iterations) and ``rest_s`` (predictor, corrector, neighbour list, ...:
the step minus those three), with ``iterations`` per solve, ``unknowns``, ``dt`` and
``load_avg``.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
import pytest

from mpsbench.run.linsolve import pyamg_available
from mpsbench.testing.bench import SIZES, new_solver, spacing_for, workload

IMPLICIT_SIZES = ("10k", "40k")
ROUNDS = 3
MAX_WARMUP_STEPS = 12


@pytest.mark.parametrize("size", IMPLICIT_SIZES)
@pytest.mark.parametrize("linear_solver", ["cg", "pyamg"])
def test_implicit_step(benchmark: Any, linear_solver: str, size: str) -> None:
    if linear_solver == "pyamg" and not pyamg_available():
        pytest.skip("pyamg is not installed (pip install 'mpsbench[pyamg]')")
    solver = new_solver(f"implicit:linear_solver={linear_solver}")
    solver.setup(workload(l0=spacing_for(SIZES[size])))
    # warm up past the start-up steps (dt doubling from the acoustic step), so the rounds time
    # steps at the backend's own limit
    for _ in range(MAX_WARMUP_STEPS):
        solver.step(solver.stable_dt())
        if solver.diagnostics()["dt_limit"] != "start-up":
            break
    parts: list[dict[str, float]] = []

    def step() -> None:
        dt = solver.stable_dt()
        t0 = time.perf_counter()
        with np.errstate(all="raise", under="ignore"):
            solver.step(dt)
        wall = time.perf_counter() - t0
        last = solver.diagnostics()["linear_solve"]
        parts.append({"wall": wall, "dt": dt, "assembly_s": last["assembly_s"],
                      "setup_s": last["setup_s"], "solve_s": last["solve_s"],
                      "iterations": last["iterations"], "unknowns": last["unknowns"]})

    benchmark.pedantic(step, rounds=ROUNDS, iterations=1, warmup_rounds=0)
    mean = {k: float(np.mean([p[k] for p in parts])) for k in parts[0]}
    benchmark.extra_info.update(
        solver=f"implicit:linear_solver={linear_solver}",
        method=solver.diagnostics()["linear_solve"]["method"],
        n_particles=solver.state().n,
        dt=mean["dt"],
        dt_limit=solver.diagnostics()["dt_limit"],
        assembly_s=mean["assembly_s"],
        setup_s=mean["setup_s"],
        solve_s=mean["solve_s"],
        rest_s=mean["wall"] - mean["assembly_s"] - mean["setup_s"] - mean["solve_s"],
        iterations=mean["iterations"],
        unknowns=mean["unknowns"],
        load_avg=os.getloadavg()[0],
    )
