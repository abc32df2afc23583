"""Progress of ``mpsbench validate`` (issue 18, item 3): the work-weighted ETA, plain lines off
a terminal, a bar on one, --quiet."""

from __future__ import annotations

import io
import math
from collections.abc import Iterator
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.results.executors import LocalExecutor
from mpsbench.results.live import LiveRun
from mpsbench.results.progress import Progress, short_label, task_costs, values_label
from mpsbench.results.records import Task
from mpsbench.results.sweep import plan, run_tasks
from mpsbench.run.estimate import RunEstimate
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases


class Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture
def toys() -> Iterator[tuple[ToyDiffusion, ToyCounter]]:
    diffusion, counter = ToyDiffusion(), ToyCounter()
    with only_cases(diffusion, counter):
        yield diffusion, counter


def _tasks(n: int) -> list[Task]:
    return [Task("toy-diffusion", "reference", "smoke", {"n_side": 8 * (k + 1)}, f"r{k}",
                 run_hash=f"h{k}") for k in range(n)]


def _record(k: int, status: str = "completed") -> dict[str, Any]:
    return {"run_id": f"r{k}", "case": "toy-diffusion", "solver": "reference",
            "status": status, "wall_time_s": 1.0, "reason": "NaN at step 3"}


def test_costs_come_from_the_case_estimate(toys: tuple[ToyDiffusion, ToyCounter],
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    def estimate(self: Any, params: dict[str, Any]) -> RunEstimate | None:
        n = params["n_side"]
        return None if n == 24 else RunEstimate(particles=n * n, pairs=0, steps=10)

    monkeypatch.setattr(ToyDiffusion, "estimate", estimate)
    costs = task_costs(_tasks(3))
    assert costs["r0"] == 640 and costs["r1"] == 2560
    assert costs["r2"] == (640 + 2560) / 2  # no estimate: the mean of the others


def test_eta_follows_the_work_not_the_run_count(toys: object,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    now = [0.0]
    monkeypatch.setattr("mpsbench.results.progress.time.perf_counter", lambda: now[0])
    stream = io.StringIO()
    p = Progress(_tasks(2), stream=stream)
    p.costs, p.total_work = {"r0": 1.0, "r1": 9.0}, 10.0
    now[0] = 10.0
    p(1, 2, _record(0), False)  # a tenth of the work in 10 s: 90 s left, not 10
    assert p.eta() == pytest.approx(90.0)
    line = stream.getvalue()
    assert line.startswith("[1/2     10s eta 1:30] completed r0 1.0s")


def test_eta_prices_each_case_at_its_own_measured_rate(
        toys: object, monkeypatch: pytest.MonkeyPatch) -> None:
    now = [0.0]
    monkeypatch.setattr("mpsbench.results.progress.time.perf_counter", lambda: now[0])
    tasks = [Task(case, "reference", "quick", {"k": k}, f"{case}{k}")
             for case in ("cheap", "dear") for k in range(3)]
    p = Progress(tasks, stream=io.StringIO())
    p.costs = {t.run_id: 100.0 for t in tasks}  # the same estimated work for every run
    p.total_work = 600.0
    now[0] = 10.0
    # two runs at once: 20 s of run time in 10 s; a cheap run took 1 s, a dear one 19 s
    p(1, 6, {"run_id": "cheap0", "case": "cheap", "status": "completed", "elapsed_s": 1.0,
             "wall_time_s": 0.5}, False)
    p(2, 6, {"run_id": "dear0", "case": "dear", "status": "completed", "elapsed_s": 19.0},
      False)
    # left: 2 cheap runs (2 s) and 2 dear ones (38 s) over 2 workers: 20 s; the old pricing
    # (elapsed time per unit of work done, one rate for all) said 20 s too, but only by luck
    # of this mix: see the next case
    assert p.eta() == pytest.approx((2 * 1.0 + 2 * 19.0) * 10.0 / 20.0)
    p(3, 6, {"run_id": "dear1", "case": "dear", "status": "completed", "elapsed_s": 19.0},
      False)
    p(4, 6, {"run_id": "dear2", "case": "dear", "status": "completed", "elapsed_s": 19.0},
      False)
    now[0] = 29.0
    # only cheap runs are left: 2 s of run time at 58 / 29 = 2 at once, 1 s; one rate for
    # all (29 s for 400 units) would say 14.5 s
    assert p.eta() == pytest.approx(2 * 1.0 * 29.0 / 58.0)
    # unknown while a case with runs left has finished none; a skipped run's record gives
    # its case a rate but is no run time of this sweep
    r = Progress(tasks, stream=io.StringIO())
    r.costs = {t.run_id: 100.0 for t in tasks}
    now[0] = 40.0
    r(1, 6, {"run_id": "cheap0", "case": "cheap", "status": "completed", "elapsed_s": 1.0},
      False)
    assert r.eta() is None
    r(2, 6, {"run_id": "dear0", "case": "dear", "status": "completed", "elapsed_s": 30.0},
      True)
    # 2 cheap runs at 1 s and 2 dear at 30 s: 62 s of runs, 1 s of them in 40 - 29 = 11 s
    assert r.eta() == pytest.approx(62.0 * 11.0 / 1.0)
    # a record without run times prices the work left by the elapsed time per work done
    q = Progress(tasks[:2], stream=io.StringIO())
    q.costs, q.total_work = {"cheap0": 1.0, "cheap1": 3.0}, 4.0
    now[0] = 48.0
    q(1, 2, {"run_id": "cheap0", "case": "cheap", "status": "completed"}, False)
    assert q.eta() == pytest.approx(3.0 * (48.0 - 40.0) / 1.0)


def test_eta_leaves_compilation_out_of_a_cases_rate(
        toys: object, monkeypatch: pytest.MonkeyPatch) -> None:
    now = [0.0]
    monkeypatch.setattr("mpsbench.results.progress.time.perf_counter", lambda: now[0])
    tasks = [Task("flow", "numba", "quick", {"k": k}, f"flow{k}") for k in range(5)]
    p = Progress(tasks, stream=io.StringIO())
    p.costs = {t.run_id: 100.0 for t in tasks}
    p.total_work = 500.0
    now[0] = 8.0
    # the first run took 8 s, 6 of them compiling kernels (a cold cache), one worker
    p(1, 5, {"run_id": "flow0", "case": "flow", "status": "completed", "elapsed_s": 8.0,
             "compile_s": 6.0}, False)
    # four runs left at 2 s each (not 8), one at a time (8 s of runs in 8 s, compiling
    # included)
    assert p.eta() == pytest.approx(4 * 2.0)
    # a record whose compile time is missing, not finite or larger than its run time
    q = Progress(tasks, stream=io.StringIO())
    q.costs = p.costs
    now[0] = 16.0  # 8 s after q started
    q(1, 5, {"run_id": "flow0", "case": "flow", "status": "completed", "elapsed_s": 8.0,
             "compile_s": float("nan")}, False)
    assert q.eta() == pytest.approx(4 * 8.0)
    q(2, 5, {"run_id": "flow1", "case": "flow", "status": "completed", "elapsed_s": 8.0,
             "compile_s": 20.0}, False)
    # 8 s of rate time for 200 units, 16 s busy in 8 s elapsed: 3 runs x 4 s / 2
    assert q.eta() == pytest.approx(3 * 4.0 * 8.0 / 16.0)


def test_the_median_run_of_every_case_and_solver_is_submitted_first() -> None:
    from mpsbench.commands.validate import heavy_first

    tasks = [Task(case, solver, "quick", {"i": i}, f"{case}-{solver}{i}")
             for case, n in (("many", 3), ("few", 2)) for solver in ("a", "b")
             for i in range(n)]
    costs = {t.run_id: float(10 - int(t.run_id[-1])) for t in tasks}  # the last is cheapest
    order = [t.run_id for t in heavy_first(tasks, costs)]
    # "many": costs 10, 9, 8 -> the 9; "few": 10, 9 -> the lower median, the 9; the case with
    # fewer runs still first
    assert order[:4] == ["few-a1", "few-b1", "many-a1", "many-b1"]
    assert order[4:] == ["few-a0", "few-b0", "many-a0", "many-a2", "many-b0", "many-b2"]
    assert [t.run_id for t in heavy_first(tasks, {})] == [t.run_id for t in heavy_first(tasks)]


def test_plain_lines_off_a_terminal_with_reasons(toys: object) -> None:
    out = io.StringIO()
    p = Progress(_tasks(3), stream=out)
    assert p.mode == "plain"
    p(1, 3, _record(0), True)
    p(2, 3, _record(1, "diverged"), False)
    p(3, 3, _record(2), False)
    lines = out.getvalue().splitlines()
    assert len(lines) == 4 and " skip " in lines[0] and "diverged" in lines[1]
    assert lines[2] == "    reason: NaN at step 3"
    assert "\r" not in out.getvalue() and "eta" not in lines[3]  # the last: nothing left


def test_a_bar_on_a_terminal_and_nothing_when_quiet(toys: object) -> None:
    tty = Tty()
    p = Progress(_tasks(2), stream=tty)
    assert p.mode == "bar"
    p(1, 2, _record(0, "failed"), False)
    p(2, 2, _record(1), False)
    p.close()
    text = tty.getvalue()
    assert "\r" in text and "2/2 runs" in text and "100% of the work" in text
    assert "failed: r0: NaN at step 3" in text  # written above the bar
    quiet = Tty()
    q = Progress(_tasks(2), "quiet", stream=quiet)
    q(1, 2, _record(0), False)
    q.close()
    assert quiet.getvalue() == ""
    assert Progress(_tasks(1), "verbose", stream=Tty()).mode == "verbose"


def test_short_label_drops_case_solver_and_hash() -> None:
    rec = {"run_id": "dam-break_reference_geometry=lobovsky_l0=0.025_62cfa449",
           "case": "dam-break", "solver": "reference"}
    assert short_label(rec) == "dam-break geometry=lobovsky_l0=0.025"
    assert short_label(rec, 20) == "dam-break geometr..."
    assert short_label({"run_id": "toy_reference_ab12cd34", "case": "toy",
                        "solver": "reference"}) == "toy (defaults)"


def test_validate_quiet_and_verbose(toys: object, tmp_path: Any,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    args = ["validate", "toy-diffusion", "--tier", "smoke", "--out", str(tmp_path / "r")]
    assert cli.main([*args, "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "completed" not in err and "[1/" not in err
    assert cli.main([*args, "--verbose", "--force"]) == 0
    assert capsys.readouterr().err.count("] completed ") == 2
    with pytest.raises(SystemExit) as exc:
        cli.main([*args, "--quiet", "--verbose"])
    assert exc.value.code == 2


# ---- one bar per run in progress (issue 18, item 3): what the executors report, how it is drawn

def test_a_bar_per_run_in_progress_on_a_terminal_only(toys: object) -> None:
    a, b = _tasks(2)
    live = [LiveRun(a, 0.1, 10, 0.4, 2.0), LiveRun(b, None, 0, math.nan, 65.0)]
    tty = Tty()
    p = Progress([a, b], stream=tty)
    p.running(live)
    text = tty.getvalue()
    assert "t 0.1/0.4 s, step 10, 0:02" in text and "setting up, 1:05" in text
    assert len(p.run_bars) == 2 and p.run_bars[0].n == 250 and p.run_bars[1].n == 0
    p._drawn = -1.0
    p.running(live[:1])  # the second run ended: its bar says idle until another starts
    assert "idle" in tty.getvalue()
    p.close()
    assert p.run_bars == []
    for mode, stream in (("auto", io.StringIO()), ("quiet", Tty()), ("verbose", Tty())):
        q = Progress([a], mode, stream=stream)
        q.running(live)
        q.close()
        assert stream.getvalue() == ""  # plain lines, quiet and verbose draw no run bars


def test_run_labels_name_the_values_that_tell_runs_apart() -> None:
    t = Task("dam-break", "numba", "quick", {"geometry": "lobovsky", "t_end": 0.3,
                                             "stabilization": False, "l0": 0.0125},
             "dam-break_numba_geometry=lobovsky_l0=0.0125_stabilization=False_t_end=0.3_ab12",
             run_hash="h")
    assert values_label(t, 60) == "dam-break lobovsky 0.0125 no stabilization 0.3"
    assert values_label(t, 20) == "dam-break lobovsk..."
    plain = Task("toy", "reference", "smoke", {"n": 3}, "toy_reference_ab12cd34", run_hash="h")
    assert values_label(plain) == "toy (defaults)"
    assert LiveRun(t, 0.15, 3, 0.3, 1.0).fraction == pytest.approx(0.5)
    assert LiveRun(t, 0.15, 3, math.nan, 1.0).fraction is None  # a run to a step count


class Watcher:
    """A progress callback with ``running``: what a sweep reports while its runs go on."""

    def __init__(self) -> None:
        self.live: list[LiveRun] = []
        self.done: list[str] = []

    def __call__(self, done: int, total: int, record: dict[str, Any], skipped: bool) -> None:
        self.done.append(str(record["run_id"]))

    def running(self, live: Any) -> None:
        self.live.extend(live)


@pytest.mark.parametrize("jobs", [1, 2])
def test_executors_report_the_runs_in_progress(toys: tuple[ToyDiffusion, ToyCounter],
                                               tmp_path: Any, jobs: int) -> None:
    diffusion, _ = toys
    tasks = plan(diffusion, ["reference"], "smoke")
    w = Watcher()
    recs = run_tasks(tasks, tmp_path, executor=LocalExecutor(jobs), progress=w)
    assert all(r["status"] == "completed" for r in recs) and sorted(w.done) == sorted(
        t.run_id for t in tasks)
    ids = {t.run_id for t in tasks}
    assert w.live and {lr.task.run_id for lr in w.live} <= ids
    if jobs == 1:  # in this process every solver run reports its end (a step count: no t_end)
        ends = [lr for lr in w.live if lr.steps == diffusion.defaults()["steps"]]
        assert {lr.task.run_id for lr in ends} == ids
        assert all(lr.t is not None and lr.t > 0 and lr.fraction is None for lr in ends)
