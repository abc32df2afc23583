"""The hydrostatic tank case (issue 17): metrics on constructed samples, gates and the claim on
constructed records, the smoke tier end to end on the reference backend."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from mpsbench.validations.hydrostatic import analysis as ha
from mpsbench.validations.hydrostatic import case as hc
from mpsbench.validations.hydrostatic import metrics as hm
from mpsbench.validations.hydrostatic.reference import RHO0, G

from mpsbench import cli
from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind

H, L0 = 0.3, 0.02


def layers(height: float = H, l0: float = L0) -> np.ndarray:
    return l0 * (np.arange(round(height / l0) + 3) + 0.5)


# --------------------------------------------------------------------------- metrics
def test_exact_profile_gives_zero_errors() -> None:
    y = layers()
    p = np.where(y < H, RHO0 * G * np.clip(H - y, 0.0, None), np.nan)
    m = hm.pressure_metrics(y, p, H, L0, RHO0)
    assert m["floor_pressure_error"] == pytest.approx(0.0, abs=1e-12)
    assert m["pressure_gradient_error"] == pytest.approx(0.0, abs=1e-12)
    assert m["pressure_profile_error"] == pytest.approx(0.0, abs=1e-12)


def test_scaled_and_shifted_profiles() -> None:
    """A 3 % steeper line and a line shifted by 2 % of rho0 g H give those errors; the surface
    layers left out of the fit do not change them."""
    y = layers()
    inside = y < H
    exact = RHO0 * G * (H - y[inside])
    steep = np.full(len(y), np.nan)
    steep[inside] = 1.03 * exact
    steep[inside & (y > H - 3 * L0)] = 0.0  # surface layers at p = 0: not in the fit
    m = hm.pressure_metrics(y, steep, H, L0, RHO0)
    assert m["pressure_gradient_error"] == pytest.approx(0.03, rel=1e-9)
    assert m["floor_pressure_error"] == pytest.approx(0.03, rel=1e-9)
    shifted = np.full(len(y), np.nan)
    shifted[inside] = exact + 0.02 * RHO0 * G * H
    m = hm.pressure_metrics(y, shifted, H, L0, RHO0)
    assert m["floor_pressure_error"] == pytest.approx(0.02, rel=1e-9)
    assert m["pressure_gradient_error"] == pytest.approx(0.0, abs=1e-9)
    assert m["pressure_profile_error"] == pytest.approx(0.02, rel=1e-9)


def test_settling_time() -> None:
    t = np.arange(10) * 0.1
    rms = np.array([0.0, 5, 3, 2, 0.5, 0.4, 1.5, 0.3, 0.2, 0.1])
    assert hm.settling_time(t, rms, 1.0) == pytest.approx(0.7)  # after the last excursion
    assert math.isnan(hm.settling_time(t, rms, 0.05))  # still above at the end
    assert hm.settling_time(t, np.zeros(10), 1.0) == 0.0


def test_surface_and_lost_particles() -> None:
    y = np.array([0.01, 0.03, 0.29, 0.29, 0.31])
    assert hm.surface_height(y, 2, L0) == pytest.approx(0.30 + 0.01)
    pos = np.array([[0.01, 0.01], [-0.001, 0.1], [0.201, 0.1], [0.1, -0.002], [0.1, 0.5]])
    assert hm.lost_particles(pos, 0.2) == 3


def test_window_mean_ignores_empty_layers() -> None:
    t = np.array([0.0, 0.5, 1.0])
    v = np.array([[9.0, np.nan], [1.0, np.nan], [3.0, np.nan]])
    np.testing.assert_array_equal(hm.window_mean(t, v, 0.5)[:1], [2.0])
    assert math.isnan(hm.window_mean(t, v, 0.5)[1])


# --------------------------------------------------------------------------- geometry
def test_build_fills_the_tank_with_the_column() -> None:
    problem = hc.build({**hc.CASE.defaults(), "l0": 0.03})
    p = problem.particles
    fluid = p.pos[p.kind == Kind.FLUID]
    assert len(fluid) == 7 * 10  # round(0.2 / 0.03) x round(0.3 / 0.03)
    assert fluid[:, 1].max() == pytest.approx(0.3 - 0.015)
    assert isinstance(problem.physics, FlowPhysics)
    assert problem.physics.gravity == (0.0, -G)
    assert problem.requirements()["features"] == {"stabilization"}
    no_stab = hc.build({**hc.CASE.defaults(), "stabilization": False})
    assert no_stab.requirements()["features"] == set()


def test_alpha_s_is_reset_without_stabilization() -> None:
    runs = hc.CASE.expand("smoke", {"alpha_s": [0.02]})
    off = [r for r in runs if not r["stabilization"]]
    assert off and all(r["alpha_s"] == 0.01 for r in off)
    assert [r["alpha_s"] for r in runs if r["stabilization"]] == [0.02]


# --------------------------------------------------------------------------- gates and claim
def record(stab: bool = True, **metrics: Any) -> dict[str, Any]:
    base = {**hc.CASE.defaults(), "stabilization": stab, "case": "hydrostatic",
            "solver": "reference", "tier": "quick", "status": "completed",
            "run_id": f"run-{stab}-{len(metrics)}", "column_height": H,
            "rms_speed_late_ratio": 0.002, "rms_speed_late": 0.005, "rms_speed_end": 0.003,
            "floor_pressure_error": -0.02, "particles_lost": 0, "pressure_fluctuation": 0.01,
            "settling_time": 0.15, "surface_rise_max": 0.0, "surface_rise": -0.001}
    return {**base, **metrics}


def test_gates_pass_and_fail_on_constructed_records() -> None:
    ok = ha.gates([record()])
    assert [g.passed for g in ok] == [True, True, True]
    moving = ha.gates([record(rms_speed_late_ratio=0.02)])
    assert moving[0].passed is False and moving[1].passed is True
    heavy = ha.gates([record(floor_pressure_error=0.06)])
    assert heavy[1].passed is False
    light = ha.gates([record(floor_pressure_error=-0.051)])
    assert light[1].passed is False
    leaking = ha.gates([record(particles_lost=1)])
    assert leaking[2].passed is False
    # the gates hold the recommended configuration only: an unstabilized melting run is no
    # failure, and without a recommended run they are undecided
    assert [g.passed for g in ha.gates([record(), record(False, rms_speed_late_ratio=0.05)])] \
        == [True, True, True]
    assert all(g.passed is None for g in ha.gates([record(False)]))


def test_claim_c4_on_constructed_records() -> None:
    on, off = record(True, pressure_fluctuation=0.01), record(False, pressure_fluctuation=0.1)
    (c4,) = ha.claims([on, off])
    assert c4.claim == "C4" and c4.passed is True
    (c4,) = ha.claims([record(True, pressure_fluctuation=0.2), off])
    assert c4.passed is False
    (c4,) = ha.claims([on])
    assert c4.passed is None and "no data" in c4.detail


def test_findings_name_the_melting_with_numbers() -> None:
    on = record(True, rms_speed_late=0.004, rms_speed_end=0.002)
    off = record(False, rms_speed_late=0.06, rms_speed_end=0.09, settling_time=math.nan,
                 surface_rise_max=0.007)
    text = hc.CASE.findings([on, off])
    assert "0.004 m/s" in text and "0.06 m/s" in text and "15x" in text
    assert "never settles" in text and "+7.0 mm" in text


# --------------------------------------------------------------------------- end to end
def test_smoke_tier_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "smoke"
    assert cli.main(["validate", "hydrostatic", "--tier", "smoke", "--out", str(out)]) == 0
    df = pd.read_csv(out / "results.csv")
    assert len(df) == 2 and (df["status"] == "completed").all()
    assert set(df["stabilization"]) == {True, False}
    for col in hc.METRICS:
        assert col in df.columns, col
    checks = json.loads((out / "checks.json").read_text())
    gates = [c for c in checks if c["kind"] == "gate"]
    assert len(gates) == 3 and all(c["passed"] is True for c in gates)
    assert [c["claim"] for c in checks if c["kind"] == "claim"] == ["C4"]
    stab = df[df["stabilization"]].iloc[0]
    assert abs(stab["floor_pressure_error"]) < ha.FLOOR_TOL
    assert stab["particles_lost"] == 0
    figures = {p.name for p in (out / "figures").glob("*.png")}
    assert {"motion_l0-0.03.png", "pressure_l0-0.03.png"} <= figures
    assert (out / "tables" / "rest_and_melting.csv").exists()


def test_figure_names_tell_the_solvers_and_the_stabilization_rates_apart() -> None:
    """Two solvers x two stabilization rates of one model: four distinct legend names and
    line styles (they were four copies of 'xu-jin / pgm1, stabilized')."""
    from mpsbench.validations.hydrostatic.figures import _Labels

    rows = [{"laplacian": "xu-jin", "gradient": "pgm1", "stabilization": True, "solver": s,
             "stabilization_rate": rate, "cfl": 0.2}
            for s in ("numba", "implicit:source=mixed") for rate in ("step", "acoustic")]
    g = pd.DataFrame(rows)
    lab = _Labels(g)
    names = [lab.name(r) for _, r in g.iterrows()]
    assert len(set(names)) == 4
    assert "implicit:source=mixed, alpha_s per acoustic step" in names[3]
    assert len({lab.style(r)["lw"] for _, r in g.iterrows()}) == 4
    # one solver, one rate: the plain name
    single = _Labels(g.iloc[:1])
    assert single.name(g.iloc[0]) == "xu-jin / pgm1, stabilized"
