"""``mpsbench report DIR``: re-render a results folder from its records, never re-running."""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.cases import CASES
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases
from tests.page_helpers import linked_figures

Toys = tuple[ToyDiffusion, ToyCounter]


@pytest.fixture
def toys() -> Iterator[Toys]:
    diffusion, counter = ToyDiffusion(), ToyCounter()
    with only_cases(diffusion, counter):
        yield diffusion, counter


@pytest.fixture
def folder(toys: Toys, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    out = tmp_path / "r"
    assert cli.main(["validate", "all", "--tier", "smoke", "--out", str(out), "--jobs", "1"]) == 0

    def no_runs(self: Any, params: dict[str, Any], solver: str) -> None:
        raise AssertionError("mpsbench report must not run anything")

    for cls in (ToyDiffusion, ToyCounter):
        monkeypatch.setattr(cls, "execute", no_runs)
    return out


def test_report_rerenders_without_running(folder: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    results = (folder / "results.json").read_text()
    for name in ("summary.md", "index.html"):
        (folder / name).unlink()
    shutil.rmtree(folder / "toy-diffusion" / "figures")
    # the case's current code is used: a new finding shows up without new runs
    monkeypatch.setattr(ToyDiffusion, "findings", lambda self, records: "A **new** finding.")
    # --jobs 1: rendering processes import the code from disk and would not see this patch
    assert cli.main(["report", str(folder), "--jobs", "1"]) == 0
    summary = (folder / "summary.md").read_text()
    assert "A **new** finding." in summary and "PASS (2/2 cases pass)" in summary
    page = (folder / "index.html").read_text()
    assert "A <strong>new</strong> finding." in page
    assert linked_figures(folder, page) == ["toy-diffusion/figures/profile.png"]  # redrawn
    assert not (folder / "figures").exists()  # stored once: in the case folder, not copied
    assert json.loads((folder / "results.json").read_text()) == json.loads(results)
    assert "tier **smoke**" in summary  # from manifest.json
    assert "summary:" in capsys.readouterr().out


def test_report_from_files_when_the_case_is_gone(folder: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    CASES.unregister("toy-diffusion")
    assert cli.main(["report", str(folder)]) == 0
    assert "case 'toy-diffusion' is unavailable" in capsys.readouterr().err
    summary = (folder / "summary.md").read_text()
    assert "has the smallest error" in summary  # findings.md
    assert "**PASS** l2 error below limit" in summary  # checks.json
    assert "Table **errors**" in summary  # tables/*.csv
    page = (folder / "index.html").read_text()
    assert linked_figures(folder, page) == ["toy-diffusion/figures/profile.png"]


def test_report_from_files_option(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args: Any) -> None:
        raise AssertionError("--from-files must not call the case's code")

    for name in ("tables", "figures", "checks", "findings"):
        monkeypatch.setattr(ToyDiffusion, name, broken)
    assert cli.main(["report", str(folder), "--from-files"]) == 0
    assert "PASS (2/2 cases pass)" in (folder / "summary.md").read_text()


def test_report_keeps_unavailable_cases_from_the_manifest(toys: Toys, tmp_path: Path) -> None:
    CASES.register("broken", "mpsbench.validations.no_such_module:CASE", replace=True)
    out = tmp_path / "r"
    assert cli.main(["validate", "all", "--tier", "smoke", "--out", str(out), "--jobs", "1"]) == 1
    (out / "summary.md").unlink()
    assert cli.main(["report", str(out)]) == 0
    summary = (out / "summary.md").read_text()
    assert "## broken (`broken`): FAIL" in summary and "FAIL (2/3 cases pass)" in summary


def test_report_on_a_single_case_folder(toys: Toys, tmp_path: Path) -> None:
    out = tmp_path / "one"
    assert cli.main(["validate", "toy-counter", "--tier", "smoke", "--out", str(out)]) == 0
    (out / "index.html").unlink()
    assert cli.main(["report", str(out)]) == 0
    assert (out / "index.html").is_file() and not (out / "toy-counter").exists()


def test_report_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["report", str(tmp_path / "missing")]) == 2
    assert "no such folder" in capsys.readouterr().err
    assert cli.main(["report", str(tmp_path)]) == 2
    assert "not a results folder" in capsys.readouterr().err


def test_the_solver_table_gives_the_time_to_solution_against_the_first_solver() -> None:
    from mpsbench.results.sections import solver_table

    case = CASES.get("couette")
    base = {"case": "couette", "l0": 5e-5}
    records = [
        {**base, "solver": "numba", "status": "completed", "wall_time_s": 2.0, "l2_error": 0.01},
        {**base, "solver": "implicit", "status": "completed", "wall_time_s": 3.0,
         "l2_error": 0.02},
        {**base, "l0": 2.5e-5, "solver": "numba", "status": "completed", "wall_time_s": 4.0,
         "l2_error": 0.005},
        # stopped early: its wall time is no time to solution
        {**base, "l0": 2.5e-5, "solver": "implicit", "status": "diverged", "wall_time_s": 1.0,
         "l2_error": None},
    ]
    table = solver_table(case, records)
    ratio = table["time to solution [implicit / numba]"]
    assert ratio.loc[5e-5] == 1.5
    assert ratio.isna().loc[2.5e-5]
    assert table.at[5e-5, "wall_time_s [numba]"] == 2.0


def test_the_solver_table_leaves_out_empty_and_shared_columns() -> None:
    """A metric no solver reported has no column; one all solvers report alike in every row
    (a set-up value) has one column that says so; results keep a column per solver."""
    from mpsbench.results.sections import solver_table

    case = CASES.get("couette")
    records = [
        {"case": "couette", "l0": l0, "solver": s, "status": "completed", "wall_time_s": w,
         "l2_error": e, "l2_error_steady": None}
        for l0, s, w, e in [(5e-5, "numba", 2.0, 0.01), (5e-5, "implicit", 3.0, 0.02),
                            (2.5e-5, "numba", 4.0, 0.005), (2.5e-5, "implicit", 6.0, 0.007)]
    ]
    case_metrics = set(case.metrics)
    assert {"l2_error", "l2_error_steady"} <= case_metrics
    shared = next(m for m in case.metrics if m not in ("l2_error", "l2_error_steady"))
    for r in records:
        r[shared] = 0.25
    table = solver_table(case, records)
    assert "l2_error [numba]" in table and "l2_error [implicit]" in table
    assert not any(c.startswith("l2_error_steady") for c in table.columns)
    assert f"{shared} [all solvers]" in table and f"{shared} [numba]" not in table
    assert table["time to solution [implicit / numba]"].tolist() == [1.5, 1.5]


def test_report_keeps_the_command_lines_solver_order(toys: Toys, tmp_path: Path) -> None:
    """The runs are stored in file-name order (implicit before reference); the re-render takes
    the solvers in the order of the command line, as validate did: the first is the one the
    time to solution is relative to."""
    out = tmp_path / "two"
    assert cli.main(["validate", "toy-diffusion", "--tier", "smoke", "--solver", "reference",
                     "--solver", "implicit", "--out", str(out), "--quiet"]) == 0
    ratio = "time to solution [implicit / reference]"
    assert ratio in (out / "summary.md").read_text()
    (out / "summary.md").unlink()
    assert cli.main(["report", str(out)]) == 0
    assert ratio in (out / "summary.md").read_text()
