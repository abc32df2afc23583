"""Resuming by run identity, --retry-failed, the folder lock between processes, the size guard
and its estimates, failure locations, and what reports do with broken or hostile input
(issue #19)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.cases import Case, CaseCheck, CaseRun, Param, get_case
from mpsbench.errors import InputFileError, UsageError
from mpsbench.results.guard import MAX_PARTICLES, check_plan, estimate_plan
from mpsbench.results.identity import record_hash, run_hash
from mpsbench.results.lock import LOCK_FILE
from mpsbench.results.records import Task, load_records, run_ids
from mpsbench.results.sweep import plan
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases


class Counting(Case):
    """Counts its executions; ``fail_k`` makes the run with that k raise (until cleared)."""

    name = "counting"
    title = "Counting"
    params = (Param("k", 1, "a number", kind=int, minimum=1),
              Param("scale", 1.0, "a factor", minimum=0.0))
    tiers = {"smoke": [{"k": [1, 2]}], "quick": [{"k": [1, 2, 3]}], "paper": [{"k": [1]}]}
    metrics = {"value": "k * scale"}
    executed: list[int] = []
    fail_k: int | None = None

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        Counting.executed.append(params["k"])
        if params["k"] == Counting.fail_k:
            raise RuntimeError(f"k = {params['k']} fails on purpose")
        return CaseRun({"value": params["k"] * params["scale"]})

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        return [CaseCheck("ran", True, "ran")]


@pytest.fixture
def counting() -> Iterator[type[Counting]]:
    Counting.executed = []
    Counting.fail_k = None
    with only_cases(Counting(), ToyDiffusion(), ToyCounter()):
        yield Counting


def validate(*args: str) -> int:
    return cli.main(["validate", *args])


# --------------------------------------------------------------------------- identity


def test_run_hash_is_independent_of_the_readable_name(counting: type[Counting]) -> None:
    case = get_case("counting")
    one = plan(case, ["reference"], "smoke")  # k swept: k in the names
    alone = plan(case, ["reference"], "smoke", {"k": [2]})  # k fixed at 2: named by k != default
    assert one[1].params == alone[0].params
    assert one[1].run_hash == alone[0].run_hash
    assert run_hash("counting", "reference", {"k": 2, "scale": 1.0}) == one[1].run_hash
    # normalised: an int for a float parameter is the same run
    assert record_hash({"case": "counting", "solver": "reference", "k": 2, "scale": 1},
                       case) == one[1].run_hash
    # solver and solver options make another run
    assert run_hash("counting", "numba", one[1].params) != one[1].run_hash
    assert run_hash("counting", "reference", one[1].params, {"threads": 1}) != one[1].run_hash
    # a task's solver spec NAME:options and a record's solver + solver_options agree
    spec = Task("counting", "reference:threads=1", "smoke", one[1].params, "x")
    rec = {"case": "counting", "solver": "reference", "solver_options": "threads=1",
           **one[1].params}
    assert spec.run_hash == record_hash(rec, case) != one[1].run_hash
    assert record_hash({**rec, "solver_options": ""}, case) == one[1].run_hash


def test_setting_a_swept_value_skips_the_runs_already_done(counting: type[Counting],
                                                           tmp_path: Path) -> None:
    """The issue's case: a second validate with --set into the same folder re-ran identical
    parameter sets under new names."""
    out = tmp_path / "out"
    assert validate("counting", "--tier", "smoke", "--out", str(out)) == 0
    assert counting.executed == [1, 2]
    names = sorted(p.name for p in (out / "runs").glob("*.json"))
    assert validate("counting", "--tier", "smoke", "--set", "k=2", "--out", str(out)) == 0
    assert counting.executed == [1, 2]  # nothing ran again
    assert sorted(p.name for p in (out / "runs").glob("*.json")) == names


def test_widening_a_study_grid_runs_only_the_new_combinations(counting: type[Counting],
                                                              tmp_path: Path) -> None:
    out = tmp_path / "study"
    study = tmp_path / "s.toml"
    study.write_text('case = "counting"\ntier = "smoke"\n[grid]\nk = [1, 2]\n')
    assert cli.main(["study", "run", str(study), "--out", str(out)]) == 0
    assert counting.executed == [1, 2]
    study.write_text('case = "counting"\ntier = "smoke"\n[grid]\nk = [1, 2, 3]\n'
                     'scale = [1.0, 2.0]\n')
    assert cli.main(["study", "run", str(study), "--out", str(out)]) == 0
    assert sorted(counting.executed) == [1, 1, 2, 2, 3, 3]  # 4 new of 6: (1|2, 2.0), (3, *)
    assert len(load_records(out / "counting")) == 6
    status = json.loads(_capture(["study", "status", str(out), "--json"]))
    assert (status["planned"], status["done"], status["pending"]) == (6, 6, 0)


def _capture(argv: list[str]) -> str:
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli.main(argv) == 0
    return buf.getvalue()


def test_old_records_without_a_hash_are_matched_by_their_parameters(
        counting: type[Counting], tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert validate("counting", "--tier", "smoke", "--out", str(out)) == 0
    for path in (out / "runs").glob("*.json"):  # as written before run_hash existed
        rec = json.loads(path.read_text())
        del rec["run_hash"]
        rec["run_id"] = "old-name-" + str(rec["k"])
        rec.pop("scale")  # a parameter added later: the default
        path.unlink()
        (out / "runs" / f"{rec['run_id']}.json").write_text(json.dumps(rec))
    assert validate("counting", "--tier", "smoke", "--out", str(out)) == 0
    assert counting.executed == [1, 2]
    assert validate("counting", "--tier", "quick", "--out", str(out)) == 0
    assert counting.executed == [1, 2, 3]  # only k = 3 is new


def test_retry_failed_reruns_only_the_runs_that_did_not_complete(
        counting: type[Counting], tmp_path: Path) -> None:
    out = tmp_path / "out"
    counting.fail_k = 2
    assert validate("counting", "--tier", "quick", "--out", str(out)) == 0  # the check passes
    failed = [r for r in load_records(out) if r["status"] == "failed"]
    assert [r["k"] for r in failed] == [2]
    assert "(at tests/test_resume_guard.py:" in failed[0]["reason"]  # module, not install path
    counting.fail_k = None
    assert validate("counting", "--tier", "quick", "--out", str(out)) == 0
    assert counting.executed == [1, 2, 3]  # resumed: the failed run is done too
    assert validate("counting", "--tier", "quick", "--retry-failed", "--out", str(out)) == 0
    assert counting.executed == [1, 2, 3, 2]
    assert {r["status"] for r in load_records(out)} == {"completed"}
    assert len(load_records(out)) == 3


def test_a_broken_record_is_run_again_when_resuming(counting: type[Counting],
                                                    tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert validate("counting", "--tier", "smoke", "--out", str(out)) == 0
    path = sorted((out / "runs").glob("*.json"))[0]
    path.write_text(path.read_text()[:20])
    with pytest.raises(InputFileError, match="truncated or corrupt JSON"):
        load_records(out)  # a report refuses it ...
    assert validate("counting", "--tier", "smoke", "--out", str(out)) == 0
    assert len(counting.executed) == 3  # ... a resumed sweep runs it again
    assert len(load_records(out)) == 2


# --------------------------------------------------------------------------- the lock


def test_two_validates_into_one_folder_the_second_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "mpsbench", "validate", "dam-break", "--tier", "smoke", "--set",
           "geometry=koshizuka-oka", "--set", "variant=wc-mps", "--out", str(out)]
    first = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        lock = out / LOCK_FILE
        while not (lock.is_file() and lock.read_text().startswith(f"{first.pid}:")):
            assert first.poll() is None, first.communicate()[1]
            assert time.monotonic() < deadline, "the first validate never took the lock"
            time.sleep(0.05)
        second = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert first.poll() is None, "the first validate ended before the second was refused"
    finally:
        first.kill()
        first.communicate()
    assert second.returncode == 2
    errors = [line for line in second.stderr.splitlines() if "error:" in line]
    assert errors == [f"mpsbench validate: error: {out} is in use by another mpsbench process "
                      f"(pid {first.pid}: mpsbench validate dam-break --tier smoke); wait for it "
                      "to finish or pick another --out"]
    assert "Traceback" not in second.stderr


def test_a_folder_that_cannot_be_written_is_one_line(tmp_path: Path) -> None:
    """--out in a read-only folder: chmod for a normal user; root writes through permissions,
    so as root the folder is a read-only tmpfs mounted in a private mount namespace (gone when
    the process ends)."""
    ro = tmp_path / "ro"
    ro.mkdir()
    args = ["-m", "mpsbench", "validate", "diffusion", "--tier", "smoke", "--set",
            "laplacian=xu-jin", "--set", "l0=1/20", "--set", "dt_check=false", "--out",
            str(ro / "out")]
    if os.geteuid() == 0:
        if shutil.which("unshare") is None:
            pytest.skip("root without unshare: no way to make a folder read-only")
        script = f'mount -t tmpfs -o ro tmpfs "{ro}" && exec "$0" "$@"'
        cmd = ["unshare", "--mount", "sh", "-c", script, sys.executable, *args]
    else:
        ro.chmod(0o555)
        cmd = [sys.executable, *args]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if os.geteuid() == 0 and "mount" in out.stderr and out.returncode != 2:
        pytest.skip(f"cannot mount here: {out.stderr.strip()}")
    assert out.returncode == 2, out.stderr
    last = out.stderr.splitlines()[-1]
    assert last.startswith(f"mpsbench validate: error: --out {ro / 'out'}: cannot create the "
                           "folder: "), last
    assert last.endswith(("Read-only file system", "Permission denied")), last
    assert "Traceback" not in out.stderr
    assert list(ro.iterdir()) == []


# --------------------------------------------------------------------------- size guard


@pytest.mark.parametrize("name", ["diffusion", "couette", "water-jet", "dam-break",
                                  "hydrostatic", "poiseuille", "taylor-green", "cavity"])
def test_estimates_agree_with_the_runs_of_the_smoke_baseline(name: str) -> None:
    """Particles within 10 %, steps within 10 % of what the committed smoke runs did."""
    baseline = Path(__file__).resolve().parents[1] / "validations" / "baselines" / "smoke"
    records = [r for r in json.loads((baseline / "results.json").read_text())
               if r["case"] == name]
    case = get_case(name)
    assert records
    for rec in records:
        params = {p.name: rec.get(p.name, p.default) for p in case.params}
        est = case.estimate(params)
        assert est is not None
        assert abs(est.particles / rec["n_particles"] - 1) < 0.1, (rec["run_id"], est)
        assert est.steps is not None
        assert abs(est.steps / rec["n_steps"] - 1) < 0.1, (rec["run_id"], est)
        assert est.solver_runs == rec["n_solver_runs"]
        assert not est.dt_too_large


def test_the_diffusion_dt_limit_is_the_operators_own() -> None:
    """2 / (kappa rho), rho the largest |eigenvalue| of the matrix the reference backend
    assembles (the Fourier symbol on the lattice gives it exactly)."""
    import numpy as np
    from mpsbench.solvers.reference import ReferenceSolver
    from mpsbench.validations.diffusion.case import KAPPA, DiffusionCase

    case = get_case("diffusion")
    assert isinstance(case, DiffusionCase)
    for lap, wf, re, l0 in (("khayyer-gotoh", "wf1", 2.1, 1 / 20), ("xu-jin", "wf2", 3.1, 1 / 20),
                            ("koshizuka-oka", "wf1", 4.0, 1 / 16)):
        params = {**case.defaults(), "laplacian": lap, "weight": wf, "re_ratio": re, "l0": l0}
        solver = ReferenceSolver()
        solver.setup(case.build(params))
        rho = float(np.abs(np.linalg.eigvals(solver.matrix.toarray())).max())
        assert case.estimate(params).dt_limit == pytest.approx(2.0 / (KAPPA * rho), rel=1e-9)


def test_a_fixed_dt_above_the_limit_is_refused_and_is_unstable() -> None:
    from mpsbench.validations.diffusion.case import DiffusionCase

    from mpsbench.run.runner import run

    case = get_case("diffusion")
    assert isinstance(case, DiffusionCase)
    params = {**case.defaults(), "laplacian": "khayyer-gotoh", "re_ratio": 2.1, "l0": 1 / 40}
    limit = case.estimate(params).dt_limit
    assert limit is not None

    def task(dt: float) -> list[Task]:
        return [Task("diffusion", "reference", "smoke", {**params, "dt": dt}, "r")]

    with pytest.raises(UsageError, match="above the explicit stability limit"):
        check_plan(estimate_plan(task(1.01 * limit)))
    check_plan(estimate_plan(task(0.99 * limit)))
    # the refusal is not hypothetical: above the limit the run blows up, below it does not
    above = run("reference", case.build({**params, "dt": 2.0 * limit}), end_time=1.0)
    assert above.status.value == "diverged", above.reason
    below = run("reference", case.build({**params, "dt": 0.9 * limit}), end_time=1.0)
    assert below.status.value == "completed", below.reason


def test_size_thresholds_and_memory() -> None:
    case = get_case("diffusion")
    big = {**case.defaults(), "l0": 1 / 1100, "dt": 1e-6}
    tasks = [Task("diffusion", "reference", "smoke", big, "big")]
    est = estimate_plan(tasks)
    assert est.largest()[1].particles == 1100**2 > MAX_PARTICLES  # type: ignore[index]
    with pytest.raises(UsageError, match="give --yes"):
        check_plan(est, memory=2**40)
    check_plan(est, yes=True, memory=2**40)
    with pytest.raises(UsageError, match="more than this machine's"):
        check_plan(est, yes=True, memory=2**30)
    # several at once: the guard names the --jobs that fit
    small = {**case.defaults(), "l0": 1 / 400}
    many = [Task("diffusion", "reference", "smoke", {**small, "seed": k}, f"r{k}")
            for k in range(4)]
    one = estimate_plan(many).largest()[1].memory_bytes  # type: ignore[index]
    with pytest.raises(UsageError, match="use --jobs 2"):
        check_plan(estimate_plan(many), jobs=4, memory=int(2.5 * one))


# --------------------------------------------------------------------------- reports


@pytest.fixture
def toys_folder(tmp_path: Path) -> Iterator[Path]:
    with only_cases(ToyDiffusion(), ToyCounter()):
        out = tmp_path / "r"
        assert validate("all", "--tier", "smoke", "--out", str(out), "--jobs", "1") == 0
        yield out


def test_records_of_an_unknown_case_without_checks_fail(toys_folder: Path) -> None:
    folder = toys_folder / "nosuchcase"
    shutil.copytree(toys_folder / "toy-counter" / "runs", folder / "runs")
    for path in (folder / "runs").glob("*.json"):
        rec = json.loads(path.read_text())
        rec["case"] = "nosuchcase"
        path.write_text(json.dumps(rec))
    assert cli.main(["report", str(toys_folder)]) == 0
    summary = (toys_folder / "summary.md").read_text()
    assert "## nosuchcase (`nosuchcase`): FAIL" in summary
    assert "nothing decides pass or fail" in summary
    assert "FAIL (2/3 cases pass)" in summary


def test_hostile_text_is_escaped_and_links_are_defused(tmp_path: Path) -> None:
    from tests.test_hostile import LinkCase

    evil = "[click](javascript:alert(1)) <img src=x onerror=alert(1)>"
    with only_cases(LinkCase()):
        out = tmp_path / "r"
        assert validate("hostile-links", "--tier", "smoke", "--set", f"label={evil}",
                        "--out", str(out)) == 0
        manifest = json.loads((out / "manifest.json").read_text())
        manifest["tier"] = "[x](javascript:alert(2))"
        (out / "manifest.json").write_text(json.dumps(manifest))
        assert cli.main(["report", str(out)]) == 0
    page = (out / "index.html").read_text()
    assert "javascript:alert" in page  # shown as text ...
    assert 'href="javascript' not in page.lower() and "<img" not in page  # ... never live
    for name in ("summary.md", "report.md", "findings.md"):
        text = (out / name).read_text()
        assert "<img" not in text and "&lt;img" in text, name
        assert "](javascript" not in text.replace("\\](javascript", ""), name


def test_compare_flags_a_gated_metric_the_baseline_has_no_value_for(
        toys_folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    records = json.loads((toys_folder / "results.json").read_text())
    for rec in records:
        if "l2_error" in rec:
            rec["l2_error"] = None
    base = tmp_path / "base.json"
    base.write_text(json.dumps(records))
    assert cli.main(["compare", str(base), str(toys_folder), "--markdown", "-"]) == 0
    out = capsys.readouterr().out
    assert "2 not held (no baseline value)" in out
    assert "unheld" in out and "no baseline value: not held" in out


def test_run_ids_stay_filesystem_safe() -> None:
    ids = run_ids("c", "s", [{"label": "../../x"}, {"label": ".hidden/.."}], {"label": "a"})
    for rid in ids:
        assert "/" not in rid and ".." not in rid and not rid.startswith(".")


def test_a_line_starting_with_a_hash_is_a_paragraph_not_a_hang() -> None:
    from mpsbench.results.html import markdown_html

    assert markdown_html("#tag\n\n####### x") == "<p>#tag</p>\n<p>####### x</p>"


def test_a_plugin_name_that_would_climb_out_of_a_folder_is_ignored(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from types import SimpleNamespace

    import mpsbench.registry as registry_module
    from mpsbench.registry import Registry

    def entry_points(*, group: str) -> list[SimpleNamespace]:
        dist = SimpleNamespace(name="evil-dist")
        return [SimpleNamespace(name=n, value="mpsbench.solvers.reference:ReferenceSolver",
                                dist=dist) for n in ("../../x", "a/b", ".hidden", "fine-name")]

    monkeypatch.setattr(registry_module, "entry_points", entry_points)
    reg: Registry[Any] = Registry("solver", group="mpsbench.solvers")
    assert reg.names() == ["fine-name"]
    ignored = {e.name: e.error for e in reg.ignored}
    assert set(ignored) == {"../../x", "a/b", ".hidden"}
    assert all("the name is not allowed" in str(why) for why in ignored.values())


@pytest.mark.parametrize(("case", "value", "allowed"), [
    ("taylor-green", "0.03", "whole number"), ("couette", "3e-5", "whole number"),
    ("cavity", "0.07", "whole number"), ("diffusion", "0.03", "whole number"),
    ("poiseuille", "3e-5", "whole number"), ("water-jet", "0.03", "whole multiple")])
def test_a_spacing_the_case_refuses_stops_before_any_run(
        case: str, value: str, allowed: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The case's own check (L / l0 a whole number) is bad input like a parameter's bounds:
    exit 2 with the parameter, the value and what is allowed, and no run recorded."""
    out = tmp_path / "r"
    assert cli.main(["validate", case, "--tier", "smoke", "--set", f"l0={value}",
                     "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"case {case}: " in err and allowed in err and "l0" in err
    assert not (out / "runs").exists()
