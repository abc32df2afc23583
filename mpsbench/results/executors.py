"""Executors: where the runs of a study execute.

An executor takes the runs that are not done yet and yields ``(task, record)`` as each one
finishes; every record is on disk (written atomically) before it is yielded, so a study that is
interrupted at any point keeps every finished run and loses none.
:func:`mpsbench.results.sweep.run_tasks`
does the skip-if-done bookkeeping and the progress count; the executor only runs.

* :class:`LocalExecutor` -- in-process (``jobs=1``) or a pool of worker processes.
* :class:`DaskExecutor` -- a ``dask.distributed`` cluster: a scheduler address, an existing
  ``Client``, or (neither) a local cluster started for the study and closed after it.  Workers
  compute; the client writes the records, so the workers need no access to the output folder
  (a remote cluster works), only the same mpsbench (and plugins) installed.

A run that raises inside the case is recorded ``failed`` by
:func:`mpsbench.results.records.execute_task`
itself; a worker that dies (a segfault, killed, out of memory) makes only its own run
``crashed``, with the signal; a local worker whose step never returns is killed past the run's
wall-clock limit and its run recorded ``timed-out`` (:mod:`.supervise`).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from mpsbench.errors import MpsbenchError
from mpsbench.results.live import LiveRun, WatchFn
from mpsbench.results.records import (
    Task,
    _crashed,
    atomic_write_bytes,
    atomic_write_text,
    execute_task,
    needs_isolation,
)
from mpsbench.results.supervise import run_supervised

FolderFn = Callable[[Task], Path]
"""Maps a task to the folder whose ``runs/`` receives its record."""

EXECUTORS = ("local", "dask")


class ExecutorError(MpsbenchError, RuntimeError):
    """An executor could not be started (missing extra, unreachable scheduler)."""


class Executor:
    """Base class: run tasks, write their records, yield ``(task, record)`` as each finishes."""

    name = "base"

    def run(
        self, tasks: Sequence[Task], folder: FolderFn, env: dict[str, Any],
        watch: WatchFn | None = None,
    ) -> Iterator[tuple[Task, dict[str, Any]]]:
        """``watch``, where the executor can see its runs' state, hears the runs in progress
        every fraction of a second (:mod:`.live`); an executor that cannot ignores it."""
        raise NotImplementedError

    def describe(self) -> str:
        return self.name

    def close(self) -> None:
        """Release workers or connections (the executor can't be used after)."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _write_crash(
    task: Task, folder: FolderFn, exc: BaseException, env: dict[str, Any]
) -> dict[str, Any]:
    rec = _crashed(task, exc, env)
    runs = Path(folder(task)) / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    atomic_write_text(runs / f"{task.run_id}.json", json.dumps(rec, indent=1))
    return rec


class LocalExecutor(Executor):
    """Runs in this process (``jobs=1``) or on ``jobs`` supervised worker processes on this
    machine (:mod:`.supervise`: a crash or a hang costs only its own run).

    With one job, the runs go to one supervised worker process instead when ``isolate`` is set
    or a run's solver declares ``isolate`` (:func:`mpsbench.results.records.needs_isolation`).
    In this process the run limits are checked between steps only: a step that never returns
    can only be stopped in a worker process.
    """

    name = "local"

    def __init__(self, jobs: int = 1, *, isolate: bool = False) -> None:
        if not isinstance(jobs, int) or isinstance(jobs, bool) or jobs < 1:
            raise ValueError(f"LocalExecutor: jobs = {jobs!r} is not allowed: an integer >= 1")
        self.jobs = jobs
        self.isolate = isolate

    def describe(self) -> str:
        return f"local ({self.jobs} process{'es' if self.jobs > 1 else ''})"

    def run(
        self, tasks: Sequence[Task], folder: FolderFn, env: dict[str, Any],
        watch: WatchFn | None = None,
    ) -> Iterator[tuple[Task, dict[str, Any]]]:
        if not tasks:
            return
        inline = self.jobs <= 1 and not self.isolate and not any(
            needs_isolation(t) for t in tasks)
        if inline:
            for task in tasks:
                yield task, execute_task(task, str(folder(task)), env,
                                         progress=_inline_watch(task, watch),
                                         progress_every=0.5)
            return
        # Each worker runs single-threaded numerics; the workers give the parallelism.
        yield from run_supervised(tasks, folder, env, self.jobs, watch)


def _inline_watch(task: Task, watch: WatchFn | None) -> Callable[[float, int, float], None] | None:
    """The runner's progress sink of a run in this process, passed on to ``watch``."""
    if watch is None:
        return None
    started = time.monotonic()

    def sink(t: float, steps: int, t_end: float) -> None:
        watch([LiveRun(task, t, steps, t_end, time.monotonic() - started)])

    return sink


# --------------------------------------------------------------------------- dask


def run_detached(task: Task, env: dict[str, Any]) -> tuple[str, bytes | None]:
    """Run one task in a scratch folder; return the record's JSON text and the arrays (.npz).

    This is what a dask worker executes: it never touches the study's output folder.  The
    record text is exactly what :func:`~mpsbench.results.records.execute_task` writes, so the client
    stores byte-for-byte the same record as the local executor would.
    """
    from mpsbench.results.provenance import machine_environment

    env = {**env, **machine_environment()}  # the worker's machine, not the client's
    scratch = tempfile.mkdtemp(prefix="mpsbench-run-", dir=_worker_directory())
    try:
        execute_task(task, scratch, env)
        runs = Path(scratch) / "runs"
        text = (runs / f"{task.run_id}.json").read_text()
        npz = runs / f"{task.run_id}.npz"
        return text, (npz.read_bytes() if npz.exists() else None)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _worker_directory() -> str | None:
    """The dask worker's own local directory (None outside a worker: the system's temp).

    A worker killed in the middle of a run never reaches the ``finally`` that removes its
    scratch folder; inside the worker's directory the folder goes with it (dask removes the
    directories of dead workers when the next one starts on that machine)."""
    try:
        from distributed import get_worker

        return str(get_worker().local_directory)
    except (ImportError, ValueError, AttributeError):
        return None


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ExecutorError(
            "the dask executor needs dask.distributed: pip install 'mpsbench[dask]'"
        ) from None
    return distributed


class DaskExecutor(Executor):
    """Sends every run to a ``dask.distributed`` cluster; the client writes the records.

    ``address``: a scheduler address (``tcp://host:8786``), an existing ``distributed.Client``,
    or None for a local cluster of ``n_workers`` single-threaded worker processes (default: the
    number of CPUs) started on first use and closed by :meth:`close`.  ``retries`` re-submits a
    run whose worker died before its run is recorded ``failed``.
    """

    name = "dask"

    def __init__(
        self,
        address: Any = None,
        *,
        n_workers: int | None = None,
        retries: int = 0,
        cluster_kwargs: dict[str, Any] | None = None,
        worker_wait: float = 120.0,
        report: Callable[[str], None] | None = None,
    ) -> None:
        _import_distributed()
        if n_workers is not None and (not isinstance(n_workers, int) or n_workers < 1):
            raise ValueError(f"DaskExecutor: n_workers = {n_workers!r}: an integer >= 1")
        self.address = address
        self.n_workers = n_workers
        self.retries = retries
        self.cluster_kwargs = cluster_kwargs or {}
        self.worker_wait = worker_wait
        self.report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self._client: Any = None
        self._cluster: Any = None
        self._own_client = False

    def describe(self) -> str:
        if self.address is None:
            n = self.n_workers or os.cpu_count() or 1
            return f"dask (local cluster, {n} worker{'s' if n > 1 else ''})"
        if isinstance(self.address, str):
            return f"dask (scheduler {self.address})"
        return "dask (given client)"

    @property
    def client(self) -> Any:
        if self._client is None:
            distributed = _import_distributed()
            if self.address is None:
                kwargs = {
                    "n_workers": self.n_workers or os.cpu_count() or 1,
                    "threads_per_worker": 1,
                    "processes": True,
                    "dashboard_address": ":0",
                    **self.cluster_kwargs,
                }
                self._cluster = distributed.LocalCluster(**kwargs)
                self._client = distributed.Client(self._cluster)
                self._own_client = True
            elif isinstance(self.address, str):
                try:
                    self._client = distributed.Client(self.address, timeout="20s")
                except OSError as exc:
                    raise ExecutorError(
                        f"cannot reach the dask scheduler at {self.address!r}: {exc}"
                    ) from None
                self._own_client = True
            else:
                self._client = self.address
        return self._client

    def run(
        self, tasks: Sequence[Task], folder: FolderFn, env: dict[str, Any],
        watch: WatchFn | None = None,
    ) -> Iterator[tuple[Task, dict[str, Any]]]:
        # ``watch`` is not called: dask workers do not report a run before it finishes
        if not tasks:
            return
        distributed = _import_distributed()
        client = self.client
        futures = {
            client.submit(
                run_detached, task, env, pure=False, retries=self.retries,
                key=f"mpsbench-{task.run_id}-{os.urandom(4).hex()}",
            ): task
            for task in tasks
        }
        workers = _WorkerWatch(client, self.worker_wait, self.report, self.describe())
        try:
            for fut in workers.as_completed(distributed, futures):
                task = futures.pop(fut)
                try:
                    text, npz = fut.result()
                except Exception as exc:  # noqa: BLE001 - KilledWorker, lost worker, ...
                    yield task, _write_crash(task, folder, exc, env)
                    continue
                runs = Path(folder(task)) / "runs"
                runs.mkdir(parents=True, exist_ok=True)
                if npz is not None:
                    atomic_write_bytes(runs / f"{task.run_id}.npz", npz)
                atomic_write_text(runs / f"{task.run_id}.json", text)
                yield task, json.loads(text)
        finally:
            if futures:  # interrupted: do not leave runs queued on a shared cluster
                client.cancel(list(futures))

    def close(self) -> None:
        if self._client is not None and self._own_client:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None


class _WorkerWatch:
    """Waits for a dask study's runs while watching the cluster's workers (issue 18).

    A worker that leaves is reported with the runs it was processing; the scheduler gives them
    to another worker (after ``distributed.scheduler.allowed-failures`` deaths of the same run
    it gives up, and the run is recorded ``failed``).  With no worker at all for
    ``worker_wait`` seconds the study stops with an :class:`ExecutorError` saying so (the runs
    not done yet are cancelled; running the study again resumes them).
    """

    def __init__(self, client: Any, worker_wait: float, report: Callable[[str], None],
                 where: str) -> None:
        self.client, self.worker_wait, self.report, self.where = client, worker_wait, report, where
        self.processing: dict[str, list[str]] = {}
        self.workers: set[str] = set(self._info())
        self.none_since: float | None = None
        self.poll_s = 0.25  # how often the workers are looked at while runs go on

    def _info(self) -> dict[str, Any]:
        return dict(self.client.scheduler_info().get("workers", {}))

    def as_completed(self, distributed: Any, futures: dict[Any, Task]) -> Iterator[Any]:
        import time

        names = {f.key: t.run_id for f, t in futures.items()}
        pending = set(futures)
        while pending:
            try:
                done, _ = distributed.wait(list(pending), timeout=self.poll_s,
                                           return_when="FIRST_COMPLETED")
            except (TimeoutError, getattr(distributed, "TimeoutError", TimeoutError)):
                done = set()
            self.check(names, time.monotonic())
            for fut in done:
                pending.discard(fut)
                yield fut

    def check(self, names: dict[str, str], now: float) -> None:
        workers = set(self._info())
        for gone in sorted(self.workers - workers):
            runs = [names[k] for k in self.processing.get(gone, []) if k in names]
            self.report(f"dask: worker {gone} lost; "
                        + (f"its run(s) go back to the queue: {', '.join(runs)}" if runs
                           else "no run of this study was seen on it"))
        for new in sorted(workers - self.workers):
            self.report(f"dask: worker {new} joined")
        self.workers = workers
        if workers:
            self.none_since = None
            self.processing = {w: [str(k) for k in keys]
                               for w, keys in self.client.processing().items()}
            return
        self.none_since = self.none_since if self.none_since is not None else now
        if now - self.none_since >= self.worker_wait:
            raise ExecutorError(
                f"no dask worker for {self.worker_wait:g} s ({self.where}): start workers "
                "('dask worker ADDRESS'), or run with --executor local; the runs not done "
                "yet run when the study is run again")


def make_executor(
    name: str, *, jobs: int = 1, scheduler: str | None = None, isolate: bool = False,
    worker_wait: float = 120.0,
) -> Executor:
    """An executor by name: ``local`` (``jobs`` processes; ``isolate``: child processes even
    with one job) or ``dask`` (``scheduler`` address, or a local cluster of ``jobs`` workers
    when none is given; every run is in a worker process there; ``worker_wait``: seconds
    without any worker before the study stops)."""
    if name == "local":
        if scheduler:
            raise ValueError("a scheduler address only goes with the dask executor")
        return LocalExecutor(jobs, isolate=isolate)
    if name == "dask":
        return DaskExecutor(scheduler, n_workers=jobs if scheduler is None else None,
                            worker_wait=worker_wait)
    raise ValueError(f"executor = {name!r} is not allowed: one of {', '.join(EXECUTORS)}")
