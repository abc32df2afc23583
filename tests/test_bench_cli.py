"""``mpsbench bench``: interleaved rounds, medians and ratios, history, PySPH, usage errors.

Real backends run at n ~ 1-2k for a few rounds (seconds); the scheduling (order of blocks,
freeing the cold start, the budget, the ratios) is checked on toy contenders that log what
happens to them.
"""

from __future__ import annotations

import json
import subprocess
import sys
import weakref
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mpsbench.cli import main
from mpsbench.commands import bench as command
from mpsbench.results import bench_history
from mpsbench.results.records import ENV_COLUMNS
from mpsbench.testing import bench
from mpsbench.testing.bench import RECORD_FIELDS, Contender, run_size, spacing_for, workload

pytest.importorskip("numba")

L0 = spacing_for(600)


class Toy:
    """A stepper that logs its steps; ``dt`` fixed, ``work`` sleeps-free busy loops."""

    def __init__(self, label: str, log: list[tuple[str, str]], dt: float, work: int) -> None:
        self.label, self.log, self.dt, self.work = label, log, dt, work
        self.steps = 0

    def setup(self, problem: Any) -> None:
        self.log.append((self.label, "setup"))

    def stable_dt(self) -> float:
        return self.dt

    def step(self, dt: float) -> None:
        self.steps += 1
        self.log.append((self.label, "step"))
        float(np.sum(np.arange(self.work)))  # some real work, so the blocks take time


def toy(label: str, log: list[tuple[str, str]], made: list[Any], dt: float = 1e-4,
        work: int = 20_000) -> Contender:
    def make() -> Toy:
        t = Toy(label, log, dt, work)
        made.append(weakref.ref(t))
        weakref.finalize(t, log.append, (label, "freed"))
        return t

    return Contender(label, make)


def test_rounds_interleave_and_the_cold_start_is_freed_first() -> None:
    log: list[tuple[str, str]] = []
    made: list[Any] = []
    recs = run_size([toy("A", log, made), toy("B", log, made)], L0, steps=3, repeat=4,
                    warmup=2)
    assert [r.rounds for r in recs] == [4, 4] and [len(r.block_wall_s) for r in recs] == [4, 4]
    # cold A (setup + first step), freed; warm A (setup, first step, 2 warm-up); same for B
    assert log[:2] == [("A", "setup"), ("A", "step")] and log[2] == ("A", "freed")
    start = log.index(("B", "freed")) + 1 + 4  # B's warm setup, first step, 2 warm-up steps
    assert log.index(("A", "freed")) < log.index(("B", "setup"))
    timed = [label for label, what in log[start:] if what == "step"]
    assert timed == (["A"] * 3 + ["B"] * 3) * 4  # A B A B ..., blocks of 3 steps
    assert made[0]() is None and made[2]() is None  # both cold instances are gone


def test_block_steps_make_the_fastest_block_last_block_s() -> None:
    assert bench.block_steps(2.5e-3) == 100  # numba at 10k: 0.25 s / 2.5 ms
    assert bench.block_steps(0.1) == bench.DEFAULT_STEPS  # slow steps: never fewer than 20
    assert bench.block_steps(1e-9) == bench.MAX_BLOCK_STEPS
    assert bench.block_steps(0.0) == bench.MAX_BLOCK_STEPS  # a step below the clock's grain
    assert bench.block_steps(bench.BLOCK_S / 37.5) == 38  # rounded up: at least BLOCK_S


def test_blocks_are_sized_by_the_fastest_contenders_warm_up(
        monkeypatch: pytest.MonkeyPatch) -> None:
    log: list[tuple[str, str]] = []
    made: list[Any] = []
    seen: list[float] = []

    def sized(step_s: float) -> int:
        seen.append(step_s)
        return 7

    monkeypatch.setattr(bench, "block_steps", sized)
    recs = run_size([toy("slow", log, made, work=400_000), toy("fast", log, made)], L0,
                    repeat=2, warmup=2)
    assert [r.steps for r in recs] == [7, 7]
    timed = [label for label, what in log if what == "step"][-28:]
    assert timed == (["slow"] * 7 + ["fast"] * 7) * 2
    # the step time handed over is the fast toy's, well below the slow one's
    per_step = [w / 7 for w in recs[0].block_wall_s]
    assert len(seen) == 1 and seen[0] < 0.5 * min(per_step)


def test_budget_sets_the_rounds_and_ratios_come_from_the_same_rounds() -> None:
    log: list[tuple[str, str]] = []
    made: list[Any] = []
    fast, slow = toy("fast", log, made, dt=2e-4), toy("slow", log, made, work=80_000)
    recs = run_size([slow, fast], L0, steps=2, budget=0.3)
    s, f = recs
    walls = np.array([s.block_wall_s, f.block_wall_s])
    # the rounds went on until the blocks had taken the budget, and no round longer
    assert s.rounds >= bench.MIN_ROUNDS and walls.sum() >= 0.3
    assert s.rounds == bench.MIN_ROUNDS or walls[:, :-1].sum() < 0.3
    # medians over blocks, ratios per round to the first contender (here: slow)
    n = s.n
    assert s.particle_steps_per_s == pytest.approx(np.median(n * 2 / walls[0]))
    assert s.particle_steps_per_s_q1 <= s.particle_steps_per_s <= s.particle_steps_per_s_q3
    assert s.particle_steps_per_s_min <= s.particle_steps_per_s_q1
    assert s.speedup_vs_first == 1.0 and s.first_solver == f.first_solver == "slow"
    assert f.speedup_vs_first == pytest.approx(np.median(walls[0] / walls[1]))
    assert f.speedup_min <= f.speedup_q1 <= f.speedup_vs_first <= f.speedup_q3 <= f.speedup_max
    # fast takes steps twice as long in simulated time: it reaches the same t twice as soon
    assert f.dt_mean == pytest.approx(2e-4) and s.dt_mean == pytest.approx(1e-4)
    assert f.time_to_solution_speedup == pytest.approx(2 * f.speedup_vs_first)
    assert f.rebuild_method == "none" and f.rebuilds_per_step is None  # no counters


def test_bench_json_records_and_environment(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--n", "2000", "--steps", "4", "--repeat", "3", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    env = doc["environment"]
    assert set(ENV_COLUMNS) - {"solver_commit"} <= set(env)
    assert set(env["solvers"]) == {"reference", "numba"}
    assert doc["settings"]["repeat"] == 3 and doc["settings"]["sizes"] == [2000]
    records = doc["records"]
    assert [r["solver"] for r in records] == ["reference", "numba"]  # the reference first
    for r in records:
        assert list(r)[: len(RECORD_FIELDS)] == list(RECORD_FIELDS)
        assert 1500 <= r["n"] <= 2500 and r["rounds"] == 3 and len(r["block_wall_s"]) == 3
        assert r["particle_steps_per_s"] == pytest.approx(
            np.median([r["n"] * 4 / w for w in r["block_wall_s"]]))
        assert r["threads"] >= 1 and r["jit_compile_s"] >= 0 and r["dt_mean"] > 0
        assert r["solver_version"] == env["solvers"][r["solver"]]["solver_version"]
        assert r["solver_commit"] == env["solvers"][r["solver"]]["solver_commit"]
    ref, nb = records
    assert ref["n"] == nb["n"]  # the same problem for both
    assert ref["speedup_vs_first"] == 1.0 and nb["first_solver"] == "reference"
    assert nb["speedup_vs_first"] == pytest.approx(
        np.median(np.array(ref["block_wall_s"]) / np.array(nb["block_wall_s"])))
    assert nb["rebuild_method"] == "direct" and nb["rebuild_ms"] > 0


def test_bench_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--solver", "numba", "--solver", "reference", "--n", "1000",
                 "--steps", "2", "--repeat", "2"]) == 0
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if ln.startswith(("numba ", "reference "))]
    assert [ln.split()[0] for ln in lines] == ["numba", "reference"]  # ratios to numba
    assert "1.00x [1.00-1.00]" in lines[0] and "speed-up" in out


def test_bench_table_columns_line_up_with_long_specs(capsys: pytest.CaptureFixture[str]) -> None:
    long = "numba:threads=1,vectorize=true"
    assert main(["bench", "--solver", "numba:threads=1", "--solver", long, "--n", "1000",
                 "--steps", "2", "--repeat", "2"]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("numba")]
    assert len(lines) == 2
    # the particle count starts in the same column on both lines
    cols = {ln.index(" 1", len(ln.split()[0])) for ln in lines}
    assert len(cols) == 1, lines


def test_save_then_compare(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    storage = tmp_path / "hist"
    args = ["bench", "--solver", "reference", "--n", "1000", "--steps", "2", "--repeat", "3",
            "--storage", str(storage)]
    assert main([*args, "--compare"]) == 2  # nothing saved yet
    assert "no saved 'mpsbench bench' run" in capsys.readouterr().err
    assert main([*args, "--save"]) == 0
    files = list((storage / bench_history.machine_id()).glob("0001_*.json"))
    assert len(files) == 1
    saved = json.loads(files[0].read_text())
    assert {"machine_info", "commit_info", "benchmarks", "mpsbench_bench"} <= set(saved)
    assert saved["benchmarks"][0]["name"].startswith("bench[reference-")
    assert saved["benchmarks"][0]["stats"]["rounds"] == 3
    # a saved run ten times faster than this machine can do: the comparison says slower
    for rec in saved["mpsbench_bench"]["records"]:
        for key in ("particle_steps_per_s", "particle_steps_per_s_q1",
                    "particle_steps_per_s_q3"):
            rec[key] *= 10
    files[0].write_text(json.dumps(saved))
    capsys.readouterr()
    assert main([*args, "--compare", "1", "--save"]) == 1
    out = capsys.readouterr().out
    assert "SLOWER" in out and "now/saved" in out
    assert len(list((storage / bench_history.machine_id()).glob("000[12]_*.json"))) == 2
    # and one ten times slower: no slowdown (the threshold is a fraction, 0.95 is allowed)
    for rec in saved["mpsbench_bench"]["records"]:
        for key in ("particle_steps_per_s", "particle_steps_per_s_q1",
                    "particle_steps_per_s_q3"):
            rec[key] /= 100
    files[0].write_text(json.dumps(saved))
    assert main([*args, "--compare", str(files[0]), "--threshold", "0.95"]) == 0
    assert "OK: no figure" in capsys.readouterr().out
    assert main([*args, "--compare", "9"]) == 2
    assert "no run 9" in capsys.readouterr().err


def test_pytest_benchmark_reads_the_history(tmp_path: Path) -> None:
    rec = {"solver": "toy", "n": 1000, "steps": 2, "block_wall_s": [0.1, 0.12, 0.11]}
    path = bench_history.save({"environment": {"git_commit": "abc"}, "records": [rec]},
                              tmp_path)
    assert path.name.startswith("0001_abc_")
    proc = subprocess.run([sys.executable, "-m", "pytest_benchmark", "--storage",
                           f"file://{tmp_path}", "compare", "0001"], capture_output=True,
                          text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "bench[toy-1000]" in proc.stdout


@pytest.mark.slow  # runs one benchmark of the suite (a rebuild at 10k particles)
def test_benchmark_suite_stores_provenance(tmp_path: Path) -> None:
    root = Path(__file__).resolve().parent
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", str(root / "benchmarks" / "test_bench_numba.py"),
         "-k", "neighbour_rebuild and reference and 10k", "--benchmark-only",
         "--benchmark-autosave", f"--benchmark-storage=file://{tmp_path}", "-q",
         "-p", "no:cacheprovider"],
        capture_output=True, text=True, timeout=600, check=False, cwd=root.parent)
    assert proc.returncode == 0, proc.stdout[-2000:]
    (path,) = tmp_path.glob("*/0001_*.json")
    saved = json.loads(path.read_text())
    assert saved["commit_info"]["id"] and "dirty" in saved["commit_info"]
    env = saved["machine_info"]["mpsbench"]
    assert set(ENV_COLUMNS) - {"solver_commit"} <= set(env) and "reference" in env["solvers"]
    assert saved["benchmarks"][0]["extra_info"]["solver"] == "reference"


def test_slowdown_rule() -> None:
    def doc(rate: float, q1: float, q3: float) -> dict[str, Any]:
        return {"records": [{"solver": "s", "n": 1, "particle_steps_per_s": rate,
                             "particle_steps_per_s_q1": q1, "particle_steps_per_s_q3": q3}]}

    saved = doc(100.0, 95.0, 105.0)
    assert not bench_history.compare(saved, doc(92.0, 88.0, 94.0))[0].slowdown  # 8 % down
    assert bench_history.compare(saved, doc(85.0, 80.0, 90.0))[0].slowdown  # 15 %, apart
    assert not bench_history.compare(saved, doc(85.0, 70.0, 97.0))[0].slowdown  # overlapping
    with pytest.raises(bench_history.HistoryError, match="nothing|no solver"):
        bench_history.compare(saved, {"records": [{"solver": "t", "n": 1}]})


def test_pysph_missing_exits_2_with_the_install_hint(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "pysph", None)  # as if not installed: imports fail
    assert main(["bench", "--pysph", "--n", "1000"]) == 2
    err = capsys.readouterr().err
    assert "PySPH is not installed" in err and "pip install pysph" in err
    assert err.count("\n") == 1  # one line, no traceback


@pytest.mark.slow  # the first run of a configuration compiles PySPH's kernels (minutes)
def test_pysph_runs_the_same_particles(capsys: pytest.CaptureFixture[str]) -> None:
    pysph = pytest.importorskip("pysph")
    assert main(["bench", "--solver", "reference", "--pysph", "--pysph-threads", "1",
                 "--n", "1000", "--steps", "3", "--repeat", "3", "--json"]) == 0
    ref, ph = json.loads(capsys.readouterr().out)["records"]
    assert ph["solver"] == "pysph-wcsph" and ph["solver_version"] == pysph.__version__
    assert ph["n"] == ref["n"] and ph["n_fluid"] == ref["n_fluid"] and ph["threads"] == 1
    # PySPH's time step differs from WC-MPS's: the two ratios differ by dt_pysph / dt_ref
    assert ph["time_to_solution_speedup"] == pytest.approx(
        ph["speedup_vs_first"] * ph["dt_mean"] / ref["dt_mean"], rel=0.3)


@pytest.mark.parametrize(
    "argv,message",
    [
        (["bench", "--n", "10"], "--n 10 is not allowed"),
        (["bench", "--steps", "0"], "--steps 0 is not allowed"),
        (["bench", "--budget", "0"], "--budget 0.0 is not allowed"),
        (["bench", "--repeat", "0"], "--repeat 0 is not allowed"),
        (["bench", "--threshold", "1.5", "--compare"], "--threshold 1.5 is not allowed"),
        (["bench", "--pysph-threads", "2"], "--pysph-threads goes with --pysph"),
        (["bench", "--solver", "nope"], "unknown solver 'nope'"),
    ],
)
def test_bench_usage_errors(capsys: pytest.CaptureFixture[str], argv: list[str],
                            message: str) -> None:
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_cli_defaults_are_the_bench_defaults() -> None:
    assert command.DEFAULT_SIZES == bench.DEFAULT_SIZES
    assert command.DEFAULT_BUDGET_S == bench.DEFAULT_BUDGET_S
    assert command.DEFAULT_STEPS == bench.DEFAULT_STEPS
    assert command.BLOCK_S == bench.BLOCK_S


def test_workload_size() -> None:
    for n in (2_000, 40_000):
        assert abs(workload(l0=spacing_for(n)).particles.n - n) < 0.03 * n
    with pytest.raises(ValueError, match="n = 3"):
        spacing_for(3)
