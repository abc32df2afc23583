"""Dask for ``mpsbench validate`` (issue 18, item 5): a lost worker is reported and its runs go
to another, a cluster without workers stops the study with a message, and the CLI runs a case
on a scheduler address.  Uses the ``study-toy`` case (a formula and a sleep per run) on a
LocalCluster of 2 worker processes whose nannies restart a killed worker."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.results.executors import DaskExecutor, ExecutorError
from mpsbench.results.sweep import run_tasks
from tests.test_executors import _ToyPlugin, toy_tasks
from tests.test_studyfile import TOY, toy_case  # noqa: F401 - fixture

distributed = pytest.importorskip("distributed")


@pytest.fixture
def cluster() -> Iterator[Any]:
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as c, distributed.Client(c) as client:
        client.register_plugin(_ToyPlugin())
        yield client


def test_a_killed_worker_is_reported_and_the_study_completes(tmp_path: Path,
                                                             cluster: Any) -> None:
    tasks = toy_tasks(weight=["wf1", "wf2"], re_ratio=[2.1, 3.1], sleep=[3.0])
    lines: list[str] = []

    def kill_a_busy_worker() -> None:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            busy = [w for w, keys in cluster.processing().items() if keys]
            if busy:
                pid = cluster.run(os.getpid, workers=[busy[0]])[busy[0]]
                time.sleep(1.5)  # inside its run's sleep, seen by the watch (polls 4 per s)
                os.kill(pid, signal.SIGKILL)
                return
            time.sleep(0.05)

    killer = threading.Thread(target=kill_a_busy_worker)
    killer.start()
    with DaskExecutor(cluster, worker_wait=30, report=lines.append) as ex:
        recs = run_tasks(tasks, tmp_path, executor=ex)
    killer.join()
    assert [r["status"] for r in recs] == ["completed"] * 4  # its runs ran elsewhere
    lost = [line for line in lines if "lost" in line]
    assert lost and "its run(s) go back to the queue: study-toy" in lost[0], lines
    assert len(list((tmp_path / "runs").glob("*.json"))) == 4


def test_no_worker_for_worker_wait_stops_with_a_message(tmp_path: Path) -> None:
    with distributed.LocalCluster(n_workers=0, processes=True, dashboard_address=":0") as c, \
            distributed.Client(c) as client:
        t0 = time.monotonic()
        with DaskExecutor(client, worker_wait=2.0, report=lambda text: None) as ex, \
                pytest.raises(ExecutorError, match=r"no dask worker for 2 s"):
            run_tasks(toy_tasks(weight=["wf1"]), tmp_path, executor=ex)
        assert time.monotonic() - t0 < 20
        assert not client.processing() or not any(client.processing().values())


def test_validate_on_a_scheduler_address(tmp_path: Path, cluster: Any,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    address = cluster.scheduler.address
    out = tmp_path / "r"
    assert cli.main(["validate", TOY, "--tier", "smoke", "--scheduler", address,
                     "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"executor: dask (scheduler {address})" in err
    assert len(list((out / "runs").glob("*.json"))) == 2
    assert cli.main(["validate", TOY, "--tier", "smoke", "--scheduler", address,
                     "--executor", "local", "--out", str(out)]) == 2
    assert "--scheduler goes with --executor dask" in capsys.readouterr().err
