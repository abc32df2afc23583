"""Supervised worker processes: runs that may crash or hang the process running them.

:func:`run_supervised` keeps up to ``jobs`` long-lived worker processes and hands each one task
at a time (a worker keeps its imports and compiled kernels from one run to the next).  The
parent watches every busy worker:

* the worker writes the time and step its run reached into shared memory after every step (the
  runner's :class:`~mpsbench.run.runner.TaskContext` reports them) and sends
  ``("done", record)`` when the run is recorded (the worker writes the record itself,
  atomically, as ``execute_task`` always does);
* a worker that dies -- a segfault in native code, ``os._exit``, the OOM killer -- makes its run
  ``crashed``: the parent writes the record, with the signal (``SIGSEGV``) or the exit status
  and the time the run had reported reaching, and starts a fresh worker for the next run;
* a run still going ``GRACE_FRACTION`` (at least ``GRACE_MIN_S``) past its wall-clock limit
  is one whose step never returned (the runner checks the limit between steps): the parent
  kills the worker (SIGKILL: a hang in native code ignores anything gentler) and records the
  run ``timed-out`` with the time reached.

Every other run goes on: one bad run costs its own record only.  Workers end with the parent,
even when it is killed (``PR_SET_PDEATHSIG``), ignore Ctrl-C (the parent stops them), and are
killed when the consumer stops early; a run cut short that way leaves no record (writes are
atomic) and runs again on resume.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_ready
from pathlib import Path
from typing import Any

from mpsbench.results.live import LiveRun, WatchFn
from mpsbench.results.records import (
    Task,
    _solver_commit,
    atomic_write_text,
    execute_task,
    stopped_record,
    task_limits,
)
from mpsbench.run.protocol import Status

GRACE_FRACTION = 0.1
GRACE_MIN_S = 20.0
"""How long past its wall-clock limit a run may go before its worker is killed: the runner
stops a run at the first step boundary past the limit, so only a step that does not return
(or a case's analysis that does not) reaches the kill."""

FolderFn = Callable[[Task], Path]


def kill_after(wall_s: float | None) -> float:
    """Seconds after the start of a run with wall-clock limit ``wall_s`` at which its worker is
    killed (inf: no limit)."""
    if not wall_s:
        return math.inf
    return wall_s + max(GRACE_MIN_S, GRACE_FRACTION * wall_s)


def signal_name(code: int) -> str:
    try:
        return signal.Signals(code).name
    except ValueError:
        return f"signal {code}"


def _die_with_parent(parent: int) -> None:
    """In a worker: end when the study process ends, even by SIGKILL (Linux; elsewhere a no-op).

    Without this, workers of a killed study go on with the runs already handed to them.
    """
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent died before the call: nobody will signal us
        os._exit(1)


def _worker_main(conn: Connection, parent: int, reached: Any) -> None:
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us on Ctrl-C

    def report(t: float, steps: int, t_end: float) -> None:
        # shared memory, written after every step (a pipe message per step would cost more
        # than a small step): the parent reads it for the progress bars and when the run dies
        # or is killed
        reached[0], reached[1], reached[2] = t, steps, t_end

    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        task, folder, env = msg
        reached[0], reached[1], reached[2] = math.nan, 0.0, math.nan
        rec = execute_task(task, folder, env, progress=report, progress_every=0.0)
        conn.send(("done", rec))


class _Worker:
    """One worker process and the run it is on."""

    def __init__(self, ctx: Any) -> None:
        self.conn, child = ctx.Pipe()
        self.shared = ctx.RawArray("d", 3)  # (t, steps, t_end) of the current solver run
        self.shared[0] = self.shared[2] = math.nan
        self.proc = ctx.Process(target=_worker_main, args=(child, os.getpid(), self.shared),
                                name="mpsbench-worker")
        self.proc.start()
        child.close()
        self.task: Task | None = None
        self.started = 0.0
        self.kill_at = math.inf
        self.wall: float | None = None

    @property
    def reached(self) -> tuple[float | None, int]:
        t, steps = float(self.shared[0]), int(self.shared[1])
        return (None, 0) if math.isnan(t) else (t, steps)

    def live(self) -> LiveRun:
        assert self.task is not None
        t, steps = self.reached
        return LiveRun(self.task, t, steps, float(self.shared[2]),
                       time.monotonic() - self.started)

    def assign(self, task: Task, folder: Path, env: dict[str, Any]) -> None:
        self.task, self.started = task, time.monotonic()
        self.shared[0], self.shared[1], self.shared[2] = math.nan, 0.0, math.nan
        self.wall = task_limits(task).max_wall_s
        self.kill_at = self.started + kill_after(self.wall)
        self.conn.send((task, str(folder), env))

    def collect(self) -> dict[str, Any] | None:
        """Read what the worker sent; its record when the run is done."""
        try:
            while self.conn.poll():
                kind, *rest = self.conn.recv()
                if kind == "done":
                    return dict(rest[0])
        except (EOFError, OSError):
            pass
        return None

    def where(self) -> str:
        t, steps = self.reached
        return f" [t = {t:.6g} s, step {steps}]" if t is not None else " [before the first step]"

    def stop(self, kill: bool = False) -> None:
        if self.proc.is_alive():
            if kill or self.task is not None:
                self.proc.kill()
            else:
                try:
                    self.conn.send(None)
                except OSError:
                    self.proc.kill()
        self.proc.join(timeout=10)
        if self.proc.is_alive():  # pragma: no cover - a worker that ignores SIGKILL
            self.proc.kill()
            self.proc.join(timeout=10)
        self.conn.close()


def _record(task: Task, folder: FolderFn, rec: dict[str, Any]) -> dict[str, Any]:
    rec["solver_commit"] = _solver_commit(task.solver)
    runs = Path(folder(task)) / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    import json

    atomic_write_text(runs / f"{task.run_id}.json", json.dumps(rec, indent=1))
    return rec


def _crashed(w: _Worker, folder: FolderFn, env: dict[str, Any]) -> dict[str, Any]:
    assert w.task is not None
    w.proc.join(timeout=5)
    code = w.proc.exitcode
    if code is not None and code < 0:
        sig = signal_name(-code)
        why = f"the process running it died from {sig} (signal {-code})"
    else:
        sig = ""
        why = f"the process running it exited with status {code} before recording the run"
    t, steps = w.reached
    rec = stopped_record(w.task, Status.CRASHED, why + w.where(), env, sim_time_s=t,
                         n_steps=steps, elapsed_s=time.monotonic() - w.started, signal=sig)
    return _record(w.task, folder, rec)


def _killed(w: _Worker, folder: FolderFn, env: dict[str, Any]) -> dict[str, Any]:
    assert w.task is not None
    took = time.monotonic() - w.started
    w.proc.kill()
    w.proc.join(timeout=10)
    t, steps = w.reached
    why = (f"killed after {took:.0f} s: the wall-clock limit is {w.wall:g} s and no step "
           f"returned within {took - (w.wall or 0):.0f} s past it (a solver that hangs inside "
           "a step)" + w.where())
    rec = stopped_record(w.task, Status.TIMED_OUT, why, env, sim_time_s=t, n_steps=steps,
                         elapsed_s=took)
    return _record(w.task, folder, rec)


def run_supervised(
    tasks: Sequence[Task], folder: FolderFn, env: dict[str, Any], jobs: int,
    watch: WatchFn | None = None,
) -> Iterator[tuple[Task, dict[str, Any]]]:
    """Run ``tasks`` on ``jobs`` supervised worker processes; yield ``(task, record)`` as each
    run is recorded (module docstring).  ``watch`` hears the runs in progress about twice a
    second (:mod:`.live`)."""
    ctx = mp.get_context()
    queue = deque(tasks)
    workers: list[_Worker] = []
    try:
        while queue or any(w.task is not None for w in workers):
            for w in workers:
                if w.task is None and queue:
                    task = queue.popleft()
                    w.assign(task, folder(task), env)
            while queue and len(workers) < jobs:
                w = _Worker(ctx)
                workers.append(w)
                task = queue.popleft()
                w.assign(task, folder(task), env)
            busy = [w for w in workers if w.task is not None]
            timeout = min(w.kill_at for w in busy) - time.monotonic()
            wait_ready([w.conn for w in busy] + [w.proc.sentinel for w in busy],
                       timeout=min(max(timeout, 0.0), 5.0 if watch is None else 0.5))
            if watch is not None:
                watch([w.live() for w in busy])
            for w in busy:
                current = w.task
                assert current is not None
                rec = w.collect()
                if rec is None and not w.proc.is_alive():
                    rec = w.collect()  # a record sent just before the end
                    if rec is None:
                        rec = _crashed(w, folder, env)
                        _retire(w, workers)
                elif rec is None and time.monotonic() >= w.kill_at:
                    rec = _killed(w, folder, env)
                    _retire(w, workers)
                if rec is not None:
                    w.task = None
                    yield current, rec
    finally:
        for w in workers:
            w.stop()


def _retire(w: _Worker, workers: list[_Worker]) -> None:
    """Reap a worker that died or was killed; the next run gets a fresh one."""
    w.task = None
    workers.remove(w)
    w.stop(kill=True)
