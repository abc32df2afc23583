"""Frames: particle states kept from every run for ParaView and ``mpsbench show``.

Frames are an *output* option (``mpsbench validate ... --vtu``), not a case parameter: asking
for them changes no run id, no identity hash and no result.  To that end a frame recorder,
unlike a probe, never shortens a time step: it copies the state at the first step that reaches
each frame time (so the frame's time is the time actually reached, stored with it), and a run
with frames takes exactly the steps of a run without.

``keeping_frames(n)`` turns recording on for every :func:`mpsbench.run.runner.run` inside the
block (the worker that executes a task sets it from ``Task.frames``): ``n`` frames evenly
spaced over [0, end_time] (or over the step count of a ``max_steps`` run), the first at the
start, the last at the end; a run that stops early also keeps its last state.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any

from mpsbench.physics.particles import Particles

_FRAMES: ContextVar[int] = ContextVar("mpsbench_frames", default=0)


@dataclass
class Frame:
    time: float  # [s], the time the run had reached
    step: int
    particles: Particles


@contextmanager
def keeping_frames(n: int) -> Iterator[None]:
    """Every run inside the block keeps ``n`` frames (0: none)."""
    token = _FRAMES.set(max(0, int(n)))
    try:
        yield
    finally:
        _FRAMES.reset(token)


class FrameRecorder:
    """Copies the state at ``n`` evenly spaced times (or step counts) of one run."""

    def __init__(self, n: int, end_time: float | None, max_steps: int | None) -> None:
        self.frames: list[Frame] = []
        k = range(n)
        last = max(1, n - 1)
        if end_time is not None and math.isfinite(end_time):
            self.by_time = True
            self.marks = [end_time * i / last for i in k] if n > 1 else [end_time]
        else:
            self.by_time = False
            steps = max_steps or 0
            self.marks = [float(round(steps * i / last)) for i in k] if n > 1 else [float(steps)]
        self._next = 0

    def maybe_record(self, solver: Any) -> None:
        now = float(solver.time) if self.by_time else float(solver.n_steps)
        reached = False
        while self._next < len(self.marks) and now >= self.marks[self._next] * (1 - 1e-12):
            self._next += 1
            reached = True
        if reached:
            self._keep(solver)

    def finish(self, solver: Any) -> None:
        """After the loop: the last state, when the run stopped before its last frame."""
        if not self.frames or self.frames[-1].step != solver.n_steps:
            self._keep(solver)

    def _keep(self, solver: Any) -> None:
        self.frames.append(Frame(float(solver.time), int(solver.n_steps),
                                 solver.state().copy()))


def recorder(end_time: float | None, max_steps: int | None) -> FrameRecorder | None:
    """The recorder for a run starting now (None when no frames are asked for)."""
    n = _FRAMES.get()
    return FrameRecorder(n, end_time, max_steps) if n > 0 else None
