"""The external-executable adapter (``external:program=PATH``, docs/external-solvers.md) with a
real separate program: ``tests/external/mini_mps.py``, a standalone viscous MPS code that does
not import mpsbench, run as a subprocess through the file protocol.

Held against the reference backend on the same model (Koshizuka-Oka Laplacian, WF1, r_e/l0 =
3.1; the program's own time step): the start-up Couette errors against the series solution
agree, end to end through ``mpsbench validate`` (records, the unsupported mirror run, the
cross-code table).  Failure paths: a refusal by the program, a program that dies, a program
that does not exist.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest
from mpsbench.validations.couette.metrics import SMOKE_DRIFT

from mpsbench.cli import main
from mpsbench.results.records import load_records
from mpsbench.run.protocol import Status
from mpsbench.run.runner import run
from mpsbench.testing.problems import periodic_flow_problem

PROGRAM = Path(__file__).parent / "external" / "mini_mps.py"
SPEC = f"external:program={PROGRAM}"


def test_the_program_stands_alone() -> None:
    imports = [line for line in PROGRAM.read_text().splitlines()
               if line.startswith(("import ", "from "))]
    assert imports and not [line for line in imports if "mpsbench" in line]


def test_couette_through_the_protocol_agrees_with_the_reference(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    code = main(["validate", "couette", "--tier", "smoke", "--solver", SPEC,
                 "--solver", "reference", "--set", "l0=5e-05", "--set", "laplacian=koshizuka-oka",
                 "--set", "weight=wf1", "--set", "steady=false", "--set", "dt_check=false",
                 "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.out + captured.err
    recs = load_records(out)
    ext = [r for r in recs if r["solver"] == "external"]
    ref = [r for r in recs if r["solver"] == "reference"]
    status = {(r["wall_velocity"], r["drift"]): r["status"] for r in ext}
    # mirrored wall velocities are not declared: refused with the reason, not failed
    assert status == {("prescribed", 0.0): "completed", ("mirror", 0.0): "unsupported",
                      ("prescribed", SMOKE_DRIFT): "completed"}
    (e,) = [r for r in ext if r["status"] == "completed" and r["drift"] == 0]
    (f,) = [r for r in ref if r["wall_velocity"] == "prescribed" and r["drift"] == 0]
    (moving,) = [r for r in ext if r["drift"] > 0]
    # every particle crossed the periodic edges once: the program wraps them, the profile holds
    assert abs(moving["l2_error"] - e["l2_error"]) < 1e-6 * e["l2_error"]
    assert set(e["not_applicable"].split(",")) == {"c_nu", "laplacian", "re_ratio", "weight"}
    # same model, each its own time step: the errors against the series solution agree to a
    # few per cent of their size (both ~2 % at L/20; a Laplacian 10 % off moves it by ~50 %)
    assert 0.01 < f["l2_error"] < 0.03
    assert abs(e["l2_error"] - f["l2_error"]) < 0.05 * f["l2_error"], (e["l2_error"],
                                                                       f["l2_error"])
    assert abs(e["linf_error"] - f["linf_error"]) < 0.05 * f["linf_error"]
    assert e["n_steps"] > 100 and e["particle_steps_per_s"] > 0  # the program's own steps
    table = pd.read_csv(out / "cross-code.csv")
    assert set(table["solver"]) == {SPEC, "reference"}
    assert "own kernel" in set(table["models"])
    assert "cross-code" in (out / "summary.md").read_text()
    assert "unsupported" in captured.out


def test_a_problem_the_program_refuses_is_unsupported_with_its_reason() -> None:
    # with gravity: mini_mps has no pressure solver and says so
    problem = periodic_flow_problem(n_side=6, gravity=(0.0, -9.81))
    res = run(SPEC, problem, end_time=1e-3)
    assert res.status == Status.UNSUPPORTED
    assert "no pressure solver" in res.reason


def test_a_program_that_dies_fails_the_run_with_its_stderr(tmp_path: Path) -> None:
    prog = tmp_path / "dies.py"
    prog.write_text("import sys\nsys.stdin.readline()\nprint('ready', flush=True)\n"
                    "sys.stdin.readline()\nprint('out of memory in step 3', file=sys.stderr)\n"
                    "sys.exit(3)\n")
    problem = periodic_flow_problem(n_side=6)
    res = run(f"external:program={prog}", problem, end_time=1e-3)
    assert res.status == Status.FAILED
    assert "exit status 3" in res.reason and "out of memory in step 3" in res.reason


def test_a_missing_program_fails_setup(tmp_path: Path) -> None:
    res = run(f"external:program={tmp_path / 'nope'}", periodic_flow_problem(n_side=6),
              end_time=1e-3)
    assert res.status == Status.FAILED and "not found" in res.reason


def test_the_python_running_the_script_is_this_one() -> None:
    from mpsbench.solvers.external import ExternalSolver

    assert ExternalSolver(program=str(PROGRAM))._command() == [sys.executable, str(PROGRAM)]
