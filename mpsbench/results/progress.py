"""Progress of a sweep on the terminal (``mpsbench validate``): how far, and how long is left.

The work of a run is its estimated cost, particles x time steps from ``Case.estimate``
(:mod:`mpsbench.run.estimate`; a run without an estimate counts as the mean of those with one,
or 1 when none has), so the ETA follows the work done rather than the run count: a tier's many
short runs and few long ones no longer make the count say nothing (issue 18).

A particle-step does not cost the same in every case: one Laplacian sum in the diffusion case,
half a dozen pair passes and neighbour rebuilds in a flow (the numba quick tier measured 0.04
us per particle-step for diffusion, 0.3-1.2 us for the flows).  So the ETA prices the work left
of each case and solver at that pair's own seconds per unit of work, measured on its finished
runs (:meth:`Progress.eta`; a skipped run's record counts with the time of its earlier run),
less the seconds its backend spent compiling (the record's ``compile_s``: numba's kernels on a
cold cache, once per worker process, would otherwise price a case's every run as if it compiled
again; compilations still to come are not foreseen), and divides by the concurrency seen so
far (run seconds per elapsed second, compiling included); the ETA is
unknown ("?" on the bar, left out of a plain line) until every pair with runs left has
finished one.  ``mpsbench validate all`` submits a run of median work of every case and solver
first (:func:`mpsbench.commands.validate.heavy_first`), so every rate is known within the
first seconds (one case runs in its plan's order).

Three modes:

* on a terminal (a TTY), an overall bar drawn with tqdm: runs done / planned, the share of the
  estimated work done, elapsed time and ETA, the last finished run's short label; under it one
  bar per run in progress (:meth:`Progress.running`): its short label, the simulated time of
  its current solver run against that run's end time, the step, how long it has been going
  ("setting up" before its first step: building the problem, compiling kernels); a run that
  did not complete is printed above the bars with its reason;
* otherwise (a log, CI) plain lines, one per finished run: ``[done/total elapsed eta] status
  run_id wall`` (and the reason of a run that did not complete);
* ``quiet``: nothing per run (the verdicts at the end are printed as always); ``verbose``:
  the plain lines even on a terminal.

The runs in progress come from the executor (:mod:`.live`): local runs report, a dask
cluster's do not (only the overall bar moves).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

from mpsbench.results.live import LiveRun
from mpsbench.results.records import Task

ProgressFn = Callable[[int, int, dict[str, Any], bool], None]


def task_costs(tasks: Sequence[Task]) -> dict[str, float]:
    """Estimated work per run id: particles x steps (see the module docstring)."""
    from mpsbench.cases import get_case

    known: dict[str, float] = {}
    for t in tasks:
        try:
            est = get_case(t.case).estimate(dict(t.params))
            work = est.particle_steps if est is not None else None
        except Exception:  # noqa: BLE001 - no estimate: the mean below
            work = None
        if work:
            known[t.run_id] = float(work)
    mean = sum(known.values()) / len(known) if known else 1.0
    return {t.run_id: known.get(t.run_id, mean) for t in tasks}


def _run_seconds(record: dict[str, Any]) -> float | None:
    """How long a finished run kept its worker: ``elapsed_s`` (building the problem, the
    solver runs and the analysis), else ``wall_time_s``; None when the record has neither."""
    for name in ("elapsed_s", "wall_time_s"):
        value = _seconds(record.get(name))
        if value is not None:
            return value
    return None


def _seconds(value: Any) -> float | None:
    ok = isinstance(value, (int, float)) and math.isfinite(value) and value >= 0
    return float(value) if ok else None


def short_label(record: dict[str, Any], width: int = 48) -> str:
    """A run's id without its case, solver and hash, cut to ``width`` characters."""
    rid = str(record.get("run_id", "?"))
    head = f"{record.get('case', '')}_{record.get('solver', '')}_"
    body = rid[len(head):] if rid.startswith(head) else rid
    body = body.rsplit("_", 1)[0] if "_" in body else "(defaults)"
    label = f"{record.get('case', '')} {body}".strip()
    return label if len(label) <= width else label[: width - 3] + "..."


def _clock(seconds: float) -> str:
    s = int(round(max(0.0, seconds)))
    if s >= 3600:
        return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
    return f"{s // 60}:{s % 60:02d}"


class Progress:
    """The progress callback of :func:`mpsbench.results.sweep.run_tasks` (call :meth:`close`
    at the end)."""

    def __init__(self, tasks: Sequence[Task], mode: str = "auto", stream: Any = None) -> None:
        self.stream = stream or sys.stderr
        self.costs = task_costs(tasks) if mode != "quiet" else {}
        self.total_work = sum(self.costs.values()) or 1.0
        self.work_done = 0.0  # of runs that ran now (skipped ones are not timed)
        self.work_skipped = 0.0
        self.pending = {t.run_id: (t.case, t.solver) for t in tasks}  # not finished yet
        self.finished: set[tuple[str, str]] = set()  # case and solver pairs with a run done
        self.seconds: dict[tuple[str, str], float] = {}  # run time of their timed runs
        self.timed_work: dict[tuple[str, str], float] = {}  # and those runs' work
        self.busy = 0.0  # run time of the runs run now (not skipped)
        self.t0 = time.perf_counter()
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.mode = mode if mode in ("quiet", "verbose") else ("bar" if tty else "plain")
        self.bar: Any = None
        if self.mode == "bar":
            import shutil

            from tqdm import tqdm

            # a pty made without a size (script, some CI runners) reports 0 x 0: tqdm then
            # draws nothing at all, so fall back to 100 x 24
            size = shutil.get_terminal_size((100, 24))
            cols = size.columns or 100
            self.cols, self.rows = cols, size.lines or 24
            self.bar = tqdm(total=len(tasks), file=self.stream, unit="run", ncols=cols,
                            nrows=self.rows,
                            bar_format="{desc} {bar} {n_fmt}/{total_fmt} runs{postfix}")
        self.run_bars: list[Any] = []  # one per run in progress, under the overall bar
        self._drawn = -1.0

    def eta(self) -> float | None:
        """Seconds left: the work left of each case and solver at its own measured seconds
        per unit of work, over the concurrency seen so far (the run seconds of this sweep per
        elapsed second).  None before any run finished, and while a case and solver that has
        runs left has not finished one (their first runs go first); a case and solver whose
        runs carry no run time is priced at the rate of all the others, and without any run
        times the work left goes at the elapsed time per unit of work done."""
        elapsed = time.perf_counter() - self.t0
        if self.work_done <= 0:
            return None
        timed = sum(self.timed_work.values())
        if self.busy <= 0 or timed <= 0:
            left = self.total_work - self.work_done - self.work_skipped
            return max(0.0, left) * elapsed / self.work_done
        if any(key not in self.finished for key in self.pending.values()):
            return None
        overall = sum(self.seconds.values()) / timed
        rate = {key: self.seconds[key] / work for key, work in self.timed_work.items()}
        run_seconds = sum(self.costs.get(rid, 0.0) * rate.get(key, overall)
                          for rid, key in self.pending.items())
        return run_seconds * elapsed / self.busy  # busy / elapsed: the runs going at once

    def __call__(self, done: int, total: int, record: dict[str, Any], skipped: bool) -> None:
        if self.mode == "quiet":
            return
        rid = str(record.get("run_id"))
        work = self.costs.get(rid, 0.0)
        key = self.pending.pop(rid, (str(record.get("case", "")), str(record.get("solver", ""))))
        self.finished.add(key)
        run_s = _run_seconds(record)
        if run_s is not None and work > 0:  # a skipped run's record: its earlier run's time
            # compiling is once per worker process, not per unit of work: not in the rate
            compiled = min(_seconds(record.get("compile_s")) or 0.0, run_s)
            self.seconds[key] = self.seconds.get(key, 0.0) + run_s - compiled
            self.timed_work[key] = self.timed_work.get(key, 0.0) + work
        if skipped:
            self.work_skipped += work
        else:
            self.work_done += work
            self.busy += run_s or 0.0
        elapsed = time.perf_counter() - self.t0
        eta = self.eta()
        state = "skip" if skipped else str(record.get("status", "?"))
        bad = not skipped and record.get("status") not in ("completed", None)
        if self.bar is not None:
            share = (self.work_done + self.work_skipped) / self.total_work
            self.bar.set_description_str(f"{100 * min(1.0, share):3.0f}% of the work", False)
            self.bar.set_postfix_str(f"{_clock(elapsed)} elapsed, ETA "
                                     f"{_clock(eta) if eta is not None else '?'} | "
                                     f"{state} {short_label(record, 40)}", False)
            if bad:
                self.bar.write(f"{state}: {record['run_id']}: {record.get('reason', '')}",
                               file=self.stream)
            self.bar.update(1)
            return
        took = "" if skipped else f" {record.get('wall_time_s', 0):.1f}s"
        left = f" eta {_clock(eta)}" if eta is not None and done < total else ""
        print(f"[{done}/{total} {elapsed:6.0f}s{left}] {state:<9} {record['run_id']}{took}",
              file=self.stream, flush=True)
        if bad:
            print(f"    reason: {record.get('reason', '')}", file=self.stream, flush=True)

    def running(self, live: Sequence[LiveRun]) -> None:
        """Draw one bar per run in progress (a terminal only; at most 4 times a second)."""
        if self.bar is None:
            return
        now = time.perf_counter()
        if now - self._drawn < 0.25:
            return
        self._drawn = now
        from tqdm import tqdm

        while len(self.run_bars) < len(live):
            self.run_bars.append(tqdm(total=1000, file=self.stream, position=len(self.run_bars) + 1,
                                      leave=False, ncols=self.cols, nrows=self.rows, unit="",
                                      bar_format="  {desc} {bar} {unit}"))
        width = max(20, min(48, self.cols // 2 - 10))
        for k, bar in enumerate(self.run_bars):
            if k < len(live):
                desc, n, post = run_line(live[k], width)
            else:
                desc, n, post = "", 0, "idle"
            bar.n = n
            bar.set_description_str(desc, False)
            bar.unit = post  # shown through {unit}: a postfix would get a ", " in front
            bar.refresh()

    def close(self) -> None:
        for bar in self.run_bars:
            bar.close()
        self.run_bars = []
        if self.bar is not None:
            self.bar.close()


def values_label(task: Task, width: int = 36) -> str:
    """A run's case and the values of its id's parameters (``dam-break lobovsky wc-mps
    0.0125``): the run ids under one case share their names, so the values tell them apart."""
    head = f"{task.case}_{task.solver}_"
    rid = task.run_id
    body = rid[len(head):] if rid.startswith(head) else rid
    body = body.rsplit("_", 1)[0] if "_" in body else ""
    # the parameters the id names (those off their defaults), in the id's order; names are
    # looked up in the task's parameters because a name or a value may itself contain "_"
    named = sorted((pos, k) for k in task.params
                   for pos in [("_" + body).find(f"_{k}=")] if pos >= 0)
    values = [_plain_value(k, task.params[k]) for _, k in named]
    label = " ".join([task.case, *values]) if values else f"{task.case} (defaults)"
    return label if len(label) <= width else label[: width - 3] + "..."


def _plain_value(name: str, v: Any) -> str:
    if isinstance(v, bool):  # "True" alone would not say what is on
        return name if v else f"no {name}"
    return f"{v:g}" if isinstance(v, float) else str(v)


def run_line(run: LiveRun, width: int = 36) -> tuple[str, int, str]:
    """A run in progress as (label, bar position out of 1000, what it has reached)."""
    label = values_label(run.task, width).ljust(width)
    frac = run.fraction
    if run.t is None:
        return label, 0, f"setting up, {_clock(run.elapsed_s)}"
    reached = (f"t {run.t:.3g}/{run.t_end:.3g} s" if frac is not None else f"t {run.t:.3g} s")
    return (label, int(1000 * frac) if frac is not None else 0,
            f"{reached}, step {run.steps}, {_clock(run.elapsed_s)}")
