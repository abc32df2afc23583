"""Cases rendered in worker processes (mpsbench.results.render_pool) give what rendering them
here gives: the same sections, the same files, a case's bug kept in its own section, and a case
that cannot be sent to a process rendered here."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

from mpsbench import cli
from mpsbench.cases import Case
from mpsbench.results.render_pool import render_cases
from mpsbench.results.sections import CaseSection
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases


class BrokenFigures(ToyCounter):
    """A case whose figure code has a bug (module level: a worker process can load it)."""

    name = "toy-broken"

    def figures(self, records: list[dict[str, Any]], arrays: Any, outdir: Path) -> list[Path]:
        raise ZeroDivisionError("a bug in the figure code")


class Unpicklable(ToyCounter):
    name = "toy-unpicklable"

    def __init__(self) -> None:
        super().__init__()
        self.hook = lambda: 0  # a lambda does not pickle: this case cannot go to a process


class WhereRendered(ToyCounter):
    """Its findings name the process that rendered it."""

    name = "toy-where"

    def findings(self, records: list[dict[str, Any]]) -> str:
        return f"rendered by process {os.getpid()}"


def summary(sections: list[CaseSection]) -> list[tuple[Any, ...]]:
    return [(s.name, s.passed, s.error.split(" at ")[0],
             [(x.solver, x.rendered.passed, [c.name for c in x.rendered.checks])
              for x in s.solvers]) for s in sections]


def files(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*"))
            if p.suffix in (".md", ".csv", ".json") and p.parent.name != "runs"}


def test_cases_rendered_in_processes_match_rendered_here(tmp_path: Path) -> None:
    cases: list[Case] = [ToyDiffusion(), ToyCounter(), BrokenFigures(), Unpicklable(),
                         WhereRendered()]
    out = tmp_path / "run"
    with only_cases(*cases):
        # exit 1: the broken case fails its render; every run is in results.json all the same
        assert cli.main(["validate", "all", "--tier", "smoke", "--out", str(out),
                         "--jobs", "1"]) == 1
    records = json.loads((out / "results.json").read_text())
    done = {}
    for processes in (1, 2):
        folder = tmp_path / f"p{processes}"
        shutil.copytree(out, folder)
        work = [(c, [r for r in records if r["case"] == c.name], folder / c.name) for c in cases]
        done[processes] = (render_cases(work, processes), folder)
    (here, a), (pooled, b) = done[1], done[2]
    assert [s.name for s in pooled] == [c.name for c in cases]  # in the order given
    assert summary(pooled) == summary(here)
    broken = pooled[2]
    assert not broken.passed and "ZeroDivisionError: a bug in the figure code" in broken.error
    assert pooled[3].passed and pooled[1].passed  # the unpicklable one, rendered here
    for c in cases[:-1]:
        assert files(b / c.name) == files(a / c.name)
    here_pid = f"rendered by process {os.getpid()}"
    assert here_pid in (a / "toy-where" / "report.md").read_text()
    pooled_report = (b / "toy-where" / "report.md").read_text()
    assert "rendered by process" in pooled_report and here_pid not in pooled_report


def test_report_refuses_a_jobs_count_below_one(tmp_path: Path,
                                               capsys: Any) -> None:
    assert cli.main(["report", str(tmp_path), "--jobs", "0"]) == 2
    assert "--jobs 0 is not allowed: an integer >= 1" in capsys.readouterr().err


def test_report_renders_the_same_with_one_job_and_with_two(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with only_cases(ToyDiffusion(), ToyCounter()):
        assert cli.main(["validate", "all", "--tier", "smoke", "--out", str(out),
                         "--jobs", "1"]) == 0
        shutil.copytree(out, tmp_path / "again")
        assert cli.main(["report", str(out), "--jobs", "1"]) == 0
        assert cli.main(["report", str(tmp_path / "again"), "--jobs", "2"]) == 0
    for name in ("toy-diffusion", "toy-counter"):
        assert files(tmp_path / "again" / name) == files(out / name)
    assert (tmp_path / "again" / "summary.md").read_text() == (out / "summary.md").read_text()
