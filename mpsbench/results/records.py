"""Run records: a task, its run id, executing it into a record, atomic writes, loading, and the
environment every record carries.

Output folder layout::

    OUT/runs/<run_id>.json   one record per run (written atomically: temp file + rename)
    OUT/runs/<run_id>.npz    arrays the case keeps for its figures (profiles, snapshots),
                             and the frames of --vtu (mpsbench.results.frames says what it holds)

Failed, diverged, unsupported, timed-out and crashed runs are recorded with their reason (a run
that stopped early also with the simulated time it reached, ``sim_time_s``).  Every record
carries the common columns documented in docs/columns.md.  Sweeps over many tasks are
:mod:`mpsbench.results.sweep`.
"""

from __future__ import annotations

import json
import math
import os
import platform
import re
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mpsbench.cases import get_case
from mpsbench.errors import InputFileError, where
from mpsbench.registry import name_problem
from mpsbench.results.frames import frame_arrays
from mpsbench.results.identity import HASH_COLUMN, run_hash, task_hash
from mpsbench.run.frames import keeping_frames
from mpsbench.run.protocol import Status
from mpsbench.run.runner import ProgressSink, RunLimits, RunResult, task_context
from mpsbench.run.specs import solver_spec

COMMON_COLUMNS = (
    "case", "solver", "solver_options", "solver_version", "tier", "run_id", HASH_COLUMN, "status",
    "reason",
    "wall_time_s", "particle_steps_per_s", "n_particles", "n_steps", "sim_time_s",
)
RECORD_STATUSES = (Status.COMPLETED.value, Status.DIVERGED.value, Status.FAILED.value,
                   Status.UNSUPPORTED.value, Status.TIMED_OUT.value, Status.CRASHED.value)
NOT_RUN = (Status.UNSUPPORTED.value,)
"""Statuses of runs that were not made at all: they never count against a case."""
RUN_ID_CHARS = "letters, digits, '=', '.', '_', '+', '-', starting with a letter or digit"
_RUN_ID_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9=._+-]{0,199}")


def run_id(
    case: str,
    solver: str,
    params: dict[str, Any],
    defaults: dict[str, Any] | None = None,
    always: Iterable[str] = (),
) -> str:
    """A readable, filesystem-safe name built from the parameters (plus a short hash).

    ``solver`` is the canonical solver spec (``numba`` or ``numba:threads=1``): options off
    their defaults are part of the name.  With the case's ``defaults`` (in the case's parameter
    order) the readable part lists the parameters that differ from them or are named in
    ``always`` (those a study sweeps), in that order, so names stay short and say what the run
    varies; the suffix is the start of the run's identity hash (:mod:`mpsbench.results.identity`),
    which covers every parameter.  The name is a label: runs are matched by their hash, not by
    name.
    """
    if defaults is not None:
        keep = set(always)
        order = [k for k in defaults if k in params] + sorted(set(params) - set(defaults))
        shown = [k for k in order if k in keep or k not in defaults or params[k] != defaults[k]]
    else:
        shown = sorted(params)
    parts = [case, solver] + [f"{k}={_short(params[k])}" for k in shown]
    text = "_".join(parts)
    safe = re.sub(r"\.{2,}", "_", re.sub(r"[^A-Za-z0-9=.+-]+", "_", text)).lstrip("._=+-")
    if len(safe) > 150:
        safe = safe[:150]
    return f"{safe or 'run'}_{run_hash(case, solver, params)[:8]}"


def run_ids(
    case: str, solver: str, param_sets: Sequence[dict[str, Any]], defaults: dict[str, Any]
) -> list[str]:
    """Run ids of a set of runs: every parameter the set sweeps is named in each id."""
    swept = {
        k for k in {k for p in param_sets for k in p}
        if len({repr(p.get(k)) for p in param_sets}) > 1
    }
    return [run_id(case, solver, p, defaults, swept) for p in param_sets]


def _short(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


@dataclass
class Task:
    """One planned run.  ``run_hash`` (its identity, see :mod:`.identity`) is computed from
    case, solver and parameters unless given.

    ``max_steps`` / ``max_wall_s`` override the case's default run limits at the tier
    (:meth:`mpsbench.cases.Case.run_limits`; 0 = no limit); they are not part of the identity.
    ``isolate``: run it in a supervised child process even with one job.
    """

    case: str
    solver: str  # the canonical solver spec: NAME or NAME:key=value,... (non-default options)
    tier: str
    params: dict[str, Any]
    run_id: str
    run_hash: str = ""
    max_steps: int | None = None
    max_wall_s: float | None = None
    isolate: bool = False
    # case parameters that do not apply to the solver (it ignores what they set): at their
    # defaults in ``params``, recorded in the ``not_applicable`` column
    not_applicable: tuple[str, ...] = ()
    # an output option, not part of the run's identity: frames to keep for ParaView
    # (validate --vtu; mpsbench.run.frames), stored in runs/<run_id>.npz
    frames: int = 0

    def __post_init__(self) -> None:
        if not self.run_hash:
            self.run_hash = task_hash(self.case, self.solver, self.params)


def task_limits(task: Task) -> RunLimits:
    """The run limits of ``task``: its own where set (0 = none), else the case's default."""
    try:
        default = get_case(task.case).run_limits(task.tier, dict(task.params))
    except Exception:  # noqa: BLE001 - an unknown case fails in execute_task with the reason
        default = RunLimits()
    steps = default.max_steps if task.max_steps is None else (task.max_steps or None)
    wall = default.max_wall_s if task.max_wall_s is None else (task.max_wall_s or None)
    return RunLimits(steps, wall)


def needs_isolation(task: Task) -> bool:
    """Whether ``task`` runs in a supervised child process: asked for, or its solver declares
    ``isolate`` (native code that can crash or hang the process)."""
    if task.isolate:
        return True
    from mpsbench.run.specs import get_solver_class

    try:
        return bool(getattr(get_solver_class(task.solver), "isolate", False))
    except Exception:  # noqa: BLE001 - an unloadable solver fails its run with the reason
        return False


def solver_columns(spec: str) -> dict[str, str]:
    """The record columns of a solver spec: ``solver`` (the name) and ``solver_options``
    (``key=value,...`` of the non-default options, '' for none), kept apart so the name stays
    a plain name wherever a record's solver is used (folders, tables)."""
    name, _, options = spec.partition(":")
    return {"solver": name, "solver_options": options}


def solver_label(record: dict[str, Any]) -> str:
    """The solver spec of a record: ``solver``, with ``:solver_options`` when it has options."""
    name = str(record.get("solver", "?"))
    options = record.get("solver_options") or ""
    return f"{name}:{options}" if options else name


def solver_folder(label: str) -> str:
    """A folder name for a solver spec: the name, then the options with every character that is
    not a letter, digit or ``=.+-`` replaced by ``_`` (``numba:threads=1``: ``numba_threads=1``).
    """
    name, _, options = label.partition(":")
    return f"{name}_{re.sub(r'[^A-Za-z0-9=.+-]+', '_', options)}" if options else name


def canonical_solver(text: str) -> str:
    """The canonical spec of ``text`` (validated against the backend's options)."""
    return solver_spec(text).text


ENV_COLUMNS = (
    "mpsbench_version", "git_commit", "git_dirty", "solver_commit", "python", "numpy_version",
    "scipy_version", "numba_version", "pandas_version", "os", "cpu_model", "cpu_count",
    "cpu_cores", "machine",
)
"""Where and with what a run was made: the last columns of every record (docs/columns.md).
``environment()`` gives all but ``solver_commit``, which :func:`execute_task` adds per record."""


def environment(solvers: Sequence[str] = ()) -> dict[str, Any]:
    """Versions, commits and machine description stored in every record (cached per process).

    With ``solvers`` (for a manifest or a bench), also ``solvers``: each one's
    ``solver_version`` and ``solver_commit``.
    """
    from mpsbench.results import provenance

    env: dict[str, Any] = {
        **provenance.mpsbench_environment(),
        "python": platform.python_version(),
        **dict(provenance.library_versions()),
        **provenance.machine_environment(),
    }
    if solvers:
        env["solvers"] = {s: provenance.solver_provenance(s) for s in solvers}
    return env


def _outcome(results: list[RunResult]) -> tuple[Status, str]:
    """The record's status from its solver runs: the first that did not complete decides; an
    unsupported one wins over the others (the run was not made as asked)."""
    for r in results:
        if r.status == Status.UNSUPPORTED:
            return r.status, r.reason
    for r in results:
        if r.status != Status.COMPLETED:
            return r.status, r.reason
    return Status.COMPLETED, ""


def _run_columns(results: list[RunResult]) -> dict[str, Any]:
    wall = sum(r.wall_time_s for r in results)
    psteps = sum(r.particle_steps for r in results)
    return dict(
        solver_version=next((r.solver_version for r in results if r.solver_version), ""),
        wall_time_s=round(wall, 4),
        particle_steps_per_s=round(psteps / wall, 1) if wall > 0 else 0.0,
        n_particles=max((r.n_particles for r in results), default=0),
        n_steps=sum(r.n_steps for r in results),
        n_solver_runs=len(results),
        sim_time_s=results[-1].time if results else 0.0,
    )


def base_record(task: Task) -> dict[str, Any]:
    """The identity columns every record of ``task`` starts with."""
    return {
        "case": task.case, **solver_columns(task.solver), "solver_version": "",
        "tier": task.tier, "run_id": task.run_id, HASH_COLUMN: task.run_hash, **task.params,
        **({"not_applicable": ",".join(task.not_applicable)} if task.not_applicable else {}),
    }


def execute_task(task: Task, outdir: str, env: dict[str, Any],
                 progress: ProgressSink | None = None,
                 progress_every: float = 0.25) -> dict[str, Any]:
    """Run one task, write its record (and arrays) atomically, return the record.

    Never raises for a failing run: the record says ``failed`` (or ``diverged``,
    ``unsupported``, ``timed-out``) with the reason.  The task's run limits
    (:func:`task_limits`) apply to every solver run of the case; ``progress(t, steps, t_end)`` hears
    how far the current solver run got, at most every ``progress_every`` seconds (a
    supervising process keeps the last report, to say where a run that crashed or never
    returned was stopped).
    """
    runs = Path(outdir) / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    record = base_record(task)
    t0 = time.perf_counter()
    arrays: dict[str, np.ndarray] = {}
    limits = task_limits(task)
    with task_context(limits, progress) as ctx:
        ctx.every_s = progress_every
        try:
            case = get_case(task.case)
            with keeping_frames(task.frames):
                out = case.execute(dict(task.params), task.solver)
            # every solver run of the case, also those it did not return (as a refusal's)
            results = out.results + [r for r in ctx.results if not any(r is o for o in out.results)]
            status, reason = _outcome(results)
            record.update(status=status.value, reason=reason, **_run_columns(results))
            record.update(solver_counters(results))
            if status != Status.UNSUPPORTED:
                record.update({k: _plain(v) for k, v in out.metrics.items()})
                arrays = {**out.arrays, **frame_arrays(results)}
        except Exception as exc:  # noqa: BLE001 - a broken case or solver is recorded, not fatal
            status, reason = _outcome(ctx.results)
            if status in (Status.UNSUPPORTED, Status.TIMED_OUT):
                # the case tripped over the empty or short probes of a refused or stopped run:
                # the refusal (or the limit) is the reason, not the case's error
                record.update(status=status.value, reason=reason, **_run_columns(ctx.results))
            else:
                record.update(
                    status=Status.FAILED.value, reason=f"{type(exc).__name__}: {exc}{where(exc)}",
                    **_run_columns(ctx.results),
                )
                record["wall_time_s"] = round(time.perf_counter() - t0, 4)
                record["particle_steps_per_s"] = 0.0
    record["elapsed_s"] = round(time.perf_counter() - t0, 4)
    record.update(env)
    record["solver_commit"] = _solver_commit(task.solver)
    if arrays:
        _atomic_npz(runs / f"{task.run_id}.npz", arrays)
    atomic_write_text(runs / f"{task.run_id}.json", json.dumps(record, indent=1, default=_plain))
    return record


SOLVER_COUNTER_PREFIX = "linear_"
"""Solver counters whose names start with this are record columns (the semi-implicit
backend's linear solves, docs/columns.md): summed over the record's solver runs, or the largest
when the name ends in ``_max``.  Backends without them add no columns."""
SOLVER_COUNTER_COLUMNS = ("compile_s",)
"""Solver counters that are record columns by their whole name, summed the same way:
``compile_s``, seconds a backend spent compiling code for the run (numba's kernels on a cold
cache, PySPH's generated extension), which the ETA of ``validate`` leaves out of a case's rate."""


def solver_counters(results: Sequence[Any]) -> dict[str, float]:
    """The record columns of the solver counters of ``results`` (:data:`SOLVER_COUNTER_PREFIX`)."""
    out: dict[str, float] = {}
    for r in results:
        for name, value in getattr(r, "counters", {}).items():
            if not (name.startswith(SOLVER_COUNTER_PREFIX) or name in SOLVER_COUNTER_COLUMNS):
                continue
            v = float(value)
            if name.endswith("_max"):
                out[name] = max(out.get(name, v), v)
            else:
                out[name] = out.get(name, 0.0) + v
    return {k: round(v, 6) if k.endswith("_s") else int(v) if "residual" not in k else v
            for k, v in out.items()}


def _solver_commit(solver: str) -> str | None:
    from mpsbench.results.provenance import solver_provenance

    return solver_provenance(solver)["solver_commit"]


def _plain(v: Any) -> Any:
    """A JSON value; a non-finite number becomes null (a record never holds NaN or inf)."""
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else None
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.ndarray):
        return _plain(v.tolist())
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def _file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


_FILE_MODE = _file_mode()


def _atomic_replace(path: Path, fill: Callable[[str], None], suffix: str = ".tmp") -> None:
    """``fill(tmp)`` writes a temp file beside ``path``, which then replaces ``path`` in one
    rename: a reader never sees half a file, and a failed write leaves nothing behind."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    os.close(fd)
    try:
        fill(tmp)
        os.chmod(tmp, _FILE_MODE)  # mkstemp makes 0600; reports are meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically and durably (fsync before the rename)."""

    def fill(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())

    _atomic_replace(path, fill)


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically: see :func:`atomic_write_bytes`."""
    atomic_write_bytes(path, text.encode("utf-8"))


def _atomic_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    # the .npz suffix: savez_compressed appends one to any other file name
    _atomic_replace(path, lambda tmp: np.savez_compressed(tmp, **arrays),  # type: ignore[arg-type]
                    suffix=".npz")


def record_problem(data: Any, path: Path | None = None) -> str | None:
    """Why ``data`` (read from ``path``) is not a usable run record; None when it is.

    Names that become path components (case, solver, run id) must be safe ones
    (:func:`mpsbench.registry.name_problem`), the run id must be the file's name, the status
    one of the recorded ones, and no value may be NaN or infinite (a record stores a missing
    value as null).
    """
    if not isinstance(data, dict):
        return f"not a run record (a JSON {type(data).__name__}, expected an object)"
    missing = [k for k in ("case", "solver", "run_id", "status") if k not in data]
    if missing:
        return f"not a run record: lacks {', '.join(missing)}"
    for key in ("case", "solver"):
        problem = name_problem(data[key])
        if problem is not None:
            return f"{key} = {str(data[key])[:80]!r} is not allowed: {problem}"
    rid = data["run_id"]
    problem = run_id_problem(rid)
    if problem is not None:
        return problem
    if path is not None and path.stem != rid:
        return f"run_id {rid!r} is not the file's name"
    if data["status"] not in RECORD_STATUSES:
        return f"status = {str(data['status'])[:40]!r} is not one of {', '.join(RECORD_STATUSES)}"
    bad = _non_finite(data)
    if bad:
        return f"{bad} is not a finite number (a missing value is stored as null)"
    return None


def run_id_problem(rid: object) -> str | None:
    """Why ``rid`` may not be a run id (it names files under ``runs/``); None when it may."""
    if not isinstance(rid, str) or not _RUN_ID_RE.fullmatch(rid) or ".." in rid:
        return f"run_id = {str(rid)[:80]!r} is not allowed: {RUN_ID_CHARS}, no '..'"
    return None


def _non_finite(value: Any, key: str = "") -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return f"{key} = {value!r}"
    if isinstance(value, dict):
        for k, v in value.items():
            found = _non_finite(v, f"{key}.{k}" if key else str(k))
            if found:
                return found
    if isinstance(value, list):
        for k, v in enumerate(value):
            found = _non_finite(v, f"{key}[{k}]")
            if found:
                return found
    return ""


def read_record(path: Path) -> dict[str, Any]:
    """The record in ``path``; :class:`~mpsbench.errors.InputFileError` naming the file and
    the problem when it is unreadable, truncated or not a valid record."""
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})"
                             ) from None
    except json.JSONDecodeError as exc:
        raise InputFileError(f"{path}: truncated or corrupt JSON ({exc.msg} at line "
                             f"{exc.lineno} column {exc.colno})") from None
    except RecursionError:
        raise InputFileError(f"{path}: JSON nested too deeply") from None
    problem = record_problem(data, path)
    if problem is not None:
        raise InputFileError(f"{path}: {problem}")
    return data


def load_record(path: Path) -> dict[str, Any] | None:
    """A record, or None when the file is missing, unreadable or not a valid record.

    For resuming a sweep only: such a run counts as not done and runs again (its new record
    replaces the broken file).  Reports and comparisons use :func:`read_record` /
    :func:`load_records`, which refuse a broken file instead of dropping it.
    """
    try:
        return read_record(path)
    except InputFileError:
        return None


def load_records(outdir: str | Path) -> list[dict[str, Any]]:
    """Every record of ``outdir/runs/``; InputFileError naming the first broken file (and how
    many more there are) when one is unreadable, truncated or invalid: none is dropped."""
    runs = Path(outdir) / "runs"
    records = []
    broken: list[str] = []
    for path in sorted(runs.glob("*.json")) if runs.is_dir() else []:
        try:
            records.append(read_record(path))
        except InputFileError as exc:
            broken.append(str(exc))
    if broken:
        more = f" (and {len(broken) - 1} more broken record file(s))" if len(broken) > 1 else ""
        raise InputFileError(f"{broken[0]}{more}; fix or delete it (a resumed 'mpsbench "
                             "validate' or 'study run' runs it again)")
    return records


def load_arrays(outdir: str | Path, rid: str) -> dict[str, np.ndarray]:
    """The arrays a run kept for its figures ({} when it kept none); InputFileError when the
    file is there but unreadable or truncated."""
    problem = run_id_problem(rid)
    if problem is not None:
        raise InputFileError(problem)
    path = Path(outdir) / "runs" / f"{rid}.npz"
    if not path.exists():
        return {}
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except Exception as exc:  # noqa: BLE001 - OSError, zipfile.BadZipFile, zlib.error, ...
        raise InputFileError(f"{path}: unreadable arrays: {type(exc).__name__}: {exc}"
                             ) from None


def _crashed(task: Task, exc: BaseException, env: dict[str, Any]) -> dict[str, Any]:
    return stopped_record(task, Status.CRASHED,
                          f"worker process died: {type(exc).__name__}: {exc}", env)


def stopped_record(task: Task, status: Status, reason: str, env: dict[str, Any], *,
                   sim_time_s: float | None = None, n_steps: int = 0, elapsed_s: float = 0.0,
                   signal: str = "") -> dict[str, Any]:
    """The record of a run its process could not record itself: it ``crashed`` (the process
    died, by ``signal`` when known) or was killed ``timed-out`` (a step never returned); the
    time and steps it had reported reaching, when known."""
    rec = {
        **base_record(task), "status": status.value, "reason": reason, "wall_time_s": elapsed_s,
        "particle_steps_per_s": 0.0, "n_particles": 0, "n_steps": n_steps,
        "sim_time_s": sim_time_s, "elapsed_s": round(elapsed_s, 4),
    }
    if signal:
        rec["signal"] = signal
    return {**rec, **env}
