"""Throughput of solver backends on one WC-MPS workload, measured side by side in one process.

The workload is the benchmark dam break of ``tests/benchmarks``: the Koshizuka & Oka column
(WF2, PGM1, ``xu-jin`` Laplacian, r_e = 2.1 l0 for number density and gradient, 3.1 l0 for the
Laplacian, stabilization on) with l0 chosen to give about ``n`` particles (fluid + wall +
dummy), and the sheared start u = sqrt(2 g H) y / H so that the skinned neighbour list is
rebuilt every several steps, as in a real run (a column at rest would never rebuild it).

For each backend and size: one cold setup and first step (which pays for JIT compilation or
loading compiled code from the cache), the same again warm (the difference is ``jit_compile_s``),
a few warm-up steps, then ``steps`` consecutive ``step(stable_dt())`` calls timed as a block
(wall and process CPU time; neighbour rebuilds happen at their natural rate inside the block,
so they are included), and one neighbour rebuild timed alone.  Every figure counts all
particles.  CPU time sums all threads of the process: on a loaded machine it is the steadier
figure, and ``load_avg`` records the 1-minute load average at the start of each measurement.

A backend can offer ``rebuild_neighbours()`` (rebuild the neighbour list now); without it the
rebuild time is estimated from the steps that rebuilt against those that did not.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from mpsbench.physics.particles import Kind
from mpsbench.run.protocol import Problem, Solver
from mpsbench.run.specs import SolverSpec, make_solver, solver_spec
from mpsbench.testing.problems import dam_break_problem

G = 9.81  # m/s^2
COLUMN = (0.146, 0.292)  # m: the dam-break column (width, height)
TANK_LENGTH = 0.584  # m
WALL_LAYERS = 4  # one wall row and three dummy rows
WALL_LENGTH = TANK_LENGTH + 2 * 0.6  # m: floor and two side walls of the 0.6 m high tank
MIN_N = 500

RECORD_FIELDS = (
    "solver", "n", "n_fluid", "threads", "steps", "step_ms", "cpu_ms_per_step", "rebuild_ms",
    "rebuild_method", "rebuilds_per_step", "particle_steps_per_s", "particle_steps_per_cpu_s",
    "speedup_vs_reference", "jit_compile_s", "setup_s", "first_step_s", "load_avg", "l0",
)


@dataclass
class BenchRecord:
    """One backend at one size.  Times in ms (per step) or s; rates in particle-steps/s."""

    solver: str
    n: int
    n_fluid: int
    threads: int
    steps: int
    step_ms: float
    cpu_ms_per_step: float
    rebuild_ms: float | None
    rebuild_method: str
    rebuilds_per_step: float
    particle_steps_per_s: float
    particle_steps_per_cpu_s: float
    jit_compile_s: float
    setup_s: float
    first_step_s: float
    load_avg: float
    l0: float
    speedup_vs_reference: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        extra = d.pop("extra")
        return {**{k: d[k] for k in RECORD_FIELDS}, **extra}


def spacing_for(n: int) -> float:
    """l0 [m] that gives about ``n`` particles in the benchmark dam break."""
    if not (isinstance(n, int) and n >= MIN_N):
        raise ValueError(f"n = {n!r} is not allowed: an integer >= {MIN_N}")
    a = COLUMN[0] * COLUMN[1]
    b = WALL_LAYERS * WALL_LENGTH
    inv = (-b + math.sqrt(b * b + 4.0 * a * n)) / (2.0 * a)  # a x^2 + b x = n, x = 1 / l0
    l0 = 1.0 / inv
    got = dam_break_problem(l0=l0).particles.n
    return l0 * math.sqrt(got / n)  # one correction step: counts go as 1 / l0^2


def workload(n: int | None = None, l0: float | None = None) -> Problem:
    """The benchmark dam break at about ``n`` particles (or at spacing ``l0`` [m])."""
    if l0 is None:
        if n is None:
            raise ValueError("workload: give n or l0")
        l0 = spacing_for(n)
    problem = dam_break_problem(l0=l0, stabilization=True)
    p = problem.particles
    fluid = p.kind == Kind.FLUID
    height = float(p.pos[fluid, 1].max()) + 0.5 * l0
    p.vel[fluid, 0] = math.sqrt(2.0 * G * height) * p.pos[fluid, 1] / height
    return problem


def _threads_of(solver: Any) -> int:
    threads = getattr(solver, "threads", None)
    if isinstance(threads, int):
        return threads
    return 1


def _load() -> float:
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:  # pragma: no cover - not on every platform
        return float("nan")


def _cold_start(
    make: Callable[[], Solver], problem_fn: Callable[[], Problem]
) -> tuple[float, float, Solver]:
    """(setup s, first step s, the solver) for a fresh instance."""
    s: Solver = make()
    problem = problem_fn()
    t0 = time.perf_counter()
    s.setup(problem)
    t1 = time.perf_counter()
    s.step(s.stable_dt())
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, s


def measure(
    solver: str | type | SolverSpec,
    n: int | None = None,
    *,
    l0: float | None = None,
    steps: int = 20,
    warmup: int = 3,
) -> BenchRecord:
    """Time one backend on the benchmark workload (see the module docstring)."""
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps = {steps!r} is not allowed: an integer >= 1")
    if isinstance(solver, type):
        cls: type = solver

        def make() -> Solver:
            return make_solver(cls)

        label = str(getattr(cls, "name", cls.__name__))
    else:
        spec = solver_spec(solver)

        def make() -> Solver:
            return make_solver(spec)

        label = spec.text
    if l0 is None:
        l0 = spacing_for(n) if n is not None else None
    if l0 is None:
        raise ValueError("measure: give n or l0")
    spacing = l0

    def problem_fn() -> Problem:
        return workload(l0=spacing)

    load = _load()
    with np.errstate(all="raise", under="ignore"):
        cold_setup, cold_step, _ = _cold_start(make, problem_fn)
        warm_setup, warm_step, s = _cold_start(make, problem_fn)
        jit = max(0.0, (cold_setup + cold_step) - (warm_setup + warm_step))
        for _ in range(warmup):
            s.step(s.stable_dt())
        n_particles = s.state().n
        counters = getattr(s, "counters", {})
        builds0 = float(counters.get("neighbour_builds", 0.0))
        walls: list[float] = []
        rebuilt: list[bool] = []
        c0 = time.process_time()
        w0 = time.perf_counter()
        for _ in range(steps):
            b = float(counters.get("neighbour_builds", 0.0))
            t = time.perf_counter()
            s.step(s.stable_dt())
            walls.append(time.perf_counter() - t)
            rebuilt.append(float(counters.get("neighbour_builds", 0.0)) > b)
        wall = time.perf_counter() - w0
        cpu = time.process_time() - c0
        builds = float(counters.get("neighbour_builds", 0.0)) - builds0
        rebuild_ms, method = _rebuild_time(s, walls, rebuilt)
    fluid = int(np.count_nonzero(s.state().kind == Kind.FLUID))
    return BenchRecord(
        solver=label,
        n=n_particles,
        n_fluid=fluid,
        threads=_threads_of(s),
        steps=steps,
        step_ms=1e3 * wall / steps,
        cpu_ms_per_step=1e3 * cpu / steps,
        rebuild_ms=rebuild_ms,
        rebuild_method=method,
        rebuilds_per_step=builds / steps,
        particle_steps_per_s=n_particles * steps / wall,
        particle_steps_per_cpu_s=n_particles * steps / cpu if cpu > 0 else float("nan"),
        jit_compile_s=jit,
        setup_s=warm_setup,
        first_step_s=cold_step,
        load_avg=load,
        l0=spacing,
    )


def _rebuild_time(
    s: Any, walls: Sequence[float], rebuilt: Sequence[bool]
) -> tuple[float | None, str]:
    hook = getattr(s, "rebuild_neighbours", None)
    if callable(hook):
        best = math.inf
        for _ in range(3):
            t = time.perf_counter()
            hook()
            best = min(best, time.perf_counter() - t)
        return 1e3 * best, "direct"
    with_build = [w for w, r in zip(walls, rebuilt, strict=True) if r]
    without = [w for w, r in zip(walls, rebuilt, strict=True) if not r]
    if not with_build or not without:
        return None, "none"
    return 1e3 * max(0.0, float(np.mean(with_build) - np.median(without))), "step-difference"


def run_bench(
    solvers: Sequence[str],
    sizes: Sequence[int],
    *,
    steps: int = 20,
    reference: str = "reference",
    progress: Callable[[str], None] | None = None,
) -> list[BenchRecord]:
    """Measure every solver at every size; the reference backend is always measured too.

    ``speedup_vs_reference`` = particle-steps/s of the backend over the reference's at the same
    size in this run.
    """
    # fail early on an unknown or unavailable backend or a bad option
    names = list(dict.fromkeys(solver_spec(s).text for s in [reference, *solvers]))
    records = []
    for n in sizes:
        l0 = spacing_for(n)
        base: BenchRecord | None = None
        for name in names:
            if progress is not None:
                progress(f"{name} at n ~ {n} ...")
            rec = measure(name, l0=l0, steps=steps)
            if name == reference:
                base = rec
            records.append(rec)
        for rec in records[-len(names):]:
            if base is not None and base.particle_steps_per_s > 0:
                rec.speedup_vs_reference = rec.particle_steps_per_s / base.particle_steps_per_s
    return records


def format_table(records: Sequence[BenchRecord]) -> str:
    """A plain-text table of the records (one line per backend and size)."""
    head = (
        f"{'solver':<10} {'n':>7} {'thr':>3} {'step ms':>8} {'CPU ms':>8} {'rebuild ms':>10} "
        f"{'Mpart-steps/s':>13} {'per CPU-s':>9} {'speed-up':>8} {'JIT s':>6} {'load':>5}"
    )
    lines = [head, "-" * len(head)]
    for r in records:
        rebuild = "-" if r.rebuild_ms is None else f"{r.rebuild_ms:.1f}"
        speed = "-" if r.speedup_vs_reference is None else f"{r.speedup_vs_reference:.1f}x"
        lines.append(
            f"{r.solver:<10} {r.n:>7} {r.threads:>3} {r.step_ms:>8.2f} {r.cpu_ms_per_step:>8.2f} "
            f"{rebuild:>10} {r.particle_steps_per_s / 1e6:>13.3f} "
            f"{r.particle_steps_per_cpu_s / 1e6:>9.3f} {speed:>8} {r.jit_compile_s:>6.2f} "
            f"{r.load_avg:>5.2f}"
        )
    return "\n".join(lines)


__all__ = [
    "BenchRecord",
    "RECORD_FIELDS",
    "format_table",
    "measure",
    "run_bench",
    "spacing_for",
    "workload",
]
