"""Progress of ``mpsbench validate`` (issue 18, item 3): the work-weighted ETA, plain lines off
a terminal, a bar on one, --quiet."""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.results.progress import Progress, short_label, task_costs
from mpsbench.results.records import Task
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
    p = Progress(_tasks(2), stream=io.StringIO())
    p.costs, p.total_work = {"r0": 1.0, "r1": 9.0}, 10.0
    now[0] = 10.0
    p(1, 2, _record(0), False)  # a tenth of the work in 10 s: 90 s left, not 10
    assert p.eta() == pytest.approx(90.0)
    line = p.stream.getvalue()
    assert line.startswith("[1/2     10s eta 1:30] completed r0 1.0s")


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
