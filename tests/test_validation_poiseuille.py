"""The Poiseuille case (issue 17): profile metrics against the series solution, geometry, gates
on constructed records, the smoke tier end to end on the reference backend."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from mpsbench.validations.poiseuille import analysis as pa
from mpsbench.validations.poiseuille import case as pc
from mpsbench.validations.poiseuille import metrics as pm

from mpsbench import cli
from mpsbench.errors import ConfigError
from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind

L = pm.L


def test_profile_metrics_of_the_exact_and_a_bumped_profile() -> None:
    rows = L / 40 * np.arange(1, 40)
    exact = np.array([pm.FLOW.velocity(rows, t) for t in pm.TIMES])
    m = pm.profile_metrics(rows, exact)
    assert m["l2_error"] == 0.0 and m["linf_error"] == 0.0 and m["centreline_error"] == 0.0
    bumped = exact.copy()
    bumped[-1] *= 1.02  # 2 % everywhere at the last time
    m = pm.profile_metrics(rows, bumped)
    assert m["l2_error"] == pytest.approx(0.02, rel=1e-12)
    assert m["centreline_error"] == pytest.approx(0.02, rel=1e-12)
    assert m[pm.time_key(pm.TIMES[0])] == 0.0
    assert pm.steady_error(rows, 0.99 * pm.FLOW.steady(rows)) == pytest.approx(0.01, rel=1e-12)


@pytest.mark.parametrize("wall_row", ["on-plate", "offset"])
def test_geometry_and_body_force(wall_row: str) -> None:
    problem, rows = pc.build({**pc.CASE.defaults(), "wall_row": wall_row})
    p = problem.particles
    fluid = p.pos[p.kind == Kind.FLUID]
    assert np.allclose(np.unique(np.round(fluid[:, 1], 12)), rows)
    assert len(rows) == (39 if wall_row == "on-plate" else 40)
    assert isinstance(problem.physics, FlowPhysics)
    assert problem.physics.gravity == (pm.F, 0.0)
    assert not np.any(p.vel)  # at rest, plates too
    assert problem.box.periodic == (True, False) and not problem.wall_motions
    assert "periodic-x" in problem.requirements()["boundaries"]


def test_l0_must_divide_the_gap() -> None:
    with pytest.raises(ConfigError, match="l0"):
        pc.build({**pc.CASE.defaults(), "l0": 3e-5})


def test_tiers_hold_the_headline_cell_and_its_refinement_set() -> None:
    quick = pc.CASE.expand("quick")
    head = [r for r in quick if r["laplacian"] == "xu-jin" and r["wall_velocity"] == "prescribed"]
    assert sorted(round(L / r["l0"]) for r in head) == [10, 20, 40]
    model = pc.CASE.model_records([{**r, "tier": "quick"} for r in quick])
    assert all(round(L / r["l0"]) != 10 for r in model)


def record(n: int, model: str = "xu-jin", error: float = 0.005, **extra: Any) -> dict[str, Any]:
    return {**pc.CASE.defaults(), "laplacian": model, "l0": L / n, "l2_error": error,
            "case": "poiseuille", "solver": "reference", "tier": "quick", "status": "completed",
            "run_id": f"{model}-{n}", "l2_error_steady": float("nan"), **extra}


def test_gates_on_constructed_records() -> None:
    good = [record(20, error=0.006), record(40, error=0.003),
            record(20, "koshizuka-oka", 0.017), record(40, "koshizuka-oka", 0.009)]
    assert [g.passed for g in pa.gates(good)] == [True, True]
    big = [record(20, error=0.02), record(40, error=0.011)]
    best, reduction = pa.gates(big)
    assert best.passed is False and reduction.passed is True
    stuck = [record(20, error=0.006), record(40, error=0.005)]
    assert pa.gates(stuck)[1].passed is False  # 1.2x: not first order
    assert all(g.passed is None for g in pa.gates([record(20, "khayyer-gotoh", 0.4)]))


def test_smoke_tier_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "smoke"
    assert cli.main(["validate", "poiseuille", "--tier", "smoke", "--out", str(out)]) == 0
    df = pd.read_csv(out / "results.csv")
    assert len(df) == len(pc.CASE.expand("smoke")) and (df["status"] == "completed").all()
    for col in pc.METRICS:
        assert col in df.columns, col
    checks = json.loads((out / "checks.json").read_text())
    gates = [c for c in checks if c["kind"] == "gate"]
    assert len(gates) == 2 and all(c["passed"] is True for c in gates)
    conv = pd.read_csv(out / "tables" / "convergence.csv")
    row = conv[(conv["model"] == "xu-jin") & (conv["wall_velocity"] == "prescribed")].iloc[0]
    assert 0.6 < row["observed_order"] < 1.5  # first order at prescribed walls
    assert (out / "figures" / "profiles_L-40.png").exists()
    assert "Observed order in l0" in (out / "report.md").read_text()
