"""The Couette validation case (issue 4): series solution, geometry, acceptance cells, CLI."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from mpsbench.validations.couette import analysis as coa
from mpsbench.validations.couette import case as cou

from mpsbench import cli
from mpsbench.errors import ConfigError
from mpsbench.physics.particles import Kind

L, U = cou.L, cou.U
RECORD_COLUMNS = ("case", "solver", "tier", "status", "reason", "wall_time_s",
                  "particle_steps_per_s", "laplacian", "weight", "re_ratio", "l0", "jitter", "dt",
                  "wall_velocity")
METRIC_COLUMNS = ("l2_error", "l2_error_steady", "l2_error_t0.0225", "l2_error_t0.045",
                  "l2_error_t0.1125", "l2_error_near_wall", "l2_error_interior",
                  "wall_error_share")


def cell(**params: Any) -> dict[str, Any]:
    """Run one parameter set of the case directly (no steady run unless asked)."""
    out = cou.CASE.execute({**cou.CASE.defaults(), "steady": False, **params}, "reference")
    assert out.results and all(r.ok for r in out.results), [r.reason for r in out.results]
    return out.metrics


# --------------------------------------------------------------------------- series solution


@pytest.mark.parametrize(
    ("t", "expected"),
    [(0.0225, (0.0004, 0.0184, 0.2386)), (0.045, (0.0124, 0.0956, 0.4047)),
     (0.1125, (0.1054, 0.2903, 0.5979))],
)
def test_series_reproduces_the_reference_table(t: float, expected: tuple[float, ...]) -> None:
    """docs/method.md 6 b: u/U at y/L = 0.25, 0.5, 0.75 (Morris et al. 1997)."""
    u = cou.series(np.array([0.25, 0.5, 0.75]) * L, t) / U
    np.testing.assert_array_equal(np.round(u, 4), expected)


def test_series_limits() -> None:
    y = np.linspace(0.0, L, 41)
    np.testing.assert_allclose(cou.series(y, 5.0), U * y / L, atol=1e-14 * U)  # steady
    np.testing.assert_allclose(cou.series(y, 1e4), U * y / L, atol=1e-14 * U)  # no underflow
    early = cou.series(y, 1e-6)
    assert early[-1] == pytest.approx(U) and early[0] == 0.0
    assert np.abs(early[1:-2]).max() < 1e-3 * U  # the fluid has not moved yet
    assert np.all(cou.series(y[1:-1], 0.0) == 0.0)


def test_profile_metrics() -> None:
    rows = L / 40 * np.arange(1, 40)
    exact = np.array([cou.series(rows, t) for t in cou.TIMES])
    m = cou.profile_metrics(rows, exact, 3.1 * L / 40)
    assert all(m[cou.time_key(t)] == 0.0 for t in cou.TIMES) and m["l2_error"] == 0.0
    bumped = exact.copy()
    bumped[-1] += 0.01 * U * np.sin(np.pi * rows / L)
    m = cou.profile_metrics(rows, bumped, 3.1 * L / 40)
    assert m["l2_error"] ** 2 == pytest.approx(
        m["l2_error_near_wall"] ** 2 + m["l2_error_interior"] ** 2, rel=1e-12)
    assert m["wall_row_share"] == pytest.approx(6 / 39)  # 3 rows within 3.1 l0 of each plate
    assert m["wall_error_share"] < 0.1 and m["max_error_y"] == pytest.approx(0.5)
    assert m["linf_error"] == pytest.approx(0.01, rel=1e-12)


# --------------------------------------------------------------------------- geometry


@pytest.mark.parametrize("wall_row", ["on-plate", "offset"])
def test_geometry(wall_row: str) -> None:
    params = {**cou.CASE.defaults(), "wall_row": wall_row, "re_ratio": 4.0}
    problem, rows = cou.CASE.build(params)
    l0 = L / 40
    p = problem.particles
    fluid = p.kind == Kind.FLUID
    first = 0.0 if wall_row == "on-plate" else -0.5 * l0
    expected = l0 * np.arange(1, 40) if wall_row == "on-plate" else l0 * (np.arange(40) + 0.5)
    np.testing.assert_allclose(rows, expected, atol=1e-15)
    np.testing.assert_allclose(np.unique(np.round(p.pos[fluid, 1] / l0, 6)) * l0, rows)
    bottom, top = ~fluid & (p.pos[:, 1] < 0.5 * L), ~fluid & (p.pos[:, 1] > 0.5 * L)
    assert p.pos[bottom, 1].max() == pytest.approx(first, abs=1e-15)
    assert p.pos[top, 1].min() == pytest.approx(L - first, abs=1e-15)
    # every boundary row carries its plate's velocity; the mirror geometry puts the plate at
    # y = 0 and y = L
    assert np.all(p.vel[bottom] == 0.0) and np.all(p.vel[top] == [U, 0.0])
    np.testing.assert_allclose(p.pos[bottom, 1] + p.fields["wall_dist"][bottom], 0.0, atol=1e-15)
    np.testing.assert_allclose(p.pos[top, 1] - p.fields["wall_dist"][top], L, atol=1e-15)
    # rows enough to fill the support (r_e = 4 l0) and a strip wider than 2 (r_e + skin)
    assert (p.pos[bottom, 1].max() - p.pos[bottom, 1].min()) / l0 >= 3 - 1e-9
    assert problem.box.periodic == (True, False)
    assert problem.box.length[0] > 2 * (4.0 + 0.5) * l0
    assert problem.physics.c0 >= 10 * U and problem.physics.gravity == (0.0, 0.0)
    assert problem.wall_motions[0].velocity == (U, 0.0)


def test_l0_must_divide_the_gap() -> None:
    with pytest.raises(ConfigError, match="parameter l0"):
        cou.CASE.build({**cou.CASE.defaults(), "l0": 3e-5})


def test_tiers() -> None:
    quick = pd.DataFrame(cou.CASE.expand("quick"))
    main = quick[quick["c_nu"] == 0.25]
    grid = main[(main["wall_velocity"] == "prescribed") & (main["l0"] >= L / 40)]
    assert len(grid) == 4 * 2 * 5 * 2  # model x WF x radius x {L/20, L/40}
    assert set((L / main["l0"]).round()) == {20, 40, 80}
    # the refinement sets of the headline cell: L/20, L/40, L/80 and c_nu 0.25, 0.125, 0.0625
    cell = quick[(quick["laplacian"] == "xu-jin") & (quick["weight"] == "wf2")
                 & (quick["re_ratio"] == 3.1) & (quick["wall_velocity"] == "prescribed")]
    assert sorted(set((L / cell[cell["c_nu"] == 0.25]["l0"]).round())) == [20, 40, 80]
    assert sorted(set(cell[cell["l0"] == L / 40]["c_nu"])) == [0.0625, 0.125, 0.25]
    assert len(quick) == len(grid) + 8 * 2 + 1 + 2  # + mirror grid, L/80, two c_nu
    paper = pd.DataFrame(cou.CASE.expand("paper"))
    full = paper[(paper["c_nu"] == 0.25) & (paper["l0"] >= L / 40)]
    assert set(paper["wall_velocity"]) == {"prescribed", "mirror"} and full["steady"].all()
    assert len(cou.CASE.expand("smoke")) <= 6


# --------------------------------------------------------------------------- acceptance cells


def test_xu_jin_wf2_3_1_is_below_one_percent_at_l_40() -> None:
    m = cell(laplacian="xu-jin", weight="wf2", re_ratio=3.1, l0=L / 40)
    assert m["l2_error"] < coa.BEST_MAX_L2
    assert m["l2_error"] == m["l2_error_t0.1125"]
    assert m["l2_error_t0.0225"] > m["l2_error_t0.045"] > m["l2_error"]  # early profiles: harder
    assert m["max_v"] < 1e-9  # the flow stays one-dimensional
    assert m["dt"] > 0 and m["n_rows"] == 39


def test_rate_error_models_at_l_20() -> None:
    """khayyer-gotoh and xu-jin-analytic diffuse momentum too fast (cheap version, L/20)."""
    for model in coa.RATE_MODELS:
        assert cell(laplacian=model, weight="wf2", re_ratio=2.1, l0=L / 20)["l2_error"] > 0.05


@pytest.mark.parametrize("model", coa.RATE_MODELS)
@pytest.mark.parametrize("weight", ["wf1", "wf2"])
def test_rate_error_models_above_five_percent_at_l_40(model: str, weight: str) -> None:
    m = cell(laplacian=model, weight=weight, re_ratio=coa.RATE_RE, l0=L / 40)
    assert m["l2_error"] > coa.RATE_MIN_L2
    assert m["wall_error_share"] < 0.1  # a diffusion-rate error lives in the interior


@pytest.mark.parametrize("model", coa.CONVERGING_MODELS)
def test_refinement_reduces_the_error(model: str) -> None:
    coarse = cell(laplacian=model, weight="wf2", re_ratio=3.1, l0=L / 20)["l2_error"]
    fine = cell(laplacian=model, weight="wf2", re_ratio=3.1, l0=L / 40)["l2_error"]
    assert coarse / fine >= coa.MIN_REDUCTION


def test_mirror_walls_hold_the_steady_profile_and_prescribed_ones_nearly() -> None:
    """A linear profile is a steady state of every Laplacian in the interior; with mirrored
    boundary velocities (a linear fit through the plate) it is one of the discrete problem."""
    mirror = cell(laplacian="xu-jin", weight="wf2", re_ratio=3.1, l0=L / 20,
                  wall_velocity="mirror", steady=True)
    prescribed = cell(laplacian="xu-jin", weight="wf2", re_ratio=3.1, l0=L / 20, steady=True)
    assert mirror["l2_error_steady"] < 1e-6
    assert 1e-4 < prescribed["l2_error_steady"] < 0.01
    assert mirror["l2_error"] < 0.01


def test_offset_wall_rows_with_prescribed_velocities_widen_the_channel() -> None:
    """The no-slip point follows the first boundary row: l0/2 outside each plate."""
    offset = cell(laplacian="xu-jin", weight="wf2", re_ratio=3.1, l0=L / 20, wall_row="offset")
    on_plate = cell(laplacian="xu-jin", weight="wf2", re_ratio=3.1, l0=L / 20)
    assert offset["l2_error"] > 10 * on_plate["l2_error"]
    assert offset["l2_error"] == pytest.approx(0.06, abs=0.01)  # about l0 / L


# --------------------------------------------------------------------------- command line


def validate(*args: str) -> int:
    return cli.main(["validate", "couette", *args])


def test_smoke_tier_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "smoke"
    assert validate("--tier", "smoke", "--out", str(out)) == 0
    for name in ("results.csv", "results.json", "report.md", "checks.json"):
        assert (out / name).stat().st_size > 0, name
    df = pd.read_csv(out / "results.csv")
    assert len(df) == len(cou.CASE.expand("smoke")) and (df["status"] == "completed").all()
    for col in RECORD_COLUMNS + METRIC_COLUMNS:
        assert col in df.columns, col
    assert set(df["wall_velocity"]) == {"prescribed", "mirror"}
    pivot = pd.read_csv(out / "tables" / "l2_error_t0.1125_L-40_prescribed.csv", index_col=0)
    assert pivot.index.name == "model / WF" and list(pivot.columns) == ["r_e/l0 = 3.1"]
    conv = pd.read_csv(out / "tables" / "convergence.csv")
    assert list(conv.columns[:4]) == ["model", "weight", "re_ratio", "wall_velocity"]
    assert (out / "tables" / "error_location_L-40_prescribed.md").exists()
    figures = {p.name for p in (out / "figures").glob("*.png")}
    assert {"profiles_L-40_prescribed.png", "error_profiles_L-40_prescribed.png",
            "error_vs_re_L-40.png"} <= figures
    checks = json.loads((out / "checks.json").read_text())
    gates = [c for c in checks if c["kind"] == "gate"]
    assert gates and all(c["passed"] is not False for c in gates)
    assert {c["claim"] for c in checks if c["kind"] == "claim"} == {"C2", "C3", "C8"}
    report = (out / "report.md").read_text()
    assert "Where the error sits" in report and "Steady state" in report


def test_rerun_skips_every_run_and_force_redoes_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ("--tier", "smoke", "--set", "laplacian=xu-jin", "--set", "l0=5e-5",
            "--set", "steady=false", "--set", "dt_check=false", "--set", "wall_velocity=prescribed",
            "--set", "drift=0", "--out", str(tmp_path))
    assert validate(*args) == 0
    first = capsys.readouterr().err
    assert first.count("] completed") == 1 and "] skip" not in first
    assert validate(*args) == 0
    second = capsys.readouterr().err
    assert second.count("] skip") == 1 and "] completed" not in second
    assert validate(*args, "--force") == 0
    assert capsys.readouterr().err.count("] completed") == 1


@pytest.mark.parametrize(
    ("item", "name"),
    [("l0=-1", "l0"), ("l0=0.025", "l0"), ("laplacian=nope", "laplacian"),
     ("wall_velocity=slip", "wall_velocity"), ("steady=maybe", "steady")],
)
def test_bad_set_value_exits_2_naming_the_parameter(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], item: str, name: str
) -> None:
    assert validate("--tier", "smoke", "--set", item, "--out", str(tmp_path / "x")) == 2
    err = capsys.readouterr().err
    assert name in err and "error" in err
    assert not (tmp_path / "x").exists()
