"""Runs in progress, as the executors see them while a sweep goes on (issue 18: one bar per run).

An executor that can see its runs' state calls a sweep's ``watch`` callback every fraction of a
second with a :class:`LiveRun` per run in progress: how far its current solver run got.  Local
executors can (in this process: the runner's progress sink; in supervised worker processes:
the shared memory they already write after every step); a dask cluster's workers do not report
(its runs are seen only when they finish).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from mpsbench.results.records import Task


@dataclass(frozen=True)
class LiveRun:
    """One run in progress: ``t`` (None before the first step) and ``steps`` of its current
    solver run, that run's ``t_end`` (nan: a run to a step count), seconds since it started."""

    task: Task
    t: float | None
    steps: int
    t_end: float
    elapsed_s: float

    @property
    def fraction(self) -> float | None:
        """Share of the current solver run's simulated time done (None: cannot tell)."""
        if self.t is None or not math.isfinite(self.t_end) or self.t_end <= 0:
            return None
        return min(1.0, max(0.0, self.t / self.t_end))


WatchFn = Callable[[Sequence[LiveRun]], None]
