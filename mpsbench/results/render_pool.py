"""The cases of a results folder rendered side by side, one worker process each.

``mpsbench validate all`` renders its cases after the last run, one after the other: at the
quick tier that took 24-26 s of a 241 s job on two cores (the diffusion case's seven figures
alone 10 s), while the run pool's workers had ended.  :func:`render_cases` gives each case to a
pool of ``processes`` fresh (spawned) processes, the largest case first.  A case renders into
its own folder, so they do not meet; the sections come back in the order given.

A process imports the cases' code afresh (spawn): what it renders with is the code on disk,
so a case's class changed at run time in this process (a test's monkeypatch) is not seen
there; with one process (``--jobs 1``) everything renders here.

Nothing is lost to the pool: a case that cannot be sent to a process (it holds something that
does not pickle) or whose process dies is rendered here instead, and a bug in a case's code
is what :func:`.sections.safe_render_case` makes of it, in the process or here alike.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path
from typing import Any

from mpsbench.cases import Case
from mpsbench.results.sections import CaseSection, safe_render_case

Work = tuple[Case, list[dict[str, Any]], Path]


def render_cases(work: Sequence[Work], processes: int) -> list[CaseSection]:
    """:func:`safe_render_case` of every (case, records, folder), in up to ``processes``
    processes, no more than this machine's CPUs (``--jobs`` may count a cluster's workers);
    1, or a single case: here, in order."""
    processes = min(processes, os.cpu_count() or 1)
    if processes < 2 or len(work) < 2:
        return [safe_render_case(*w) for w in work]
    order = sorted(range(len(work)), key=lambda k: -len(work[k][1]))  # the largest first
    done: dict[int, CaseSection] = {}
    context = multiprocessing.get_context("spawn")  # no fork of a process that ran threads
    with ProcessPoolExecutor(max_workers=min(processes, len(work)), mp_context=context) as pool:
        futures: dict[int, Future[CaseSection]] = {
            k: pool.submit(safe_render_case, *work[k]) for k in order}
        for k in order:
            try:
                done[k] = futures[k].result()
            except Exception:  # noqa: BLE001 - not sent, or its process died: render it here
                done[k] = safe_render_case(*work[k])
    return [done[k] for k in range(len(work))]
