"""Executors: local and dask give the same records; skip-if-done; failures; kill -9 and resume.

Uses the ``study-toy`` case of ``tests/test_studyfile.py`` (no solver, a formula per run).  The
dask tests start a ``LocalCluster`` of 2 worker processes and register the toy case on them.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mpsbench.results.executors import DaskExecutor, LocalExecutor, make_executor, run_detached
from mpsbench.results.records import environment, load_record, load_records
from mpsbench.results.study_spec import parse_study
from mpsbench.results.sweep import run_tasks
from tests.test_studyfile import TOY, register_toy, toy_case  # noqa: F401 - fixture

ROOT = Path(__file__).resolve().parents[1]

# columns that differ between two executions of the same run (timings, machine)
VOLATILE = {"wall_time_s", "particle_steps_per_s", "elapsed_s", "machine"}


def toy_tasks(**grid: Any) -> list[Any]:
    table = {"case": TOY, "tier": "smoke",
             "grid": grid or {"laplacian": ["xu-jin", "koshizuka-oka"], "re_ratio": [2.1, 3.1]}}
    return parse_study(table, "toy").tasks()


def stable(rec: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in rec.items() if k not in VOLATILE}


def test_local_executor_inline_and_pool_agree(tmp_path: Path) -> None:
    tasks = toy_tasks()
    assert len(tasks) == 8
    one = run_tasks(tasks, tmp_path / "one", executor=LocalExecutor(1))
    two = run_tasks(tasks, tmp_path / "two", executor=LocalExecutor(2))
    assert [stable(r) for r in one] == [stable(r) for r in two]
    assert all(r["status"] == "completed" for r in one)
    # the same as the default path of run_tasks (no executor)
    plain = run_tasks(tasks, tmp_path / "plain", jobs=2)
    assert [stable(r) for r in plain] == [stable(r) for r in one]


def test_executor_skips_done_runs_and_records_failures(tmp_path: Path) -> None:
    tasks = toy_tasks(explode=[False, True], weight=["wf1"])
    seen: list[tuple[str, bool]] = []
    recs = run_tasks(tasks, tmp_path, executor=LocalExecutor(2),
                     progress=lambda d, n, r, skipped: seen.append((r["status"], skipped)))
    assert sorted(r["status"] for r in recs) == ["completed", "failed"]
    assert "RuntimeError: boom" in next(r for r in recs if r["status"] == "failed")["reason"]
    seen.clear()
    run_tasks(tasks, tmp_path, executor=LocalExecutor(2),
              progress=lambda d, n, r, skipped: seen.append((r["status"], skipped)))
    assert sorted(seen) == [("completed", True), ("failed", True)]
    # retry re-runs only what it selects
    seen.clear()
    run_tasks(tasks, tmp_path, executor=LocalExecutor(1),
              retry=lambda rec: rec["status"] == "failed",
              progress=lambda d, n, r, skipped: seen.append((r["status"], skipped)))
    assert sorted(seen) == [("completed", True), ("failed", False)]


def test_run_detached_returns_the_record_text(tmp_path: Path) -> None:
    (task,) = toy_tasks(weight=["wf1"], laplacian=["xu-jin"])
    text, npz = run_detached(task, environment())
    rec = json.loads(text)
    assert rec["run_id"] == task.run_id and rec["status"] == "completed" and npz is None


def test_make_executor_rejects_bad_names() -> None:
    with pytest.raises(ValueError, match="one of local, dask"):
        make_executor("ray")
    with pytest.raises(ValueError, match="only goes with the dask executor"):
        make_executor("local", scheduler="tcp://127.0.0.1:1")
    with pytest.raises(ValueError, match="jobs = 0"):
        LocalExecutor(0)


# --------------------------------------------------------------------------- dask


@pytest.fixture(scope="module")
def dask_client() -> Iterator[Any]:
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=":0")
    client = distributed.Client(cluster)
    try:
        assert len(client.scheduler_info()["workers"]) == 2
        # on every worker, also on those the nanny restarts after a worker died
        client.register_plugin(_ToyPlugin())
        yield client
    finally:
        client.close()
        cluster.close()


try:
    from distributed import WorkerPlugin as _PluginBase
except ImportError:  # the dask tests skip; the class below is then never used
    _PluginBase = object  # type: ignore[assignment,misc]


class _ToyPlugin(_PluginBase):
    """A dask worker plugin registering the toy case on each worker."""

    name = "mpsbench-study-toy"

    def setup(self, worker: Any) -> None:
        if str(ROOT) not in sys.path:
            sys.path.insert(0, str(ROOT))
        from tests.test_studyfile import register_toy as reg

        reg()

    def teardown(self, worker: Any) -> None:
        pass


def test_dask_and_local_records_match_run_for_run(tmp_path: Path, dask_client: Any) -> None:
    tasks = toy_tasks(laplacian=["koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic"],
                      weight=["wf1", "wf2"], re_ratio=[2.1, 3.1, 4.0])
    local = run_tasks(tasks, tmp_path / "local", executor=LocalExecutor(2))
    with DaskExecutor(dask_client) as ex:
        remote = run_tasks(tasks, tmp_path / "dask", executor=ex)
    assert len(local) == len(remote) == 24
    assert [stable(r) for r in local] == [stable(r) for r in remote]
    # and on disk: the same files, every one parses
    for sub in ("local", "dask"):
        assert len(load_records(tmp_path / sub)) == 24
    names = sorted(p.name for p in (tmp_path / "dask" / "runs").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "local" / "runs").iterdir())


def test_dask_skip_if_done_and_failures(tmp_path: Path, dask_client: Any) -> None:
    tasks = toy_tasks(explode=[False, True], weight=["wf1", "wf2"])
    seen: list[tuple[str, bool]] = []

    def progress(d: int, n: int, r: dict[str, Any], skipped: bool) -> None:
        seen.append((r["status"], skipped))

    # half done by the local executor first
    run_tasks(tasks[:2], tmp_path, executor=LocalExecutor(1))
    with DaskExecutor(dask_client) as ex:
        recs = run_tasks(tasks, tmp_path, executor=ex, progress=progress)
    assert sorted(seen) == sorted([(recs[0]["status"], True), (recs[1]["status"], True),
                                   (recs[2]["status"], False), (recs[3]["status"], False)])
    assert sorted(r["status"] for r in recs) == ["completed", "completed", "failed", "failed"]
    assert all("RuntimeError: boom" in r["reason"] for r in recs if r["status"] == "failed")


def test_dask_unknown_case_fails_only_its_run(tmp_path: Path, dask_client: Any) -> None:
    from mpsbench.results.records import Task

    good = toy_tasks(weight=["wf1"], laplacian=["xu-jin"])
    unknown = Task("no-such-case", "reference", "smoke", {}, "unknown")
    with DaskExecutor(dask_client) as ex:
        recs = run_tasks(good + [unknown], tmp_path, executor=ex)
    assert recs[0]["status"] == "completed"
    assert recs[1]["status"] == "failed" and "no-such-case" in recs[1]["reason"]


def test_dask_worker_death_crashes_only_its_run(tmp_path: Path, dask_client: Any) -> None:
    tasks = toy_tasks(die=[False, True], weight=["wf1"])
    with DaskExecutor(dask_client) as ex:
        recs = run_tasks(tasks, tmp_path, executor=ex)
    by_die = {r["die"]: r for r in recs}
    assert by_die[False]["status"] == "completed"
    assert by_die[True]["status"] == "crashed"
    assert "worker process died" in by_die[True]["reason"]
    assert load_record(tmp_path / "runs" / f"{by_die[True]['run_id']}.json") is not None
    dask_client.wait_for_workers(2, timeout=60)  # the cluster recovers


def test_dask_scratch_folders_live_in_the_worker_directory(dask_client: Any) -> None:
    """A worker killed mid-run cannot remove its scratch folder: it is made inside the worker's
    own directory, which dask removes with the dead worker (before: /tmp/mpsbench-run-* left
    behind, five per run of this file)."""
    from mpsbench.results.executors import _worker_directory

    assert _worker_directory() is None  # not in a worker: the system's temp folder
    where = dask_client.submit(_worker_directory, pure=False).result()
    assert where is not None and Path(where).is_dir()
    assert Path(where).resolve() != Path(tempfile.gettempdir()).resolve()


def test_dask_executor_local_cluster_of_its_own(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    tasks = toy_tasks(weight=["wf1"], laplacian=["xu-jin"])
    # the toy case is in-process only: this cluster's workers cannot see it -> failed record,
    # which is the point: the run is recorded with the reason, nothing crashes
    with DaskExecutor(n_workers=1) as ex:
        assert "local cluster, 1 worker" in ex.describe()
        (rec,) = run_tasks(tasks, tmp_path, executor=ex)
    assert rec["status"] == "failed" and "study-toy" in rec["reason"]
    assert load_record(tmp_path / "runs" / f"{rec['run_id']}.json") == rec


# --------------------------------------------------------------------------- kill -9


RUNNER = (
    "import sys; sys.path.insert(0, {root!r}); "
    "from tests.test_studyfile import register_toy; register_toy(); "
    "from mpsbench.cli import main; sys.exit(main(sys.argv[1:]))"
)


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize(
    ("jobs", "sig", "group"),
    [(1, signal.SIGKILL, True), (2, signal.SIGKILL, True), (2, signal.SIGKILL, False),
     (2, signal.SIGINT, True)],
    ids=["kill-9-inline", "kill-9-pool", "kill-9-main-process-only", "ctrl-c-pool"],
)
def test_interrupt_then_resume(
    tmp_path: Path, jobs: int, sig: signal.Signals, group: bool
) -> None:
    """Kill (or Ctrl-C) a running study once some records exist; the rerun completes the grid.

    SIGKILL goes to the whole process group (the study and its workers, as when a job
    scheduler ends it) or to the study process only (its workers must not live on, nor keep
    the output folder locked); SIGINT to the group, as a terminal's Ctrl-C does.
    """
    study = tmp_path / "kill.toml"
    study.write_text(
        f'case = "{TOY}"\ntier = "smoke"\n[params]\nsleep = 0.15\n'
        '[grid]\nre_ratio = [1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0]\n'
    )
    n_grid = 20  # 10 radii x 2 weights (the smoke tier's grid)
    out = tmp_path / "out"
    cmd = [sys.executable, "-c", RUNNER.format(root=str(ROOT)), "study", "run", str(study),
           "--out", str(out), "--jobs", str(jobs), "--no-report"]
    # A shell without job control starts background jobs with SIGINT ignored, and an ignored
    # signal stays ignored across exec: under such a CI runner the study would never see the
    # Ctrl-C (it ran to the end and exited 0).  A terminal's Ctrl-C is what is tested here, so
    # the study starts with the default disposition, as in a terminal.
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True, preexec_fn=_default_sigint)
    runs = out / TOY / "runs"
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline:
            if runs.is_dir() and len(list(runs.glob("*.json"))) >= 5:
                break
            assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
            time.sleep(0.02)
        else:
            pytest.fail("the study wrote no records in 60 s")
    finally:
        t_signal = time.monotonic()
        if group:
            os.killpg(proc.pid, sig)
        else:
            os.kill(proc.pid, sig)
        try:
            proc.wait(timeout=30)
        finally:
            with contextlib.suppress(ProcessLookupError):  # anything left of this test's group
                os.killpg(proc.pid, signal.SIGKILL)
    seen = f"exit status {proc.returncode} with {len(list(runs.glob('*.json')))}/{n_grid} records"
    if sig == signal.SIGKILL:
        assert proc.returncode == -signal.SIGKILL, seen
    else:  # Ctrl-C: a prompt exit with status 130, the busy workers stopped
        assert proc.returncode == 130, seen
        assert time.monotonic() - t_signal < 10
    done_before = len(load_records(out / TOY))
    assert 5 <= done_before < n_grid
    if not group and sys.platform.startswith("linux"):
        time.sleep(1.0)  # orphaned workers would write more records meanwhile
        assert len(load_records(out / TOY)) == done_before

    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert again.stderr.count("skip ") >= done_before
    files = sorted(runs.glob("*.json"))
    assert len(files) == n_grid
    for path in files:
        rec = json.loads(path.read_text())  # every record parses
        assert rec["status"] == "completed" and path.stem == rec["run_id"]
    assert len(load_records(out / TOY)) == n_grid
    plan = json.loads((out / "plan.json").read_text())
    assert {r["run_id"] for r in plan["runs"]} == {p.stem for p in files}
    status = subprocess.run(
        [sys.executable, "-m", "mpsbench", "study", "status", str(out), "--json"],
        capture_output=True, text=True, timeout=60,
    )
    st = json.loads(status.stdout)
    assert (st["planned"], st["done"], st["pending"], st["failed"]) == (n_grid, n_grid, 0, 0)


# --------------------------------------------------------------------------- the example study


@pytest.mark.slow
def test_example_study_local_and_dask_records_match(tmp_path: Path) -> None:
    """examples/studies/couette_laplacians.toml with both executors: the same 24 records."""
    pytest.importorskip("distributed")
    pytest.importorskip("mpsbench.validations.couette")
    from mpsbench import cli

    study = str(ROOT / "examples" / "studies" / "couette_laplacians.toml")
    for executor in ("local", "dask"):
        args = ["study", "run", study, "--jobs", "2", "--executor", executor,
                "--out", str(tmp_path / executor), "--no-report"]
        assert cli.main(args) == 0
    local = {r["run_id"]: r for r in load_records(tmp_path / "local" / "couette")}
    remote = {r["run_id"]: r for r in load_records(tmp_path / "dask" / "couette")}
    assert len(local) == 24 and set(local) == set(remote)
    for rid, rec in local.items():
        assert rec["status"] == "completed", rec["reason"]
        assert stable(rec) == stable(remote[rid]), rid


def test_cli_study_on_a_scheduler_address(
    tmp_path: Path, dask_client: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    """--scheduler ADDRESS: the CLI connects to a running cluster (and leaves it running)."""
    from mpsbench import cli

    address = dask_client.scheduler.address
    study = tmp_path / "s.toml"
    study.write_text(f'case = "{TOY}"\ntier = "quick"\n')
    out = tmp_path / "out"
    assert cli.main(["study", "run", str(study), "--scheduler", address, "--out", str(out),
                     "--no-report"]) == 0
    assert f"executor: dask (scheduler {address})" in capsys.readouterr().err
    assert len(load_records(out / TOY)) == 4
    assert len(dask_client.scheduler_info()["workers"]) == 2  # still up


def test_atomic_writes_leave_whole_shareable_files_or_nothing(tmp_path: Path) -> None:
    """Records and arrays (local or from dask) get the same atomic write and file mode."""
    from mpsbench.results.records import _atomic_replace, atomic_write_bytes, atomic_write_text

    mask = os.umask(0)
    os.umask(mask)
    path = tmp_path / "rec.json"
    atomic_write_text(path, '{"a": "\u00e9"}')
    assert path.read_bytes() == '{"a": "\u00e9"}'.encode()
    blob = tmp_path / "run.npz"
    atomic_write_bytes(blob, b"\x00\x01")
    for p in (path, blob):
        assert p.stat().st_mode & 0o777 == 0o666 & ~mask

    def broken(tmp: str) -> None:
        Path(tmp).write_text("half")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        _atomic_replace(path, broken)
    assert path.read_bytes() == '{"a": "\u00e9"}'.encode()  # the old file is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.json", "run.npz"]  # no temp left
