"""Progress of a sweep on the terminal (``mpsbench validate``): how far, and how long is left.

The work of a run is its estimated cost, particles x time steps from ``Case.estimate``
(:mod:`mpsbench.run.estimate`; a run without an estimate counts as the mean of those with one,
or 1 when none has), so the ETA follows the work done rather than the run count: a tier's many
short runs and few long ones no longer make the count say nothing (issue 18).

Three modes:

* on a terminal (a TTY), an overall bar drawn with tqdm: runs done / planned, the share of the
  estimated work done, elapsed time and ETA, the last finished run's short label; a run that
  did not complete is printed above the bar with its reason;
* otherwise (a log, CI) plain lines, one per finished run: ``[done/total elapsed eta] status
  run_id wall`` (and the reason of a run that did not complete);
* ``quiet``: nothing per run (the verdicts at the end are printed as always); ``verbose``:
  the plain lines even on a terminal.

Not yet: one bar per run in progress (its simulated time against t_end) needs each worker
process to report (time, steps) to the parent while it runs; the supervised workers of issue
16 carry such reports, and the bars belong on them.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

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
        self.t0 = time.perf_counter()
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.mode = mode if mode in ("quiet", "verbose") else ("bar" if tty else "plain")
        self.bar: Any = None
        if self.mode == "bar":
            import shutil

            from tqdm import tqdm

            cols = shutil.get_terminal_size((100, 24)).columns or 100  # 0 on some ptys
            self.bar = tqdm(total=len(tasks), file=self.stream, unit="run", ncols=cols,
                            bar_format="{desc} {bar} {n_fmt}/{total_fmt} runs{postfix}")

    def eta(self) -> float | None:
        """Seconds left at the rate of the work done so far (None before any run finished)."""
        elapsed = time.perf_counter() - self.t0
        if self.work_done <= 0:
            return None
        left = self.total_work - self.work_done - self.work_skipped
        return max(0.0, left) * elapsed / self.work_done

    def __call__(self, done: int, total: int, record: dict[str, Any], skipped: bool) -> None:
        if self.mode == "quiet":
            return
        work = self.costs.get(str(record.get("run_id")), 0.0)
        if skipped:
            self.work_skipped += work
        else:
            self.work_done += work
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

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
