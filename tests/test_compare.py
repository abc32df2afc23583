"""``mpsbench compare BASELINE CURRENT``: matching, tolerances, regressions, bad input."""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.results.compare import CompareError, Rule, compare, load_results, metric_rule
from mpsbench.results.records import ENV_COLUMNS
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases

Toys = tuple[ToyDiffusion, ToyCounter]


@pytest.fixture
def toys() -> Iterator[Toys]:
    diffusion, counter = ToyDiffusion(), ToyCounter()
    with only_cases(diffusion, counter):
        yield diffusion, counter


def validate(out: Path, tier: str = "smoke") -> Path:
    assert cli.main(["validate", "all", "--tier", tier, "--out", str(out), "--jobs", "1"]) == 0
    return out


@pytest.fixture
def baseline(toys: Toys, tmp_path: Path) -> Path:
    return validate(tmp_path / "base")


def edited(src: Path, dest: Path, edit: Any) -> Path:
    """A copy of the results.json of ``src`` with ``edit(record)`` applied to every record."""
    records = json.loads((src / "results.json").read_text())
    for rec in records:
        edit(rec)
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "results.json").write_text(json.dumps(records))
    return dest


def run_compare(*args: str) -> int:
    return cli.main(["compare", *args])


def test_self_compare_exits_0(baseline: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_compare(str(baseline), str(baseline)) == 0
    out = capsys.readouterr().out
    assert "3 matched records" in out and "0 regression(s)" in out
    assert "OK: no regression" in out
    md = (baseline / "compare.md").read_text()
    assert md.startswith("## mpsbench compare: no regression")
    assert "Every compared metric is within its tolerance." in md
    assert "### Timing" in md


def test_doubled_error_from_a_model_change_exits_1(toys: Toys, baseline: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    toys[0].error_scale = 2.0  # "a model change that doubles the diffusion error"
    current = validate(tmp_path / "cur")
    assert run_compare(str(baseline), str(current)) == 1
    out = capsys.readouterr().out
    assert "2 regression(s)" in out
    for laplacian in ("koshizuka-oka", "xu-jin"):
        line = next(x for x in out.splitlines()
                    if x.startswith("  toy-diffusion_reference_laplacian=" + laplacian))
        assert "l2_error" in line and "(rule lower, 0.05)" in line
    md = (current / "compare.md").read_text()
    assert "2 REGRESSION(S)" in md and "| REGRESSION | toy-diffusion_reference_laplacian=" in md
    assert "+100.0%" in md
    assert "toy-counter" not in md.split("### Timing")[0]  # unchanged records are not listed


def test_improvement_and_rtol_override(toys: Toys, baseline: Path, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    better = edited(baseline, tmp_path / "better",
                    lambda r: r.update(l2_error=r["l2_error"] / 2) if "l2_error" in r else None)
    assert run_compare(str(baseline), str(better)) == 0
    assert "2 better" in capsys.readouterr().out
    worse = edited(baseline, tmp_path / "worse",
                   lambda r: r.update(l2_error=r["l2_error"] * 2) if "l2_error" in r else None)
    assert run_compare(str(baseline), str(worse)) == 1
    assert run_compare(str(baseline), str(worse), "--rtol", "1.5") == 0
    assert run_compare(str(baseline), str(worse), "--rtol", "-1") == 2


def test_declared_rules_counters_and_timings(baseline: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    def slower(rec: dict[str, Any]) -> None:
        rec["wall_time_s"] = (rec["wall_time_s"] + 1) * 10  # timings never regress
        rec["particle_steps_per_s"] /= 10
        rec["n_steps"] += 1  # counters are shown, never regress

    assert run_compare(str(baseline), str(edited(baseline, tmp_path / "a", slower))) == 0
    out = capsys.readouterr().out
    assert "| info" in out and "n_steps" in out and "timing (informational)" in out

    # ToyCounter declares score: ("higher", 0.1); drift is error-like (lower, 0.05)
    def counter(**values: float) -> Any:
        return lambda r: r.update(values) if r["case"] == "toy-counter" else None

    steps: list[tuple[str, dict[str, float], int]] = [
        ("b", {"score": 12}, 0), ("c", {"score": 9.5}, 0), ("d", {"score": 8}, 1),
        ("e", {"drift": 1}, 1)]
    for name, change, status in steps:
        current = edited(baseline, tmp_path / name, counter(**change))
        assert run_compare(str(baseline), str(current)) == status, change
    # ToyDiffusion declares peak: ("equal", 0.01): any change beyond 1 % either way regresses
    up = edited(baseline, tmp_path / "f",
                lambda r: r.update(peak=r["peak"] * 0.9) if "peak" in r else None)
    assert run_compare(str(baseline), str(up)) == 1
    assert "changed" in capsys.readouterr().out


def test_diverged_now_is_a_regression(baseline: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    def diverge(rec: dict[str, Any]) -> None:
        if rec.get("laplacian") == "xu-jin":
            rec.update(status="diverged", reason="runaway velocity", l2_error=None)

    current = edited(baseline, tmp_path / "cur", diverge)
    assert run_compare(str(baseline), str(current)) == 1
    out = capsys.readouterr().out
    assert "laplacian=xu-jin" in out and "status completed -> diverged" in out
    # and the other way round it is an improvement
    assert run_compare(str(current), str(baseline)) == 0


def test_environment_columns_are_no_metrics(baseline: Path, tmp_path: Path) -> None:
    """Another machine, a dirty checkout, a baseline older than the provenance columns: the
    environment (records.ENV_COLUMNS) is never compared as a metric."""
    def elsewhere(rec: dict[str, Any]) -> None:
        rec.update(cpu_count=64, cpu_cores=32, git_dirty=not rec["git_dirty"],
                   numba_version="9.9", machine="elsewhere")

    def older(rec: dict[str, Any]) -> None:
        for key in ENV_COLUMNS:
            if key not in ("mpsbench_version", "python", "numpy_version", "machine",
                           "git_commit"):
                rec.pop(key, None)

    current = edited(baseline, tmp_path / "cur", elsewhere)
    old = edited(baseline, tmp_path / "old", older)
    for base in (baseline, old):
        result = compare(load_results(base), load_results(current))
        assert result.changes == [], [(c.metric, c.kind) for c in result.changes]


def test_metric_missing_now_is_a_regression(baseline: Path, tmp_path: Path) -> None:
    current = edited(baseline, tmp_path / "cur", lambda r: r.pop("drift", None))
    assert run_compare(str(baseline), str(current)) == 1


def test_appeared_and_vanished(toys: Toys, baseline: Path, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    quick = validate(tmp_path / "quick", "quick")  # smoke + n_side=10 and k=2
    assert run_compare(str(baseline), str(quick)) == 0
    out = capsys.readouterr().out
    assert "3 appeared, 0 vanished" in out
    assert "| appeared | toy-counter_reference_k=2_" in out
    assert run_compare(str(quick), str(baseline)) == 0
    out = capsys.readouterr().out
    assert "0 appeared, 3 vanished" in out and "| vanished |" in out
    assert "refresh the baseline" in (baseline / "compare.md").read_text()


def test_csv_and_json_files_and_a_missing_parameter_take_the_default(
    baseline: Path, tmp_path: Path
) -> None:
    assert run_compare(str(baseline / "results.csv"), str(baseline / "results.json"),
                       "--markdown", str(tmp_path / "pr.md")) == 0
    assert (tmp_path / "pr.md").is_file()
    # a baseline older than the 'steps' parameter: records match by its default
    old = edited(baseline, tmp_path / "old", lambda r: r.pop("steps", None))
    assert run_compare(str(old), str(baseline), "--markdown", "-") == 0
    assert not (baseline / "compare.md").exists()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "corrupt JSON"),
        ('{"a": 1}', "expected a JSON list of run records"),
        ("[]", "holds no run records"),
        ('[{"case": "toy-counter", "status": "completed"}]', "lacks solver"),
    ],
)
def test_corrupt_baseline_exits_2(baseline: Path, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str],
                                  content: str, message: str) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    assert run_compare(str(bad), str(baseline)) == 2
    err = capsys.readouterr().err
    assert err.startswith("mpsbench compare: error: ") and message in err and "bad.json" in err


def test_unusable_inputs_exit_2(baseline: Path, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    (tmp_path / "empty").mkdir()
    (tmp_path / "binary.json").write_bytes(b"\xff\xfe\x00")
    cases = [
        (tmp_path / "other.csv", "lacks the column(s) case, solver, status"),
        (tmp_path / "empty", "not a results folder"),
        (tmp_path / "missing", "no such file or folder"),
        (tmp_path / "binary.json", "not a text file"),
    ]
    for path, message in cases:
        assert run_compare(str(path), str(baseline)) == 2
        assert message in capsys.readouterr().err
    # two sets with nothing in common
    only = edited(baseline, tmp_path / "only", lambda r: r.update(solver="elsewhere"))
    assert run_compare(str(only), str(baseline)) == 2
    err = capsys.readouterr().err
    assert "no record in common" in err and "solvers elsewhere" in err


def test_duplicate_records_are_an_error(baseline: Path) -> None:
    records = load_results(baseline)
    with pytest.raises(CompareError, match="two records with the same"):
        compare(records + records[:1], records)


def test_bad_declared_rule_is_a_clear_error(toys: Toys, baseline: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    toys[1].compare = {"score": ("bigger", 0.1)}
    assert run_compare(str(baseline), str(baseline)) == 2
    assert "compare['score'] = ('bigger', 0.1) is not allowed" in capsys.readouterr().err


def test_default_rules() -> None:
    assert metric_rule(None, "l2_error") == Rule("lower", 0.05)
    assert metric_rule(None, "pressure_noise_rms").direction == "lower"
    assert metric_rule(None, "mass_drift").direction == "lower"
    assert metric_rule(None, "surge_front_final") == Rule("equal", 0.05)
    assert metric_rule(None, "wall_time_s").gate is False
    assert metric_rule(None, "particle_steps_per_s").direction == "higher"
    assert metric_rule(None, "n_steps").gate is False
    assert metric_rule(None, "l2_error", rtol=0.5).rtol == 0.5
    assert metric_rule(ToyCounter(), "score") == Rule("higher", 0.1)
    assert metric_rule(ToyCounter(), "score", rtol=0.3).rtol == 0.3


def test_unknown_case_matches_by_run_id(baseline: Path, tmp_path: Path) -> None:
    # records of a case that is not installed here still compare (by run id)
    def rename(rec: dict[str, Any]) -> None:
        rec["case"] = "plugin-case"

    def rename_and_worsen(rec: dict[str, Any]) -> None:
        rename(rec)
        if "l2_error" in rec:
            rec["l2_error"] *= 3

    a = edited(baseline, tmp_path / "a", rename)
    b = edited(baseline, tmp_path / "b", rename_and_worsen)
    assert run_compare(str(a), str(a)) == 0
    assert run_compare(str(a), str(b)) == 1
    shutil.rmtree(a)


@pytest.mark.parametrize("name", ["diffusion", "couette", "water-jet", "dam-break",
                                  "hydrostatic", "poiseuille", "taylor-green", "cavity"])
def test_declared_rules_of_the_builtin_cases_are_valid(name: str) -> None:
    """Each declared rule names a metric the case records and is a rule compare accepts."""
    from mpsbench.cases import get_case

    case = get_case(name)
    for metric in case.compare:
        assert metric in case.metrics, f"{name}: compare rule for unknown metric {metric!r}"
        metric_rule(case, metric)  # raises CompareError on a bad rule
