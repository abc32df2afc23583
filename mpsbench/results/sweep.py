"""Sweeps: expand a case's grid into tasks and run every task not done yet, keeping one record
per run (:mod:`mpsbench.results.records`).

A run is done when a record of the same run -- the same identity hash (:mod:`.identity`): case,
solver and full parameter set, whatever the record's file is called -- exists in its folder; it
is skipped unless ``force`` (or ``retry`` says so).  A record file that cannot be read counts as
not done: the run runs again and its new record replaces the broken file.  Failed, diverged,
unsupported, timed-out and crashed runs are recorded with their reason and the sweep goes on.
Runs execute on an executor (:mod:`.executors`): supervised worker processes (``jobs``),
in-process (``jobs=1``) or a dask cluster.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from mpsbench.cases import Case, get_case
from mpsbench.results.executors import Executor, LocalExecutor
from mpsbench.results.identity import record_hash
from mpsbench.results.records import Task, canonical_solver, environment, load_record, run_ids


def plan(
    case: Case, solvers: Sequence[str], tier: str, overrides: dict[str, Sequence[Any]] | None = None
) -> list[Task]:
    """The tasks of a case's tier for each solver spec (``numba``, ``numba:threads=1``).

    For a backend that ignores some settings (``Capabilities.ignores``, e.g. an outside code
    with its own kernels), the case parameters that only set those (``Case.not_applicable``)
    are put back to their defaults and the parameter sets that then coincide run once; the
    tasks carry the names, and the records say they do not apply.
    """
    tasks = []
    sets = case.expand(tier, overrides)
    for solver in dict.fromkeys(canonical_solver(s) for s in solvers):
        tasks += solver_tasks(case, solver, tier, sets)
    return tasks


def solver_tasks(case: Case, solver: str, tier: str, sets: list[dict[str, Any]]) -> list[Task]:
    """The tasks of parameter ``sets`` of ``case`` on one solver (``plan``'s rule, also a
    study file's): settings the backend ignores back at their defaults, each set once."""
    na = tuple(case.not_applicable(_ignored_fields(solver)))
    mine = _collapse(sets, na, case.defaults()) if na else sets
    ids = run_ids(case.name, solver, mine, case.defaults())
    return [Task(case.name, solver, tier, p, rid, not_applicable=na)
            for p, rid in zip(mine, ids, strict=True)]


def _ignored_fields(solver: str) -> set[str]:
    from mpsbench.run.specs import get_solver_class

    caps = getattr(get_solver_class(solver), "capabilities", None)
    return caps.ignored_fields() if caps is not None else set()


def _collapse(sets: list[dict[str, Any]], names: tuple[str, ...],
              defaults: dict[str, Any]) -> list[dict[str, Any]]:
    """``sets`` with ``names`` at their defaults, each distinct set once (first-seen order)."""
    out: dict[tuple[tuple[str, str], ...], dict[str, Any]] = {}
    for params in sets:
        p = {**params, **{k: defaults[k] for k in names if k in params}}
        out.setdefault(tuple(sorted((k, repr(v)) for k, v in p.items())), p)
    return list(out.values())


ProgressFn = Callable[[int, int, dict[str, Any], bool], None]


def print_progress(stream: Any = None) -> ProgressFn:
    """A progress callback printing one line per finished (or skipped) run."""
    stream = stream or sys.stderr
    t0 = time.perf_counter()

    def report(done: int, total: int, record: dict[str, Any], skipped: bool) -> None:
        state = "skip" if skipped else record.get("status", "?")
        took = "" if skipped else f" {record.get('wall_time_s', 0):.1f}s"
        elapsed = time.perf_counter() - t0
        print(f"[{done}/{total} {elapsed:6.0f}s] {state:<9} {record['run_id']}{took}",
              file=stream, flush=True)
        if record.get("status") not in ("completed", None) and not skipped:
            print(f"    reason: {record.get('reason', '')}", file=stream, flush=True)

    return report


def run_tasks(
    tasks: Iterable[Task],
    outdir: str | Path,
    *,
    jobs: int = 1,
    force: bool = False,
    progress: ProgressFn | None = None,
    task_dir: Callable[[Task], str | Path] | None = None,
    executor: Executor | None = None,
    retry: Callable[[dict[str, Any]], bool] | None = None,
) -> list[dict[str, Any]]:
    """Run every task not yet done (all with ``force``); return all records in task order.

    ``task_dir(task)`` picks the folder of each task's ``runs/`` (default ``outdir`` for all);
    ``mpsbench validate all`` uses it to run every case through one pool and one progress count
    while each case keeps its own folder.  ``executor`` (:mod:`mpsbench.results.executors`: local
    processes, a dask cluster) runs the runs; the default is a local one with ``jobs``
    processes (``jobs`` is ignored when an executor is given).  ``retry(record)`` true
    re-runs a run whose record exists (e.g. a failed one).
    """
    tasks = list(tasks)
    outdir = Path(outdir)
    folder: dict[str, Path] = {
        t.run_id: Path(task_dir(t)) if task_dir is not None else outdir for t in tasks
    }
    for path in set(folder.values()) | (set() if task_dir is not None else {outdir}):
        (path / "runs").mkdir(parents=True, exist_ok=True)
    env = environment()
    stored = {path: stored_runs(path) for path in set(folder.values())}
    records: dict[str, dict[str, Any]] = {}
    superseded: dict[str, list[Path]] = {}
    todo: list[Task] = []
    done = 0
    for task in tasks:
        found = stored[folder[task.run_id]].get(task.run_hash, [])
        rec = None if force or not found else found[0][1]
        if rec is not None and retry is not None and retry(rec):
            rec = None
        if rec is not None:
            records[task.run_id] = rec
            done += 1
            if progress:
                progress(done, len(tasks), rec, True)
        else:
            todo.append(task)
            superseded[task.run_id] = [path for path, _ in found]
    if executor is None:
        executor = LocalExecutor(max(1, jobs))
    # a progress display with a ``running`` method gets the runs in progress (:mod:`.live`)
    watch = getattr(progress, "running", None)
    for task, rec in executor.run(todo, lambda t: folder[t.run_id], env, watch=watch):
        records[task.run_id] = rec
        _remove_superseded(superseded.get(task.run_id, []), task.run_id)
        done += 1
        if progress:
            progress(done, len(tasks), rec, False)
    return [records[t.run_id] for t in tasks]


def stored_runs(folder: Path) -> dict[str, list[tuple[Path, dict[str, Any]]]]:
    """The readable records of ``folder/runs/`` by identity hash (several files can hold the
    same run: a folder written before runs were matched by hash)."""
    out: dict[str, list[tuple[Path, dict[str, Any]]]] = {}
    runs = folder / "runs"
    cases: dict[str, Case | None] = {}
    for path in sorted(runs.glob("*.json")) if runs.is_dir() else []:
        rec = load_record(path)
        if rec is None:
            continue  # unreadable: not done, runs again
        name = str(rec["case"])
        if name not in cases:
            try:
                cases[name] = get_case(name)
            except Exception:  # noqa: BLE001 - a case that cannot be loaded: its stored hash
                cases[name] = None
        key = record_hash(rec, cases[name])
        if key is not None:
            out.setdefault(key, []).append((path, rec))
    return out


def _remove_superseded(paths: list[Path], run_id: str) -> None:
    """Remove the records (and arrays) a re-run replaced under another file name."""
    for path in paths:
        if path.stem != run_id:
            path.unlink(missing_ok=True)
            path.with_suffix(".npz").unlink(missing_ok=True)
