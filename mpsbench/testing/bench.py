"""Throughput of solver backends on one WC-MPS workload, measured side by side in one process.

The workload is the benchmark dam break of ``tests/benchmarks``: the Koshizuka & Oka column
(WF2, PGM1, ``xu-jin`` Laplacian, r_e = 2.1 l0 for number density and gradient, 3.1 l0 for the
Laplacian, stabilization on) with l0 chosen to give about ``n`` particles (fluid + wall +
dummy), and the sheared start u = sqrt(2 g H) y / H so that the skinned neighbour list is
rebuilt every several steps, as in a real run (a column at rest would never rebuild it).

How one size is timed (:func:`run_bench`), for the contenders ``A, B, ...`` in order:

1. *Cold start*, each contender in turn: a fresh instance, ``setup`` and a first step (this pays
   for JIT compilation or for loading compiled code from the cache).  The instance is then
   freed before anything is timed, so its memory does not weigh on the others.
2. *Warm start*: a second fresh instance, ``setup`` and a first step (cold minus warm is
   ``jit_compile_s``), then ``warmup`` steps.  The warm instances of all contenders stay alive.
3. *Rounds*: ``A B A B ...``: in each round every contender advances one block of ``steps``
   consecutive ``step(stable_dt())`` calls (neighbour rebuilds happen inside at their natural
   rate), timed in wall and process CPU time.  Without ``steps`` a block is as many steps as
   make the fastest contender's block last :data:`BLOCK_S` by its warm-up steps (at least
   :data:`DEFAULT_STEPS`): a block of 20 steps lasts 50 ms for the numba backend at 10k
   particles, and blocks that short scatter by 10-20 % even on a quiet 2-core machine, and so
   did the per-round ratios (docs/performance.md).  Rounds repeat until ``repeat`` of them,
   or until the blocks have taken ``budget`` seconds in all (and at least :data:`MIN_ROUNDS`).
   All contenders advance by the same number of steps, so they stay at the same stage of
   the same run.
4. One neighbour rebuild timed alone per contender (best of 3).

Figures per contender are the median over its blocks, with quartiles and min/max, so one
block slowed by another process does not move them.  ``speedup_vs_first`` is the median over
rounds of (particle-steps/s / the first contender's in the same round): both blocks of a round
ran within a fraction of a second of each other under the same load, which is what makes the
ratio steadier than either absolute figure.  ``time_to_solution_speedup`` is the same for the
wall time per simulated second: how much sooner the same physical time is reached (it differs
from the speed-up when the contenders' time steps differ, as PySPH's do).  Every figure counts
all particles.  CPU time sums all threads of the process; ``load_avg`` and ``load_avg_end``
are the 1-minute load averages at the start and end of a size.

A contender is anything with ``setup(problem)``, ``stable_dt()`` and ``step(dt)``: a solver
backend (:func:`new_solver`) or an outside code on the same particles (:mod:`.bench_pysph`).
One that offers ``rebuild_neighbours()`` has its rebuild timed directly; without it the rebuild
time is estimated from the steps that rebuilt against those that did not (``counters``).
"""

from __future__ import annotations

import gc
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from mpsbench.physics.particles import Kind
from mpsbench.run.protocol import Problem, Solver
from mpsbench.run.specs import SolverSpec, get_solver_class, make_solver, solver_spec
from mpsbench.testing.problems import dam_break_problem

G = 9.81  # m/s^2
COLUMN = (0.146, 0.292)  # m: the dam-break column (width, height)
TANK_LENGTH = 0.584  # m
WALL_LAYERS = 4  # one wall row and three dummy rows
WALL_LENGTH = TANK_LENGTH + 2 * 0.6  # m: floor and two side walls of the 0.6 m high tank
MIN_N = 500

SIZES = {"10k": 10_000, "40k": 40_000, "160k": 160_000}
"""The sizes of the pytest-benchmark suite (tests/benchmarks); ``mpsbench bench`` runs the
first two by default (DEFAULT_SIZES)."""
DEFAULT_SIZES = (SIZES["10k"], SIZES["40k"])
DEFAULT_STEPS = 20  # steps per block: the least of a sized block, the pytest suite's block
BLOCK_S = 0.25  # s: the least wall time of the fastest contender's block (steps not given)
MAX_BLOCK_STEPS = 2000  # a contender faster than 0.125 ms per step gets no longer block
DEFAULT_BUDGET_S = 20.0  # timed seconds per size, all contenders together
WARMUP_STEPS = 3
MIN_ROUNDS = 5  # below this a median and quartiles say little

RECORD_FIELDS = (
    "solver", "n", "n_fluid", "threads", "steps", "rounds", "particle_steps_per_s",
    "particle_steps_per_s_q1", "particle_steps_per_s_q3", "particle_steps_per_s_min",
    "particle_steps_per_s_max", "speedup_vs_first", "speedup_q1", "speedup_q3",
    "speedup_min", "speedup_max", "first_solver", "time_to_solution_speedup", "dt_mean",
    "wall_s_per_sim_s", "step_ms", "cpu_ms_per_step", "particle_steps_per_cpu_s", "rebuild_ms",
    "rebuild_method", "rebuilds_per_step", "jit_compile_s", "setup_s", "first_step_s",
    "load_avg", "load_avg_end", "l0", "solver_version", "solver_commit", "block_wall_s",
)


@dataclass
class BenchRecord:
    """One contender at one size.  Times in ms (per step) or s; rates in particle-steps/s;
    ``_q1`` / ``_q3`` / ``_min`` / ``_max``: quartiles and extremes over the blocks (rates)
    or the rounds (ratios)."""

    solver: str
    n: int
    n_fluid: int
    threads: int
    steps: int
    rounds: int
    particle_steps_per_s: float
    particle_steps_per_s_q1: float
    particle_steps_per_s_q3: float
    particle_steps_per_s_min: float
    particle_steps_per_s_max: float
    dt_mean: float
    wall_s_per_sim_s: float
    step_ms: float
    cpu_ms_per_step: float
    particle_steps_per_cpu_s: float
    rebuild_ms: float | None
    rebuild_method: str
    rebuilds_per_step: float | None
    jit_compile_s: float
    setup_s: float
    first_step_s: float
    load_avg: float
    load_avg_end: float
    l0: float
    block_wall_s: list[float]
    speedup_vs_first: float = 1.0
    speedup_q1: float = 1.0
    speedup_q3: float = 1.0
    speedup_min: float = 1.0
    speedup_max: float = 1.0
    first_solver: str = ""
    time_to_solution_speedup: float = 1.0
    solver_version: str | None = None
    solver_commit: str | None = None
    code_module: str = ""  # the module whose code ran (its commit is looked up by the caller)
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        extra = d.pop("extra")
        return {**{k: d[k] for k in RECORD_FIELDS}, **extra}


@dataclass
class Contender:
    """Something the bench times: ``make()`` returns a fresh, not yet set up, stepper."""

    label: str
    make: Callable[[], Any]
    code_module: str = ""


def new_solver(spec: str | type | SolverSpec) -> Solver:
    """A fresh solver from a spec (``numba``, ``numba:threads=1``) or a class: the one place the
    bench makes one."""
    return make_solver(spec)


def solver_contender(spec: str | type) -> Contender:
    """A registered backend as a contender, labelled by its canonical spec; raises (unknown
    name, missing extra, unknown option or bad value) at once."""
    cls = get_solver_class(spec)
    if isinstance(spec, str):
        parsed = solver_spec(spec)
        return Contender(parsed.text, lambda: new_solver(parsed), cls.__module__)
    return Contender(str(getattr(cls, "name", cls.__name__)), lambda: new_solver(spec),
                     cls.__module__)


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


def _load() -> float:
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:  # pragma: no cover - not on every platform
        return float("nan")


def _builds(s: Any) -> float:
    return float(getattr(s, "counters", {}).get("neighbour_builds", 0.0))


@dataclass
class _Live:
    """A warm contender during the rounds, and what its blocks measured."""

    contender: Contender
    stepper: Any
    setup_s: float
    first_step_s: float
    jit_s: float
    walls: list[float] = field(default_factory=list)  # per block
    cpus: list[float] = field(default_factory=list)
    sims: list[float] = field(default_factory=list)  # simulated time per block
    step_walls: list[float] = field(default_factory=list)  # per step, for the rebuild estimate
    rebuilt: list[bool] = field(default_factory=list)
    builds: float = 0.0

    def block(self, steps: int) -> None:
        s = self.stepper
        builds0 = _builds(s)
        sim = 0.0
        c0 = time.process_time()
        w0 = time.perf_counter()
        for _ in range(steps):
            b = _builds(s)
            t = time.perf_counter()
            dt = s.stable_dt()
            s.step(dt)
            self.step_walls.append(time.perf_counter() - t)
            self.rebuilt.append(_builds(s) > b)
            sim += dt
        self.walls.append(time.perf_counter() - w0)
        self.cpus.append(time.process_time() - c0)
        self.sims.append(sim)
        self.builds += _builds(s) - builds0


def _start(contender: Contender, problem: Problem) -> tuple[float, float, Any]:
    """(setup s, first step s, the stepper) for a fresh instance."""
    s = contender.make()
    t0 = time.perf_counter()
    s.setup(problem)
    t1 = time.perf_counter()
    s.step(s.stable_dt())
    return t1 - t0, time.perf_counter() - t1, s


def _quartiles(values: Sequence[float]) -> tuple[float, float, float, float, float]:
    """(median, q1, q3, min, max)."""
    a = np.asarray(values, dtype=float)
    q1, med, q3 = np.percentile(a, [25.0, 50.0, 75.0])
    return float(med), float(q1), float(q3), float(a.min()), float(a.max())


def run_size(
    contenders: Sequence[Contender],
    l0: float,
    *,
    steps: int | None = None,
    budget: float = DEFAULT_BUDGET_S,
    repeat: int | None = None,
    warmup: int = WARMUP_STEPS,
    progress: Callable[[str], None] | None = None,
) -> list[BenchRecord]:
    """Time every contender at spacing ``l0`` (see the module docstring); ``steps`` None:
    blocks sized by :func:`block_steps` from the warm-up."""
    if steps is not None and not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps = {steps!r} is not allowed: an integer >= 1")
    if repeat is not None and not (isinstance(repeat, int) and repeat >= 1):
        raise ValueError(f"repeat = {repeat!r} is not allowed: an integer >= 1")
    if not budget > 0:
        raise ValueError(f"budget = {budget!r} is not allowed: a number of seconds > 0")
    say = progress or (lambda text: None)
    problem = workload(l0=l0)
    n = problem.particles.n
    n_fluid = int(np.count_nonzero(problem.particles.kind == Kind.FLUID))
    load = _load()
    live: list[_Live] = []
    warm_steps: list[float] = []  # s per warm-up step, the fastest contender's sizes the blocks
    with np.errstate(all="raise", under="ignore"):
        for c in contenders:
            say(f"{c.label} at n = {n}: cold start")
            cold_setup, cold_step, cold = _start(c, problem)
            del cold
            gc.collect()  # the cold instance is gone before anything is timed
            warm_setup, warm_step, s = _start(c, problem)
            each = [warm_step]
            for _ in range(warmup):
                t = time.perf_counter()
                s.step(s.stable_dt())
                each.append(time.perf_counter() - t)
            warm_steps.append(float(np.median(each)))  # a step that rebuilt does not set it
            jit = max(0.0, (cold_setup + cold_step) - (warm_setup + warm_step))
            live.append(_Live(c, s, warm_setup, cold_step, jit))
        if steps is None:
            steps = block_steps(min(warm_steps))
        say(f"n = {n}: rounds of {steps} steps, "
            + (f"{repeat} rounds" if repeat else f"budget {budget:g} s"))
        rounds = 0
        spent = 0.0
        while True:
            for x in live:
                x.block(steps)
                spent += x.walls[-1]
            rounds += 1
            if repeat is not None:
                if rounds >= repeat:
                    break
            elif spent >= budget and rounds >= MIN_ROUNDS:
                break
        records = [_record(x, n, n_fluid, steps, rounds, load, l0) for x in live]
    _ratios(records, live)
    return records


def block_steps(step_s: float) -> int:
    """Steps per block for a fastest contender taking ``step_s`` s per step: its block lasts at
    least :data:`BLOCK_S`, and no block is shorter than :data:`DEFAULT_STEPS` steps or longer
    than :data:`MAX_BLOCK_STEPS`."""
    if not step_s > 0:  # a clock too coarse for the step: the longest block
        return MAX_BLOCK_STEPS
    return int(min(MAX_BLOCK_STEPS, max(DEFAULT_STEPS, math.ceil(BLOCK_S / step_s))))


def _record(x: _Live, n: int, n_fluid: int, steps: int, rounds: int, load: float,
            l0: float) -> BenchRecord:
    s = x.stepper
    rates = [n * steps / w for w in x.walls]
    med, q1, q3, lo, hi = _quartiles(rates)
    rebuild_ms, method = _rebuild_time(s, x.step_walls, x.rebuilt)
    counted = hasattr(s, "counters")
    cpu = float(np.median(x.cpus))
    version = getattr(s, "version", None)
    return BenchRecord(
        solver=x.contender.label, n=n, n_fluid=n_fluid, threads=_threads_of(s), steps=steps,
        rounds=rounds, particle_steps_per_s=med, particle_steps_per_s_q1=q1,
        particle_steps_per_s_q3=q3, particle_steps_per_s_min=lo, particle_steps_per_s_max=hi,
        dt_mean=float(sum(x.sims) / (steps * rounds)),
        wall_s_per_sim_s=float(np.median([w / s_ for w, s_ in zip(x.walls, x.sims, strict=True)])),
        step_ms=1e3 * float(np.median(x.walls)) / steps,
        cpu_ms_per_step=1e3 * cpu / steps,
        particle_steps_per_cpu_s=n * steps / cpu if cpu > 0 else float("nan"),
        rebuild_ms=rebuild_ms, rebuild_method=method,
        rebuilds_per_step=x.builds / (steps * rounds) if counted else None,
        jit_compile_s=x.jit_s, setup_s=x.setup_s, first_step_s=x.first_step_s,
        load_avg=load, load_avg_end=_load(), l0=l0, block_wall_s=list(x.walls),
        solver_version=None if version is None else str(version),
        code_module=x.contender.code_module,
    )


def _ratios(records: list[BenchRecord], live: list[_Live]) -> None:
    """Per-round ratios to the first contender: its blocks ran right before the others'."""
    base = live[0]
    for rec, x in zip(records, live, strict=True):
        speed = [b / w for w, b in zip(x.walls, base.walls, strict=True)]  # same steps, same n
        rec.speedup_vs_first, rec.speedup_q1, rec.speedup_q3, rec.speedup_min, rec.speedup_max = (
            _quartiles(speed))
        sooner = [(bw / bs) / (w / s) for w, s, bw, bs
                  in zip(x.walls, x.sims, base.walls, base.sims, strict=True)]
        rec.time_to_solution_speedup = float(np.median(sooner))
        rec.first_solver = base.contender.label


def _threads_of(solver: Any) -> int:
    threads = getattr(solver, "threads", None)
    return threads if isinstance(threads, int) else 1


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
    contenders: Sequence[Contender | str],
    sizes: Sequence[int],
    *,
    steps: int | None = None,
    budget: float = DEFAULT_BUDGET_S,
    repeat: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[BenchRecord]:
    """Every contender at every size; ratios are to the first contender (a name is a solver);
    ``steps`` None: blocks sized per size (:func:`block_steps`)."""
    entries = [c if isinstance(c, Contender) else solver_contender(c) for c in contenders]
    if not entries:
        raise ValueError("run_bench: no contender")
    records: list[BenchRecord] = []
    for n in sizes:
        records += run_size(entries, spacing_for(n), steps=steps, budget=budget, repeat=repeat,
                            progress=progress)
    return records


def format_table(records: Sequence[BenchRecord]) -> str:
    """A plain-text table: one line per contender and size (the solver column as wide as the
    longest spec, so options do not push the columns out of line)."""
    w = max([16, *(len(r.solver) for r in records)])
    head = (
        f"{'solver':<{w}} {'n':>7} {'thr':>3} {'rounds':>6} {'Mpart-steps/s [q1-q3]':>23} "
        f"{'speed-up [min-max]':>19} {'to t':>6} {'per CPU-s':>9} {'step ms':>8} "
        f"{'rebuild ms':>10} {'JIT s':>6} {'load':>9}"
    )
    lines = [head, "-" * len(head)]
    for r in records:
        rate = (f"{r.particle_steps_per_s / 1e6:.3f} [{r.particle_steps_per_s_q1 / 1e6:.3f}-"
                f"{r.particle_steps_per_s_q3 / 1e6:.3f}]")
        speed = f"{r.speedup_vs_first:.2f}x [{r.speedup_min:.2f}-{r.speedup_max:.2f}]"
        rebuild = "-" if r.rebuild_ms is None else f"{r.rebuild_ms:.1f}"
        lines.append(
            f"{r.solver:<{w}} {r.n:>7} {r.threads:>3} {r.rounds:>6} {rate:>23} {speed:>19} "
            f"{r.time_to_solution_speedup:>5.2f}x {r.particle_steps_per_cpu_s / 1e6:>9.3f} "
            f"{r.step_ms:>8.2f} {rebuild:>10} {r.jit_compile_s:>6.2f} "
            f"{r.load_avg:>4.1f}-{r.load_avg_end:<4.1f}"
        )
    return "\n".join(lines)


__all__ = [
    "DEFAULT_SIZES",
    "SIZES",
    "BenchRecord",
    "Contender",
    "RECORD_FIELDS",
    "format_table",
    "new_solver",
    "run_bench",
    "run_size",
    "solver_contender",
    "spacing_for",
    "workload",
]
