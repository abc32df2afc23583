"""The runner owns the time loop: time step choice, probes, divergence detection, limits.

``run(solver, problem, end_time=...)`` never raises for a failing simulation: it returns a
:class:`RunResult` whose ``status`` is ``completed``, ``diverged`` (NaN, runaway velocity,
particles leaving the domain, floating-point error), ``unsupported`` (the solver's capabilities
exclude the problem, with the reasons), ``timed-out`` (a :class:`RunLimits` step or wall-clock
limit stopped it; ``time`` is the time reached) or ``failed`` (any other exception, with the
reason).  Time steps are shortened to land exactly on probe times.  After each step the runner
checks the solver's ``health()`` summary; the state itself is read by probes on their own
schedule and once at the end.

A case calls ``run`` inside its ``execute``; the sweep that executes the case
(:func:`mpsbench.results.records.execute_task`) opens a :func:`task_context` around it, which
carries the run limits to every ``run`` of the case, collects their results (so a refusal is
reported with its reason even when the case's post-processing then trips over empty probes)
and reports progress (time reached, steps) to a supervising process.  The wall-clock limit
checked here is a soft one (between steps); a step that never returns is stopped from outside
by the supervising process (:mod:`mpsbench.results.executors`).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mpsbench.errors import where
from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Particles
from mpsbench.run.frames import Frame, recorder
from mpsbench.run.probes import Probe
from mpsbench.run.protocol import Problem, Solver, Status, UnsupportedProblem, health_of
from mpsbench.run.specs import make_solver


class Diverged(Exception):
    """Raised inside the loop when a divergence check trips."""


class TimedOut(Exception):
    """Raised inside the loop when a :class:`RunLimits` limit is reached."""


@dataclass(frozen=True)
class RunLimits:
    """Limits of one run of a case (a sweep task): ``max_steps`` time steps per solver run and
    ``max_wall_s`` wall-clock seconds for all its solver runs together, set-up included (None:
    no limit).  A run that reaches one ends ``timed-out`` with the time it reached."""

    max_steps: int | None = None
    max_wall_s: float | None = None

    def __post_init__(self) -> None:
        if self.max_steps is not None and not (
                isinstance(self.max_steps, int) and self.max_steps >= 1):
            raise ValueError(f"RunLimits.max_steps = {self.max_steps!r} is not allowed: an "
                             "integer >= 1 or None")
        if self.max_wall_s is not None and not (
                isinstance(self.max_wall_s, (int, float)) and math.isfinite(self.max_wall_s)
                and self.max_wall_s > 0):
            raise ValueError(f"RunLimits.max_wall_s = {self.max_wall_s!r} is not allowed: a "
                             "finite number > 0 (s) or None")

    def describe(self) -> str:
        bits = [f"{self.max_steps} steps" if self.max_steps else "",
                f"{self.max_wall_s:g} s" if self.max_wall_s else ""]
        return " and ".join(b for b in bits if b) or "none"


ProgressSink = Callable[[float, int, float], None]
"""Hears ``(t, steps, t_end)`` of the solver run in progress (``t_end`` nan: a run to a step
count); a supervising process draws a bar per run from it and keeps the last report."""


@dataclass
class TaskContext:
    """What :func:`task_context` shares with every ``run`` of one case run (see the module
    docstring): the limits, the start time, the results so far, the progress sink."""

    limits: RunLimits
    started: float
    progress: ProgressSink | None = None
    results: list[RunResult] = field(default_factory=list)
    every_s: float = 0.25  # progress reports at most this often
    end_time: float = math.nan  # of the solver run in progress
    _last: float = -math.inf

    @property
    def deadline(self) -> float:
        """perf_counter() value at which the wall-clock limit is reached (inf: none)."""
        w = self.limits.max_wall_s
        return self.started + w if w else math.inf

    def tick(self, t: float, steps: int, force: bool = False) -> None:
        if self.progress is None:
            return
        now = _time.perf_counter()
        if force or now - self._last >= self.every_s:
            self._last = now
            self.progress(t, steps, self.end_time)


_CONTEXT: ContextVar[TaskContext | None] = ContextVar("mpsbench_task_context", default=None)


@contextmanager
def task_context(limits: RunLimits | None = None,
                 progress: ProgressSink | None = None) -> Iterator[TaskContext]:
    """Open the context of one case run: every :func:`run` inside obeys ``limits``, appends
    its result to ``ctx.results`` and reports (time, steps) to ``progress``."""
    ctx = TaskContext(limits or RunLimits(), _time.perf_counter(), progress)
    token = _CONTEXT.set(ctx)
    try:
        yield ctx
    finally:
        _CONTEXT.reset(token)


def current_context() -> TaskContext | None:
    return _CONTEXT.get()


@dataclass
class RunResult:
    status: Status
    reason: str
    time: float
    n_steps: int
    wall_time_s: float
    particle_steps: float
    n_particles: int
    probes: dict[str, Probe] = field(default_factory=dict)
    final: Particles | None = None
    counters: dict[str, float] = field(default_factory=dict)
    solver_name: str = ""
    solver_version: str = ""
    setup_time_s: float = 0.0
    frames: list[Frame] = field(default_factory=list)  # with keeping_frames (run/frames.py)

    @property
    def ok(self) -> bool:
        return self.status == Status.COMPLETED

    @property
    def particle_steps_per_s(self) -> float:
        return self.particle_steps / self.wall_time_s if self.wall_time_s > 0 else 0.0


@dataclass
class DivergenceLimits:
    """When a run counts as diverged.

    ``max_speed`` [m/s]: default for flow = the sound speed c0 (nothing in a WC-MPS flow
    may move faster).  ``leave_margin`` [m]: how far outside the box (non-periodic axes) a fluid
    particle may go; default 5 l0.  ``max_field_growth``: for diffusion, max |phi| may not grow
    beyond this factor of its initial maximum (diffusion never amplifies).
    """

    max_speed: float | None = None
    leave_margin: float | None = None
    max_field_growth: float = 10.0


def run(
    solver: str | type | Solver,
    problem: Problem,
    *,
    end_time: float | None = None,
    max_steps: int | None = None,
    probes: Sequence[Probe] = (),
    limits: DivergenceLimits | None = None,
    dt: float | None = None,
    progress: Callable[[float, int], None] | None = None,
    keep_final: bool = True,
    run_limits: RunLimits | None = None,
) -> RunResult:
    """Run ``problem`` on ``solver`` until ``end_time`` [s] or ``max_steps`` steps.

    ``max_steps`` is what the caller asks for (reaching it completes the run); ``run_limits``
    (default: those of the enclosing :func:`task_context`) stop a run that goes on too long
    (``timed-out``).
    """
    ctx = _CONTEXT.get()
    result = _run(solver, problem, end_time, max_steps, probes, limits, dt, progress, keep_final,
                  run_limits or (ctx.limits if ctx is not None else RunLimits()),
                  ctx.deadline if ctx is not None and run_limits is None else None, ctx)
    if ctx is not None:
        ctx.results.append(result)
        ctx.tick(result.time, result.n_steps, force=True)
    return result


def _run(
    solver: str | type | Solver,
    problem: Problem,
    end_time: float | None,
    max_steps: int | None,
    probes: Sequence[Probe],
    limits: DivergenceLimits | None,
    dt: float | None,
    progress: Callable[[float, int], None] | None,
    keep_final: bool,
    run_limits: RunLimits,
    deadline: float | None,
    ctx: TaskContext | None,
) -> RunResult:
    if not isinstance(problem, Problem):
        raise TypeError(f"run: problem must be a mpsbench.run.protocol.Problem, not "
                        f"{type(problem).__name__} (a case's build() may return more than one)")
    if end_time is None and max_steps is None:
        raise ValueError("run: give end_time or max_steps (or both)")
    if end_time is not None and not (math.isfinite(end_time) and end_time > 0):
        raise ValueError(f"run: end_time = {end_time!r} is not allowed: a finite number > 0 (s)")
    limits = limits or DivergenceLimits()
    t_start = _time.perf_counter()
    if deadline is None:  # limits of this run alone: the wall clock starts now
        deadline = t_start + run_limits.max_wall_s if run_limits.max_wall_s else math.inf
    try:
        s = make_solver(solver)
    except Exception as exc:  # noqa: BLE001 - reported in the result
        return _early(Status.FAILED, f"cannot create solver: {exc}", problem)
    try:
        s.setup(problem)
    except UnsupportedProblem as exc:
        return _early(Status.UNSUPPORTED, str(exc), problem, s)
    except Exception as exc:  # noqa: BLE001
        return _early(Status.FAILED, f"setup failed: {type(exc).__name__}: {exc}{where(exc)}",
                      problem, s)
    setup_time = _time.perf_counter() - t_start
    horizon = end_time if end_time is not None else math.inf
    for probe in probes:
        probe.start(horizon)
    max_speed = limits.max_speed
    if max_speed is None and isinstance(problem.physics, FlowPhysics):
        max_speed = problem.physics.c0
    margin = limits.leave_margin if limits.leave_margin is not None else 5.0 * problem.l0
    field0 = _field_scale(s, problem)
    status, reason = Status.COMPLETED, ""
    t_loop = _time.perf_counter()
    if ctx is not None:
        ctx.end_time = end_time if end_time is not None else math.nan
    # Overflow, invalid and divide-by-zero in a step mean the run has broken down.
    old_err = np.seterr(over="raise", invalid="raise", divide="raise", under="ignore")
    frames = recorder(end_time, max_steps)  # never shortens a step: results stay the same
    try:
        _observe(probes, s)
        if frames is not None:
            frames.maybe_record(s)
        while True:
            if max_steps is not None and s.n_steps >= max_steps:
                break
            if end_time is not None and s.time >= end_time * (1 - 1e-12):
                break
            if run_limits.max_steps is not None and s.n_steps >= run_limits.max_steps:
                raise TimedOut(f"step limit of {run_limits.max_steps} steps reached")
            if _time.perf_counter() >= deadline:
                raise TimedOut(f"wall-clock limit of {run_limits.max_wall_s:g} s reached")
            h = dt if dt is not None else s.stable_dt()
            if not (math.isfinite(h) and h > 0):
                raise Diverged(f"time step {h!r} is not a positive finite number")
            nxt = min([p.next_time() for p in probes] + [horizon])
            if s.time + h > nxt:
                h = nxt - s.time
            elif s.time + 1.5 * h > nxt:  # avoid a sliver step before an event
                h = 0.5 * (nxt - s.time)
            s.step(h)
            # land exactly on the event despite round-off (no event: nxt is inf, keep the time)
            if math.isfinite(nxt) and abs(s.time - nxt) <= 1e-12 * max(1.0, abs(nxt)):
                s.time = nxt
            _check(s, problem, max_speed, margin, field0, limits)
            _observe(probes, s)
            if frames is not None:
                frames.maybe_record(s)
            if progress is not None:
                progress(s.time, s.n_steps)
            if ctx is not None:
                ctx.tick(s.time, s.n_steps)
    except TimedOut as exc:
        status, reason = Status.TIMED_OUT, str(exc)
    except (Diverged, FloatingPointError) as exc:
        status, reason = Status.DIVERGED, f"{type(exc).__name__}: {exc}" if isinstance(
            exc, FloatingPointError) else str(exc)
    except Exception as exc:  # noqa: BLE001 - a solver bug is a failed run, not a crash
        status = Status.FAILED
        reason = f"{type(exc).__name__}: {exc}{where(exc)}"
    finally:
        np.seterr(**old_err)
    wall = _time.perf_counter() - t_loop
    if frames is not None:
        frames.finish(s)
    if status != Status.COMPLETED:
        reason = f"{reason} [t = {s.time:.6g} s, step {s.n_steps}]"
    s.status = status
    state = s.state() if keep_final else None
    counters = dict(getattr(s, "counters", {}))
    return RunResult(
        status=status,
        reason=reason,
        time=s.time,
        n_steps=s.n_steps,
        wall_time_s=wall,
        particle_steps=float(counters.get("particle_steps", 0.0)),
        n_particles=s.state().n,
        probes={p.name: p for p in probes},
        final=state.copy() if state is not None else None,
        counters=counters,
        solver_name=s.name,
        solver_version=str(s.version),
        setup_time_s=setup_time,
        frames=frames.frames if frames is not None else [],
    )


def _early(status: Status, reason: str, problem: Problem, s: Any = None) -> RunResult:
    return RunResult(
        status, reason, 0.0, 0, 0.0, 0.0, problem.particles.n,
        solver_name=getattr(s, "name", ""), solver_version=str(getattr(s, "version", "")),
    )


def _observe(probes: Sequence[Probe], s: Solver) -> None:
    for probe in probes:
        probe.maybe_record(s)


def _field_scale(s: Solver, problem: Problem) -> float:
    name = getattr(problem.physics, "field_name", None)
    if name is None:
        return 0.0
    return float(np.max(np.abs(s.state().fields[name]))) or 1.0


def _check(
    s: Solver, problem: Problem, max_speed: float | None, margin: float, field0: float,
    limits: DivergenceLimits,
) -> None:
    """Raise :class:`Diverged` when the solver's health summary trips a limit (the runner asks
    for the summary, not the state: a device backend need not copy its state every step)."""
    ask = getattr(s, "health", None)
    if callable(ask):
        h = ask(margin)
    else:  # a backend written before health() (not a SolverBase): the same from its state
        h = health_of(s.state(), problem.box, margin, getattr(problem.physics, "field_name", None))
    if not h.finite:
        raise Diverged("non-finite position, velocity or pressure")
    if max_speed is not None and not h.max_fluid_speed <= max_speed:
        raise Diverged(
            f"fluid speed {h.max_fluid_speed:.4g} m/s exceeds the bound {max_speed:.4g} m/s"
        )
    if h.fluid_outside:
        raise Diverged(f"{h.fluid_outside} fluid particle(s) left the domain")
    name = getattr(problem.physics, "field_name", None)
    if name is not None:
        if not math.isfinite(h.field_max):
            raise Diverged(f"non-finite values in field {name!r}")
        if h.field_max > limits.max_field_growth * field0:
            raise Diverged(
                f"field {name!r} grew beyond {limits.max_field_growth}x its initial maximum"
            )
