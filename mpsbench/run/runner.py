"""The runner owns the time loop: time step choice, probes, divergence detection, counters.

``run(solver, problem, end_time=...)`` never raises for a failing simulation: it returns a
:class:`RunResult` whose ``status`` is ``completed``, ``diverged`` (NaN, runaway velocity,
particles leaving the domain, floating-point error) or ``failed`` (any other exception, with the
reason).  Time steps are shortened to land exactly on probe times.  After each step the runner
checks the solver's ``health()`` summary; the state itself is read by probes on their own
schedule and once at the end.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Sequence
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
) -> RunResult:
    """Run ``problem`` on ``solver`` until ``end_time`` [s] or ``max_steps`` steps."""
    if end_time is None and max_steps is None:
        raise ValueError("run: give end_time or max_steps (or both)")
    if end_time is not None and not (math.isfinite(end_time) and end_time > 0):
        raise ValueError(f"run: end_time = {end_time!r} is not allowed: a finite number > 0 (s)")
    limits = limits or DivergenceLimits()
    t_start = _time.perf_counter()
    try:
        s = make_solver(solver)
    except Exception as exc:  # noqa: BLE001 - reported in the result
        return _early(Status.FAILED, f"cannot create solver: {exc}", problem)
    try:
        s.setup(problem)
    except UnsupportedProblem as exc:
        return _early(Status.FAILED, str(exc), problem, s)
    except Exception as exc:  # noqa: BLE001
        return _early(Status.FAILED, f"setup failed: {type(exc).__name__}: {exc}", problem, s)
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
