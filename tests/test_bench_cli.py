"""``mpsbench bench``: records, table and usage errors (a small n keeps it to seconds)."""

from __future__ import annotations

import json

import pytest

from mpsbench.cli import main
from mpsbench.testing.bench import RECORD_FIELDS, spacing_for, workload

pytest.importorskip("numba")

REQUIRED = (
    "solver", "n", "step_ms", "rebuild_ms", "particle_steps_per_s", "speedup_vs_reference",
    "threads", "jit_compile_s", "cpu_ms_per_step",
)


def test_bench_json_records(capsys):
    assert main(["bench", "--n", "2000", "--steps", "4", "--json"]) == 0
    records = json.loads(capsys.readouterr().out)
    assert [r["solver"] for r in records] == ["reference", "numba"]
    for r in records:
        assert set(REQUIRED) <= set(r) and list(r)[: len(RECORD_FIELDS)] == list(RECORD_FIELDS)
        assert 1500 <= r["n"] <= 2500
        assert r["step_ms"] > 0 and r["particle_steps_per_s"] > 0
        assert r["threads"] >= 1 and r["jit_compile_s"] >= 0
    ref, nb = records
    assert ref["n"] == nb["n"]  # the same problem for both
    assert ref["speedup_vs_reference"] == 1.0
    assert nb["speedup_vs_reference"] == pytest.approx(
        nb["particle_steps_per_s"] / ref["particle_steps_per_s"]
    )
    assert nb["rebuild_method"] == "direct" and nb["rebuild_ms"] > 0


def test_bench_table(capsys):
    assert main(["bench", "--solver", "numba", "--n", "1000", "--steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "speed-up" in out and "numba" in out and "reference" in out


@pytest.mark.parametrize(
    "argv,message",
    [
        (["bench", "--n", "10"], "--n 10 is not allowed"),
        (["bench", "--steps", "0"], "--steps 0 is not allowed"),
        (["bench", "--solver", "nope"], "unknown solver 'nope'"),
    ],
)
def test_bench_usage_errors(capsys, argv, message):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_workload_size():
    for n in (2_000, 40_000):
        assert abs(workload(l0=spacing_for(n)).particles.n - n) < 0.03 * n
    with pytest.raises(ValueError, match="n = 3"):
        spacing_for(3)
