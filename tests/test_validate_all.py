"""``mpsbench validate all``: one run over every case and solver, one report folder, exit codes."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from mpsbench import cli
from mpsbench.cases import CASES
from tests.fake_cases import ToyCounter, ToyDiffusion, extra_solver, only_cases
from tests.page_helpers import linked_figures


@pytest.fixture
def toys() -> Iterator[tuple[ToyDiffusion, ToyCounter]]:
    diffusion, counter = ToyDiffusion(), ToyCounter()
    with only_cases(diffusion, counter):
        yield diffusion, counter


def validate(out: Path, *extra: str) -> int:
    return cli.main(["validate", "all", "--tier", "smoke", "--out", str(out), "--jobs", "1",
                     *extra])


def test_all_pass_writes_one_report_folder(toys: object, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    assert validate(out) == 0
    for name in ("results.csv", "results.json", "summary.md", "index.html", "manifest.json"):
        assert (out / name).is_file(), name
    # per-case folders are kept; index.html links their figures (stored once, not copied)
    for case in ("toy-diffusion", "toy-counter"):
        for name in ("report.md", "results.csv", "checks.json", "findings.md"):
            assert (out / case / name).is_file(), (case, name)
    assert (out / "toy-diffusion" / "figures" / "profile.png").is_file()
    assert not (out / "figures").exists()
    assert not (out / "runs").exists()
    mask = os.umask(0)
    os.umask(mask)
    assert (out / "index.html").stat().st_mode & 0o777 == 0o666 & ~mask  # shareable, not 0600

    records = json.loads((out / "results.json").read_text())
    assert {r["case"] for r in records} == {"toy-diffusion", "toy-counter"}
    assert len(records) == 3
    df = pd.read_csv(out / "results.csv")
    assert len(df) == 3
    for col in ("case", "solver", "solver_version", "tier", "status", "wall_time_s",
                "particle_steps_per_s", "mpsbench_version", "git_commit", "machine",
                "laplacian", "n_side", "k", "l2_error", "drift"):
        assert col in df.columns, col
    diff = df[df.case == "toy-diffusion"]
    assert (diff.status == "completed").all() and (diff.particle_steps_per_s > 0).all()
    assert {r["solver_version"] for r in records if r["case"] == "toy-diffusion"} == {"1.0"}

    summary = (out / "summary.md").read_text()
    assert summary.startswith("# mpsbench validation: PASS (2/2 cases pass)")
    assert "## Toy diffusion (`toy-diffusion`): PASS" in summary
    assert "has the smallest error" in summary  # the plain-word finding
    assert "Table **errors**" in summary  # the headline table
    assert "**PASS** l2 error below limit" in summary

    err = capsys.readouterr().err
    # one progress count across all cases
    assert "[1/3" in err and "[3/3" in err and "[1/2" not in err


def test_index_html_loads_nothing_from_the_network(toys: object, tmp_path: Path) -> None:
    out = tmp_path / "r"
    assert validate(out) == 0
    page = (out / "index.html").read_text()
    assert page.startswith("<!DOCTYPE html>")
    assert linked_figures(out, page) == ["toy-diffusion/figures/profile.png"]
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", page)
    assert "<link" not in page and "<script" not in page
    for anchor in ('id="toy-diffusion"', 'id="toy-diffusion--reference"',
                   'id="toy-counter"', 'id="toy-counter--reference"'):
        assert anchor in page
    assert "<table" in page and "<strong>xu-jin</strong>" in page


def test_failing_check_exits_1(toys: tuple[ToyDiffusion, ToyCounter], tmp_path: Path) -> None:
    toys[0].fail_check = True
    out = tmp_path / "r"
    assert validate(out) == 1
    summary = (out / "summary.md").read_text()
    assert "FAIL (1/2 cases pass)" in summary
    assert "## Toy diffusion (`toy-diffusion`): FAIL" in summary
    assert "## Toy counter (`toy-counter`): PASS" in summary
    assert '<span class="fail">FAIL</span>' in (out / "index.html").read_text()


def test_case_whose_runs_all_fail_fails(toys: object, tmp_path: Path,
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(self: ToyCounter, params: dict[str, object], solver: str) -> None:
        raise RuntimeError("kaput")

    monkeypatch.setattr(ToyCounter, "execute", boom)
    out = tmp_path / "r"
    assert validate(out) == 1  # the check is undecided, but no run completed
    summary = (out / "summary.md").read_text()
    assert "## Toy counter (`toy-counter`): FAIL" in summary and "no run completed" in summary
    assert "RuntimeError: kaput" in (out / "index.html").read_text()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["validate", "no-such-case"], "unknown case 'no-such-case'"),
        (["validate", "all", "--solver", "nope"], "unknown solver 'nope'"),
        (["validate", "all", "--set", "k=2"], "--set applies to one case"),
        (["validate", "all", "--jobs", "0"], "--jobs = 0"),
        (["validate"], "give a case name"),
    ],
)
def test_usage_errors_exit_2(toys: object, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                             args: list[str], message: str) -> None:
    assert cli.main([*args, "--out", str(tmp_path / "r")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_unknown_tier_exits_2(toys: object, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["validate", "all", "--tier", "huge"])
    assert exc.value.code == 2
    assert "invalid choice: 'huge'" in capsys.readouterr().err


def test_unloadable_case_fails_alone(toys: object, tmp_path: Path) -> None:
    CASES.register("broken", "mpsbench.validations.no_such_module:CASE", replace=True)
    out = tmp_path / "r"
    assert validate(out) == 1
    summary = (out / "summary.md").read_text()
    assert "## broken (`broken`): FAIL" in summary and "case unavailable" in summary
    assert "## Toy diffusion (`toy-diffusion`): PASS" in summary
    manifest = json.loads((out / "manifest.json").read_text())
    assert [c["name"] for c in manifest["cases"]] == ["broken", "toy-counter", "toy-diffusion"]


def test_broken_figure_code_fails_that_case_only(toys: tuple[ToyDiffusion, ToyCounter],
                                                 tmp_path: Path) -> None:
    toys[0].broken_figures = True
    out = tmp_path / "r"
    assert validate(out) == 1
    summary = (out / "summary.md").read_text()
    assert "rendering failed: RuntimeError: figure code is broken" in summary
    assert "## Toy counter (`toy-counter`): PASS" in summary
    assert len(json.loads((out / "results.json").read_text())) == 3  # records still reported


def test_several_solvers_get_a_section_each(toys: object, tmp_path: Path) -> None:
    out = tmp_path / "r"
    with extra_solver() as other:
        assert validate(out, "--solver", "reference", "--solver", other) == 0
    records = json.loads((out / "results.json").read_text())
    assert {r["solver"] for r in records} == {"reference", other}
    assert len(records) == 6
    for solver in ("reference", other):
        assert (out / "toy-diffusion" / "by-solver" / solver / "report.md").is_file()
        assert (out / "toy-diffusion" / "by-solver" / solver / "figures" / "profile.png"
                ).is_file()
    page = (out / "index.html").read_text()
    assert f'id="toy-diffusion--{other}"' in page and 'id="toy-diffusion--reference"' in page
    assert "metrics by solver" in page and f"wall_time_s [{other}]" in page
    # the second backend is the reference under another name: its errors are the reference's
    # to the last bit, shown once
    assert "l2_error [all solvers]" in page and f"l2_error [{other}]" not in page
    # the all-solver figure first, then each solver's
    assert linked_figures(out, page) == [
        "toy-diffusion/figures/profile.png",
        *[f"toy-diffusion/by-solver/{s}/figures/profile.png" for s in ("reference", other)]]
    summary = (out / "summary.md").read_text()
    assert f"### solver {other} 0.0.1: PASS" in summary


def test_parallel_jobs_and_skip_if_done(toys: object, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    assert cli.main(["validate", "all", "--tier", "quick", "--out", str(out), "--jobs", "2"]) == 0
    err = capsys.readouterr().err
    assert "[6/6" in err and "2 job(s)" in err
    assert cli.main(["validate", "all", "--tier", "quick", "--out", str(out), "--jobs", "2"]) == 0
    assert capsys.readouterr().err.count(" skip ") == 6


def test_default_out_is_named_by_time_and_tier(toys: object, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert cli.main(["validate", "all", "--tier", "smoke", "--jobs", "1"]) == 0
    assert cli.main(["validate", "all", "--tier", "smoke", "--jobs", "1"]) == 0
    folders = sorted(p.name for p in (tmp_path / "reports").iterdir())
    assert len(folders) == 2
    assert re.fullmatch(r"\d{8}-\d{4}-smoke", folders[0])
    assert all((tmp_path / "reports" / f / "index.html").is_file() for f in folders)


def test_single_case_folder_gets_summary_and_index(toys: object, tmp_path: Path) -> None:
    out = tmp_path / "one"
    assert cli.main(["validate", "toy-diffusion", "--tier", "smoke", "--out", str(out)]) == 0
    for name in ("report.md", "results.json", "summary.md", "index.html", "figures/profile.png"):
        assert (out / name).is_file(), name
    assert linked_figures(out, (out / "index.html").read_text()) == ["figures/profile.png"]


def test_cases_with_fewer_longer_runs_are_submitted_first() -> None:
    from mpsbench.commands.validate import heavy_first
    from mpsbench.results.records import Task

    tasks = [Task(case, "reference", "quick", {"i": i}, f"{case}{i}")
             for case, n in (("many", 3), ("few", 1), ("some", 2)) for i in range(n)]
    assert [t.run_id for t in heavy_first(tasks)] == ["few0", "some0", "some1", "many0",
                                                       "many1", "many2"]


@pytest.mark.numba_default
def test_the_default_solver_is_numba_when_it_loads(
        toys: object, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("numba")
    out = tmp_path / "one"
    assert cli.main(["validate", "toy-diffusion", "--tier", "smoke", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "solver: numba (the default when it is installed" in err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["solvers"] == ["numba"]


@pytest.mark.numba_default
def test_without_numba_the_default_is_the_reference_and_says_why(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from mpsbench.commands import validate as command
    from mpsbench.registry import PluginLoadError
    from mpsbench.run.protocol import SOLVERS

    real = SOLVERS.get

    def get(name: str) -> object:
        if name == "numba":
            raise PluginLoadError("solver 'numba' (built-in) could not be loaded: ImportError: "
                                  "numba is not installed: pip install 'mpsbench[fast]'")
        return real(name)

    monkeypatch.setattr(SOLVERS, "get", get)
    name, note = command.default_solver()
    assert name == "reference"
    assert note == ("solver: reference (numba is unavailable: solver 'numba' (built-in) could "
                    "not be loaded: ImportError: numba is not installed: pip install "
                    "'mpsbench[fast]')")
