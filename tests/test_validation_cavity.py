"""The lid-driven cavity case (issue 17): profile errors against the tables, the build (a
sliding lid), gates on constructed records, the smoke tier end to end on the reference
backend."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from mpsbench.validations.cavity import analysis as ca
from mpsbench.validations.cavity import case as cc
from mpsbench.validations.cavity import metrics as cm

from mpsbench import cli
from mpsbench.errors import ConfigError
from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind


# --------------------------------------------------------------------------- metrics
def test_the_tables_themselves_have_no_error_and_an_offset_is_measured() -> None:
    g = cm.ghia_points(100)
    assert len(g["u"][0]) == 15 and len(g["v"][0]) == 15  # 17 rows minus the two walls
    m = cm.profile_errors(g["u"][1], g["v"][1], 100)
    assert m["rms_error"] == 0.0 and m["max_error"] == 0.0
    m = cm.profile_errors(g["u"][1] + 0.1, g["v"][1], 100)
    assert m["u_rms_error"] == pytest.approx(0.1) and m["v_rms_error"] == 0.0
    assert m["rms_error"] == pytest.approx(0.1 / math.sqrt(2))
    # a flow that does not feel the lid: the tables' own RMS (the gate's reasoning), from
    # Ghia's table I and II values typed in here (not through the loader)
    u = [0.84123, 0.78871, 0.73722, 0.68717, 0.23151, 0.00332, -0.13641, -0.20581, -0.21090,
         -0.15662, -0.10150, -0.06434, -0.04775, -0.04192, -0.03717]
    v = [-0.05906, -0.07391, -0.08864, -0.10313, -0.16914, -0.22445, -0.24533, 0.05454,
         0.17527, 0.17507, 0.16077, 0.12317, 0.10890, 0.10091, 0.09233]
    zero = cm.profile_errors(np.zeros(15), np.zeros(15), 100)
    assert zero["rms_error"] == pytest.approx(math.sqrt(np.mean(np.square(u + v))), rel=1e-12)
    assert zero["u_rms_error"] == pytest.approx(0.4122, abs=1e-4)
    assert zero["rms_error"] > 2.5 * ca.RMS_MAX
    assert math.isnan(cm.profile_errors(np.full(15, np.nan), g["v"][1], 100)["rms_error"])


def test_sample_points_and_split() -> None:
    pts = cm.sample_points(100)
    assert pts.shape == (30, 2)
    assert np.all(pts[:15, 0] == 0.5) and np.all(pts[15:, 1] == 0.5)
    u, v = cm.split(np.arange(30.0), 100)
    assert list(u) == list(range(15)) and list(v) == list(range(15, 30))


def test_window_mean_and_unsteadiness() -> None:
    t = np.linspace(0.0, 10.0, 101)
    samples = np.where(t[:, None] < 6.0, 1.0, 2.0) * np.ones((101, 3))
    np.testing.assert_allclose(cm.window_mean(t, samples, 10.0), [2.0, 2.0, 2.0])
    assert cm.unsteadiness(t, samples, 10.0) == pytest.approx(0.0)  # same over [6, 8], [8, 10]
    drifting = t[:, None] * np.ones((101, 3))
    assert cm.unsteadiness(t, drifting, 10.0) == pytest.approx(2.0, rel=0.05)


# --------------------------------------------------------------------------- build
def test_build_has_a_sliding_lid_and_closed_walls() -> None:
    problem = cc.build({**cc.CASE.defaults(), "l0": 0.05})
    p = problem.particles
    fluid = p.kind == Kind.FLUID
    assert fluid.sum() == 400
    lid = p.fields["wall_tag"] == cc.LID_TAG
    assert np.all(p.pos[lid, 1] > 1.0) and np.all(p.vel[lid] == [1.0, 0.0])
    (motion,) = problem.wall_motions
    assert motion.displace is False and motion.tag == cc.LID_TAG
    assert "sliding-walls" in problem.requirements()["boundaries"]
    assert isinstance(problem.physics, FlowPhysics)
    assert problem.physics.nu == pytest.approx(0.01)
    with pytest.raises(ConfigError, match="l0 = 0.03"):
        cc.build({**cc.CASE.defaults(), "l0": 0.03})


def test_estimate_counts_the_particles_of_the_build() -> None:
    params = {**cc.CASE.defaults(), "l0": 0.05}
    assert cc.CASE.estimate(params).particles == cc.build(params).particles.n


def test_an_outside_code_is_not_applicable() -> None:
    from mpsbench.solvers.external import CAPABILITIES

    gaps = CAPABILITIES.gaps(cc.build({**cc.CASE.defaults(), "l0": 0.05}))
    assert any("sliding-walls" in g for g in gaps)


# --------------------------------------------------------------------------- gates
def record(n: int = 40, **metrics: Any) -> dict[str, Any]:
    base = {**cc.CASE.defaults(), "l0": 1.0 / n, "case": "cavity", "solver": "reference",
            "tier": "quick", "status": "completed", "run_id": f"run-{n}-{len(metrics)}",
            "rms_error": 0.05, "u_rms_error": 0.06, "v_rms_error": 0.03, "max_error": 0.1,
            "unsteadiness": 0.01, "u_min": -0.17, "particles_lost": 0, "n_side": n}
    return {**base, **metrics}


def test_gates_on_constructed_records() -> None:
    profile, lost = ca.gates([record()])
    assert profile.passed is True and lost.passed is True
    profile, _ = ca.gates([record(rms_error=0.12)])
    assert profile.passed is False
    _, lost = ca.gates([record(particles_lost=2)])
    assert lost.passed is False
    # the profile gate holds N = 40 over >= 8 s only: a coarse or short run is no failure
    profile, _ = ca.gates([record(20, rms_error=0.2), record(40, end_time=5.0, rms_error=0.2)])
    assert profile.passed is None


# --------------------------------------------------------------------------- end to end
def test_smoke_tier_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "smoke"
    args = ["validate", "cavity", "--tier", "smoke", "--solver", "reference", "--out", str(out)]
    assert cli.main(args) == 0
    df = pd.read_csv(out / "results.csv")
    assert len(df) == 1 and (df["status"] == "completed").all()
    for col in cc.METRICS:
        assert col in df.columns, col
    r = df.iloc[0]
    # after 5 s at N = 20 the vortex has formed: closer to the tables than no flow (0.29 U),
    # not yet within the N = 40 gate's reach
    assert 0.05 < r["rms_error"] < 0.25 and r["u_min"] < -0.05 and r["particles_lost"] == 0
    checks = json.loads((out / "checks.json").read_text())
    assert [c["passed"] for c in checks if c["kind"] == "gate"] == [None, True]
    assert (out / "figures" / "profiles_N-20_Re-100.png").exists()
    assert (out / "tables" / "runs.csv").exists()
