"""Study files: parsing, validation before any run, expansion; the ``study`` CLI end to end.

The runs use ``study-toy``, a case defined here that needs no solver (its metric is a formula
of the parameters, optionally after a sleep), so these tests take seconds.  ``tests/
test_executors.py`` reuses it for the executor and kill -9 tests.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.cases import CASES, Case, CaseCheck, CaseRun, Param
from mpsbench.errors import ConfigError
from mpsbench.results.lock import LOCK_FILE
from mpsbench.results.records import load_records
from mpsbench.results.study_spec import StudyFileError, check_tolerances, load_study, parse_study

TOY = "study-toy"


class StudyToy(Case):
    """A case without a solver: ``error = l0 * re_ratio * factor(laplacian, weight)``."""

    name = TOY
    title = "Study toy"
    params = (
        Param("laplacian", "xu-jin", "Laplacian model (any registered name)", kind=str),
        Param("weight", "wf2", "weighting function", kind=str, choices=("wf1", "wf2")),
        Param("re_ratio", 3.1, "r_e / l0", minimum=1.0, exclusive_minimum=True),
        Param("l0", 0.1, "particle spacing", unit="m", minimum=0.0, exclusive_minimum=True),
        Param("sleep", 0.0, "seconds to sleep in each run", unit="s", minimum=0.0),
        Param("explode", False, "raise inside the run", kind=bool),
        Param("die", False, "end the worker process abruptly (os._exit)", kind=bool),
    )
    tiers = {
        "smoke": [{"laplacian": ["xu-jin"], "weight": ["wf1", "wf2"]}],
        "quick": [{"laplacian": ["xu-jin", "koshizuka-oka"], "weight": ["wf1", "wf2"]}],
    }
    metrics = {"error": "a made-up error [-]", "n_pairs": "a made-up count [-]"}

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        if params["sleep"]:
            time.sleep(params["sleep"])
        if params["explode"]:
            raise RuntimeError("boom")
        if params["die"]:
            os._exit(3)
        factor = (1.0 + len(params["laplacian"])) * (2.0 if params["weight"] == "wf1" else 1.0)
        return CaseRun({"error": params["l0"] * params["re_ratio"] * factor / 100.0,
                        "n_pairs": int(10 * params["re_ratio"] ** 2)})

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        return [CaseCheck("toy ran", bool(records), f"{len(records)} runs")]


def register_toy() -> None:
    """Register ``study-toy`` (idempotent; also called inside worker processes)."""
    if TOY not in CASES or CASES.entry(TOY).error is not None:
        CASES.register(TOY, StudyToy(), origin="user", replace=True)


@pytest.fixture(autouse=True)
def toy_case() -> Iterator[None]:
    register_toy()
    yield
    CASES.unregister(TOY)


def write(tmp_path: Path, text: str, name: str = "study.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = """
name = "toy"
case = "study-toy"
solvers = ["reference"]
tier = "smoke"

[params]
l0 = 0.05

[grid]
laplacian = ["koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic"]
weight = ["wf1", "wf2"]
re_ratio = [2.1, 3.1, 4.0]

[tolerances]
error = 1.0
"""


# --------------------------------------------------------------------------- parsing


def test_good_file_expands_to_the_product(tmp_path: Path) -> None:
    spec = load_study(write(tmp_path, GOOD))
    assert spec.name == "toy" and spec.cases == (TOY,) and spec.tier == "smoke"
    tasks = spec.tasks()
    assert len(tasks) == 4 * 2 * 3
    assert len({t.run_id for t in tasks}) == len(tasks)
    assert {t.params["l0"] for t in tasks} == {0.05}
    assert {t.params["re_ratio"] for t in tasks} == {2.1, 3.1, 4.0}
    assert spec.tolerances[0].max == 1.0
    assert spec.default_out() == Path("reports/studies/toy")


def test_explicit_runs_and_grid_union(tmp_path: Path) -> None:
    text = """
case = "study-toy"
tier = "smoke"
[grid]
weight = "wf2"
laplacian = ["xu-jin"]
[[runs]]
laplacian = "koshizuka-oka"
weight = "wf1"
re_ratio = 2.5
[[runs]]
laplacian = "xu-jin"
weight = "wf2"
"""
    spec = load_study(write(tmp_path, text, "explicit.toml"))
    combos = sorted((t.params["laplacian"], t.params["weight"], t.params["re_ratio"])
                    for t in spec.tasks())
    # the second explicit run equals the grid's run: counted once
    assert combos == [("koshizuka-oka", "wf1", 2.5), ("xu-jin", "wf2", 3.1)]
    assert spec.name == "explicit"


def test_only_explicit_runs(tmp_path: Path) -> None:
    text = 'case = "study-toy"\ntier = "smoke"\n[[runs]]\nweight = "wf1"\nl0 = "1/40"\n'
    tasks = load_study(write(tmp_path, text)).tasks()
    assert [(t.params["weight"], t.params["l0"]) for t in tasks] == [("wf1", 0.025)]


def test_tier_grid_when_no_grid(tmp_path: Path) -> None:
    tasks = load_study(write(tmp_path, 'case = "study-toy"\ntier = "quick"\n')).tasks()
    assert len(tasks) == 4


def test_plugin_model_name_is_accepted(tmp_path: Path) -> None:
    from mpsbench.physics.laplacians import LAPLACIANS, KoshizukaOka

    class Mine(KoshizukaOka):
        name = "mine"

    LAPLACIANS.register("mine", Mine, origin="user")
    try:
        text = 'case = "study-toy"\ntier = "smoke"\n[grid]\nlaplacian = ["mine", "xu-jin"]\n'
        assert len(load_study(write(tmp_path, text)).tasks()) == 4
    finally:
        LAPLACIANS.unregister("mine")


# --------------------------------------------------------------------------- bad files


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        # a typo in a top-level key, with the suggestion and the allowed keys
        ('case = "study-toy"\nteir = "smoke"\n', ["teir: unknown key (did you mean 'tier'?)",
                                                  "allowed keys: name"]),
        # a typo in a parameter name
        ('case = "study-toy"\n[grid]\nlaplacain = ["xu-jin"]\n',
         ["grid.laplacain: unknown parameter of case 'study-toy' (did you mean 'laplacian'?)",
          "allowed: laplacian, weight"]),
        # a negative spacing
        ('case = "study-toy"\n[params]\nl0 = -0.05\n',
         ["params.l0: -0.05 is not allowed: a float > 0 (m)"]),
        ('case = "study-toy"\n[grid]\nl0 = [0.1, -0.05]\n',
         ["grid.l0[1]: -0.05 is not allowed: a float > 0 (m)"]),
        # an unknown model name (the case's parameter has no choices: the registry decides)
        ('case = "study-toy"\n[grid]\nlaplacian = ["xu-jim"]\n',
         ["grid.laplacian[0]: unknown Laplacian model 'xu-jim' (did you mean 'xu-jin'?)",
          "known: ", "koshizuka-oka"]),
        # a model name outside the parameter's choices
        ('case = "study-toy"\n[[runs]]\nweight = "wf3"\n',
         ["runs[0].weight: \"wf3\" is not allowed (did you mean 'wf2'?): one of wf1, wf2"]),
        ('case = "couettte"\n', ["case: unknown case 'couettte'"]),
        ('case = "study-toy"\nsolvers = ["refrence"]\n',
         ["solvers[0]: unknown solver 'refrence' (did you mean 'reference'?)"]),
        ('case = "study-toy"\ntier = "fast"\n',
         ['tier: "fast" is not allowed: one of smoke, quick, paper']),
        ('case = "study-toy"\ntier = "paper"\n',
         ["tier: \"paper\" is not a tier of case 'study-toy': one of smoke, quick"]),
        ('case = "study-toy"\njobs = 0\n', ["jobs: 0 is not allowed: an integer >= 1"]),
        ('case = "study-toy"\nexecutor = "ray"\n',
         ['executor: "ray" is not allowed: one of local, dask']),
        ('tier = "smoke"\n', ["case: missing"]),
        ('case = "study-toy"\n[tolerances]\nerorr = 0.1\n',
         ["tolerances.erorr: unknown metric (did you mean 'error'?)"]),
        ('case = "study-toy"\n[tolerances]\nerror = {max = 0.1, maxx = 2}\n',
         ["tolerances.error.maxx: unknown key; allowed: max, min"]),
        ('case = "study-toy"\n[grid]\nre_ratio = []\n', ["grid.re_ratio: an empty list"]),
        ('case = "study-toy"\n[params]\nre_ratio = 2.0\n[grid]\nre_ratio = [3.0]\n',
         ["grid.re_ratio: also set in [params]"]),
        ('case = "study-toy"\n[grid]\nre_ratio = "many"\n',
         ['grid.re_ratio: "many" is not allowed: a float > 1']),
        ('case = "study-toy"\nname = "has space"\n', ['name: "has space" is not allowed']),
        ('case = "study-toy"\n[grid\n', ["not valid TOML"]),
    ],
)
def test_bad_files_name_the_key_and_what_is_allowed(
    tmp_path: Path, text: str, expected: list[str]
) -> None:
    path = write(tmp_path, text, "bad.toml")
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    message = str(info.value)
    assert str(path) in message
    for part in expected:
        assert part in message, message
    assert isinstance(info.value, ConfigError)  # the CLI maps it to exit status 2


def test_every_problem_is_reported_at_once(tmp_path: Path) -> None:
    text = 'case = "study-toy"\nteir = "smoke"\n[params]\nl0 = -1.0\n[grid]\nweight = ["wf9"]\n'
    with pytest.raises(StudyFileError) as info:
        load_study(write(tmp_path, text))
    assert len(info.value.problems) == 3
    assert "3 problems" in str(info.value)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(StudyFileError, match="no such file"):
        load_study(tmp_path / "nope.toml")


def test_parse_study_from_a_dict() -> None:
    spec = parse_study({"case": TOY, "tier": "smoke"}, "inline")
    assert spec.name == "inline" and len(spec.tasks()) == 2


# --------------------------------------------------------------------------- tolerances


def test_tolerance_checks() -> None:
    spec = parse_study({"case": TOY, "tolerances": {"error": {"max": 0.1, "min": 0.0}}}, "t")
    ok = [{"case": TOY, "run_id": "a", "status": "completed", "error": 0.05}]
    assert [c.passed for c in check_tolerances(spec, ok)] == [True]
    bad = ok + [{"case": TOY, "run_id": "b", "status": "completed", "error": 0.5},
                {"case": TOY, "run_id": "c", "status": "diverged"}]
    (check,) = check_tolerances(spec, bad)
    assert check.passed is False
    assert "b = 0.5" in check.detail and "c (diverged)" in check.detail
    assert check_tolerances(spec, [])[0].passed is None


# --------------------------------------------------------------------------- CLI


def test_cli_bad_file_fails_before_any_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, 'case = "study-toy"\n[grid]\nl0 = [-0.05]\n')
    out = tmp_path / "out"
    assert cli.main(["study", "run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "grid.l0[0]: -0.05 is not allowed: a float > 0 (m)" in err and str(path) in err
    assert not out.exists()


def test_cli_run_then_status(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, GOOD)
    out = tmp_path / "out"
    assert cli.main(["study", "run", str(path), "--out", str(out)]) == 0
    records = load_records(out / TOY)
    assert len(records) == 24 and all(r["status"] == "completed" for r in records)
    assert json.loads((out / "plan.json").read_text())["n_runs"] == 24
    assert (out / "study.toml").read_text() == GOOD
    assert (out / TOY / "report.md").is_file()
    assert json.loads((out / "tolerances.json").read_text())[0]["passed"] is True
    capsys.readouterr()

    assert cli.main(["study", "status", str(out)]) == 0
    text = capsys.readouterr().out
    assert "24 runs planned" in text and "done        24" in text and "pending      0" in text

    # a second run skips everything
    assert cli.main(["study", "run", str(path), "--out", str(out), "--no-report"]) == 0
    assert capsys.readouterr().err.count("skip ") == 24


def test_cli_status_counts_failed_and_pending(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = ('case = "study-toy"\ntier = "smoke"\n[grid]\nexplode = [false, true]\n'
            'weight = ["wf1"]\n')
    path = write(tmp_path, text)
    out = tmp_path / "out"
    assert cli.main(["study", "run", str(path), "--out", str(out), "--no-report"]) == 1
    # grow the study: one more weight, not run yet
    path.write_text(text.replace('["wf1"]', '["wf1", "wf2"]'))
    capsys.readouterr()
    assert cli.main(["study", "status", str(path), "--out", str(out), "--json"]) == 0
    st = json.loads(capsys.readouterr().out)
    assert (st["planned"], st["done"], st["failed"], st["pending"]) == (4, 1, 1, 2)
    assert "RuntimeError: boom" in st["runs"]["failed"][0]["reason"]
    assert cli.main(["study", "status", str(out), "--list", "failed"]) == 0
    assert "failed: study-toy" in capsys.readouterr().out

    # --retry-failed re-runs the failed run only (it fails again: still recorded)
    path.write_text(text)
    assert cli.main(["study", "run", str(path), "--out", str(out), "--no-report",
                     "--retry-failed"]) == 1
    progress = capsys.readouterr().err
    assert progress.count("skip ") == 1 and progress.count("failed ") >= 1


def test_cli_dry_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, GOOD)
    assert cli.main(["study", "run", str(path), "--out", str(tmp_path / "o"), "--dry-run"]) == 0
    assert len(capsys.readouterr().out.split()) == 24
    assert not (tmp_path / "o").exists()


def test_cli_status_of_nothing(tmp_path: Path) -> None:
    assert cli.main(["study", "status", str(tmp_path)]) == 2
    assert cli.main(["study", "status", str(tmp_path / "missing")]) == 2


def test_cli_lock_refuses_a_second_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fcntl = pytest.importorskip("fcntl")
    out = tmp_path / "out"
    out.mkdir()
    # POSIX record locks never conflict within one process: hold it from another one
    holder = subprocess.Popen(
        [sys.executable, "-c", "import fcntl, sys, time; fh = open(sys.argv[1], 'a+'); "
         "fcntl.lockf(fh.fileno(), fcntl.LOCK_EX); fh.write('4242'); fh.flush(); "
         "print('locked', flush=True); time.sleep(60)", str(out / LOCK_FILE)],
        stdout=subprocess.PIPE, text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        path = write(tmp_path, GOOD)
        assert cli.main(["study", "run", str(path), "--out", str(out)]) == 2
        assert "in use by another mpsbench process (pid 4242)" in capsys.readouterr().err
        assert not (out / "plan.json").exists()
    finally:
        holder.kill()
        holder.wait()
    assert fcntl is not None


# --------------------------------------------------------------------------- the example study


EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "studies" / "couette_laplacians.toml"


def test_example_study_is_the_24_run_grid() -> None:
    pytest.importorskip("mpsbench.validations.couette")
    spec = load_study(EXAMPLE)
    tasks = spec.tasks()
    assert len(tasks) == 4 * 2 * 3
    combos = {(t.params["laplacian"], t.params["weight"], t.params["re_ratio"]) for t in tasks}
    assert len(combos) == 24
    assert {t.params["l0"] for t in tasks} == {5e-5}
    assert spec.default_out() == Path("reports/studies/couette-laplacians")


class OtherToy(StudyToy):
    name = "study-toy-2"


def test_two_cases_share_the_grid_and_keep_their_folders(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    CASES.register(OtherToy.name, OtherToy(), origin="user", replace=True)
    try:
        path = write(tmp_path, f'cases = ["{TOY}", "{OtherToy.name}"]\ntier = "smoke"\n'
                     '[grid]\nre_ratio = [2.0, 3.0]\n')
        spec = load_study(path)
        assert [t.case for t in spec.tasks()].count(OtherToy.name) == 4
        out = tmp_path / "out"
        assert cli.main(["study", "run", str(path), "--out", str(out), "--jobs", "2"]) == 0
        for name in (TOY, OtherToy.name):
            assert len(load_records(out / name)) == 4
            assert (out / name / "results.csv").is_file()
        # a bad entry of the list is named by its index
        bad = write(tmp_path, f'cases = ["{TOY}", "reference-missing"]\n', "bad.toml")
        with pytest.raises(StudyFileError, match=r"cases\[1\]: unknown case 'reference-missing'"):
            load_study(bad)
    finally:
        CASES.unregister(OtherToy.name)
