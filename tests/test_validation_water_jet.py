"""The water-jet case: free-streamline solution, noise / drift / penetration metrics, geometry,
tiers and record columns, and an end-to-end run through ``mpsbench validate``."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from mpsbench.validations.water_jet.geometry import JetGeometry, build_problem, plate_points
from mpsbench.validations.water_jet.metrics import (
    TABLE_CP,
    TABLE_XB,
    cp_errors,
    frame_measures,
    free_streamline_cp,
    free_streamline_x,
    interior_fluid,
    penetrations,
    plate_force_ratio,
    plate_profile,
    pressure_deviation,
    stabilization_viscosity,
    surface_centroid,
    tait_cp,
    temporal_noise,
)
from scipy.integrate import quad

from mpsbench.cases import get_case
from mpsbench.cli import main
from mpsbench.physics.config import FlowPhysics, Models
from mpsbench.physics.operators import lattice_constants
from mpsbench.physics.particles import Kind, Particles, block
from mpsbench.results.records import COMMON_COLUMNS
from mpsbench.run.specs import make_solver

REQUIRED_PARAMS = ("gradient", "stabilization", "alpha_s", "collision_distance", "weight", "l0")
REQUIRED_METRICS = (
    "cp_rms_error", "cp_max_error", "cp_stagnation", "noise_spatial", "noise_temporal",
    "density_drift_mean", "density_drift_max", "penetrations",
)
RE = 2.1  # r_e / l0


# --------------------------------------------------------------------------- reference solution
def test_free_streamline_matches_method_table() -> None:
    # the table is rounded to 1e-3
    np.testing.assert_allclose(free_streamline_cp(TABLE_XB), TABLE_CP, atol=5.1e-4)


def test_free_streamline_inverts_the_parametric_form() -> None:
    s = np.linspace(0.0, 0.999999, 101)
    np.testing.assert_allclose(free_streamline_cp(free_streamline_x(s)), 1.0 - s**2, atol=1e-12)
    np.testing.assert_allclose(free_streamline_cp(-free_streamline_x(s)), 1.0 - s**2, atol=1e-12)


def test_free_streamline_shape() -> None:
    x = np.linspace(0.0, 50.0, 2001)
    cp = free_streamline_cp(x)
    assert cp[0] == 1.0
    assert np.all(np.diff(cp) <= 0.0) and np.all(cp >= 0.0)
    assert free_streamline_cp(1e4) < 1e-200  # far tail: no overflow, no error


def test_free_streamline_momentum_balance() -> None:
    """integral of p dx over the plate = rho U^2 b, i.e. integral of Cp d(x/b) = 2."""
    half, _ = quad(lambda x: float(free_streamline_cp(x)), 0.0, 40.0, limit=400)
    assert 2.0 * half == pytest.approx(2.0, rel=1e-9)

    # the same through the parametrisation: integral of (1 - s^2) dx/ds ds over [0, 1)
    def integrand(s: float) -> float:
        dxds = (2.0 / math.pi) * (1.0 / (1.0 - s * s) + 1.0 / (1.0 + s * s))
        return (1.0 - s * s) * dxds

    half_s, _ = quad(integrand, 0.0, 1.0)
    assert 2.0 * half_s == pytest.approx(2.0, rel=1e-12)


# --------------------------------------------------------------------------- noise metrics
def _lattice(n: int, spacing: float = 1.0) -> Particles:
    return block(0.0, 0.0, n, n, spacing)


def _checkerboard_deviation(radius: float) -> float:
    """p_i - Shepard mean of neighbours for p = (-1)^(i+j), unit lattice, weight (1 - r/R)^3."""
    num = den = 0.0
    m = int(math.ceil(radius))
    for dx in range(-m, m + 1):
        for dy in range(-m, m + 1):
            r = math.hypot(dx, dy)
            if 0 < r <= radius:
                w = (1.0 - r / radius) ** 3
                num += w * (-1) ** (dx + dy)
                den += w
    return 1.0 - num / den


def test_uniform_pressure_has_zero_noise() -> None:
    p = _lattice(20)
    p.pressure[:] = 1234.5
    dev, ok = pressure_deviation(p.pos, p.pressure, np.ones(p.n, bool), RE)
    assert ok.all()
    np.testing.assert_allclose(dev, 0.0, atol=1e-9)
    n0 = lattice_constants("wf2", RE, 1.0)[0]
    fm = frame_measures(p.pos, p.pressure, p.kind, l0=1.0, weight="wf2", re=RE, n0=n0,
                        q=500.0, beta=0.97)
    assert fm.noise_count > 0
    assert fm.noise_sq_sum == pytest.approx(0.0, abs=1e-20)


def test_checkerboard_noise_has_the_known_value() -> None:
    n, amp, q = 24, 50.0, 500.0
    p = _lattice(n)
    ij = np.rint(p.pos - 0.5).astype(int)
    sign = (-1.0) ** (ij[:, 0] + ij[:, 1])
    p.pressure[:] = 1000.0 + amp * sign
    expected = amp * _checkerboard_deviation(RE)
    assert expected == pytest.approx(amp * 1.6100, rel=1e-3)  # hand value for R = 2.1
    dev, _ = pressure_deviation(p.pos, p.pressure, np.ones(p.n, bool), RE)
    inner = np.all((ij >= 3) & (ij <= n - 4), axis=1)
    np.testing.assert_allclose(dev[inner], expected * sign[inner], rtol=1e-12)
    # frame_measures: every particle but the outer row has n >= 0.97 n0; the second row
    # misses one neighbour at 2 l0 (weight 1e-4), so the RMS is the interior value to 1e-3
    n0 = lattice_constants("wf2", RE, 1.0)[0]
    fm = frame_measures(p.pos, p.pressure, p.kind, l0=1.0, weight="wf2", re=RE, n0=n0, q=q,
                        beta=0.97)
    assert fm.noise_count == (n - 2) ** 2
    assert math.sqrt(fm.noise_sq_sum / fm.noise_count) == pytest.approx(expected / q, rel=1e-3)


def test_noise_ignores_dummy_pressure_and_region() -> None:
    p = _lattice(16)
    p.pressure[:] = 100.0
    p.kind[p.pos[:, 1] < 2.0] = Kind.DUMMY  # two bottom rows: dummies carry p = 0 ...
    p.pressure[p.kind == Kind.DUMMY] = 0.0  # ... and must not enter the kernel mean
    n0 = lattice_constants("wf2", RE, 1.0)[0]
    fm = frame_measures(p.pos, p.pressure, p.kind, l0=1.0, weight="wf2", re=RE, n0=n0,
                        q=500.0, beta=0.97)
    assert fm.noise_count > 0 and fm.noise_sq_sum == pytest.approx(0.0, abs=1e-20)
    none = frame_measures(p.pos, p.pressure, p.kind, l0=1.0, weight="wf2", re=RE, n0=n0,
                          q=500.0, beta=0.97, region=(-1.0, -1.0))
    assert none.noise_count == 0 and none.drift_count == 0


def test_density_drift_of_a_compressed_lattice() -> None:
    n0 = lattice_constants("wf2", RE, 1.0)[0]
    lattice = _lattice(20)
    fm = frame_measures(lattice.pos, lattice.pressure, lattice.kind, l0=1.0, weight="wf2",
                        re=RE, n0=n0, q=1.0, beta=0.97)
    assert fm.drift_count > 0 and fm.drift_sum == pytest.approx(0.0, abs=1e-9)
    squeezed = _lattice(20, spacing=0.98)
    expected = lattice_constants("wf2", RE / 0.98, 0.98)[0] / n0 - 1.0  # same r_e = 2.1
    fm = frame_measures(squeezed.pos, squeezed.pressure, squeezed.kind, l0=1.0, weight="wf2",
                        re=RE, n0=n0, q=1.0, beta=0.97)
    assert fm.drift_count > 0
    assert fm.drift_sum / fm.drift_count == pytest.approx(expected, rel=1e-9)
    assert fm.drift_max == pytest.approx(expected, rel=1e-9)


def test_near_wall_measures_the_rows_above_the_plate() -> None:
    """Fluid with |x| <= x_max and y < y_max: its pressure and its mean n/n0 - 1."""
    n0 = lattice_constants("wf2", RE, 1.0)[0]
    squeezed = block(-10.0, 0.0, 20, 20, 0.98)  # rows at y = 0.49, 1.47, 2.45, ...
    q = 500.0
    squeezed.pressure[:] = 0.5 * q + 10.0 * squeezed.pos[:, 1]  # rises with y
    fm = frame_measures(squeezed.pos, squeezed.pressure, squeezed.kind, l0=1.0, weight="wf2",
                        re=RE, n0=n0, q=q, beta=0.97, near_wall=(4.0, 2.5))
    inside = (np.abs(squeezed.pos[:, 0]) <= 4.0) & (squeezed.pos[:, 1] < 2.5)
    assert fm.wall_count == inside.sum() == 3 * 8  # three rows, x = +-0.49 .. +-3.43
    assert fm.wall_cp_sum / fm.wall_count == pytest.approx(
        0.5 + 10.0 * squeezed.pos[inside, 1].mean() / q, rel=1e-12)
    # the top row of the three has full support (compressed by 2 %: n/n0 - 1 = full); the two
    # below miss the rows under y = 0, so the mean lies between the open-edge value and full
    full = lattice_constants("wf2", RE / 0.98, 0.98)[0] / n0 - 1.0
    mean_dn = fm.wall_dn_sum / fm.wall_count
    assert full > 0.05 and -0.5 < mean_dn < full
    none = frame_measures(squeezed.pos, squeezed.pressure, squeezed.kind, l0=1.0, weight="wf2",
                          re=RE, n0=n0, q=q, beta=0.97)
    assert none.wall_count == 0 and none.wall_cp_sum == 0.0


def test_tait_cp_is_the_linearised_compression_for_small_strain() -> None:
    c0 = 10.0
    assert tait_cp(0.0, c0) == 0.0
    # p = rho c0^2 dn (1 + 3 dn + ...) for gamma = 7: Cp = 2 (c0/U)^2 dn to O(dn^2)
    assert tait_cp(1e-4, c0) == pytest.approx(2 * c0**2 * 1e-4, rel=4e-4)
    assert tait_cp(-5e-3, c0) < 0.0  # not clipped
    assert tait_cp(5e-3, c0) == pytest.approx(200.0 / 7.0 * (1.005**7 - 1.0), rel=1e-12)


def test_plate_force_ratio_measures_the_integral_not_the_shape() -> None:
    xb = np.arange(26) * 0.1
    exact = free_streamline_cp(xb)
    assert plate_force_ratio(xb, exact) == pytest.approx(1.0, abs=2e-3)  # trapezoid on 0.1 b
    assert plate_force_ratio(xb, 1.2 * exact) == pytest.approx(1.2, abs=3e-3)
    # a profile twice as wide and half as high carries the same force over a long plate
    xl = np.linspace(0.0, 40.0, 4001)
    wide = 0.5 * free_streamline_cp(xl / 2.0)
    assert plate_force_ratio(xl, wide) == pytest.approx(1.0, abs=1e-3)


def test_interior_is_one_support_away_from_the_surface() -> None:
    p = _lattice(12)
    surface = surface_centroid(p.pos, p.fluid, RE, 1.0)
    ij = np.rint(p.pos - 0.5).astype(int)
    edge = np.any((ij == 0) | (ij == 11), axis=1)
    assert np.array_equal(surface, edge)  # second row (centroid 0.18 l0) is not surface
    inner = interior_fluid(p.pos, p.kind, RE, 1.0)
    assert np.array_equal(inner, np.all((ij >= 3) & (ij <= 8), axis=1))


def test_penetration_count_and_temporal_noise() -> None:
    pos = np.array([[0.0, 0.1], [0.1, -0.01], [0.2, -0.3], [5.0, -0.1], [0.0, -0.2]])
    kind = np.array([Kind.FLUID, Kind.FLUID, Kind.FLUID, Kind.FLUID, Kind.WALL], np.int8)
    assert penetrations(pos, kind, half_plate=1.0) == 2  # beyond the plate / walls: ignored
    assert temporal_noise(np.full(10, 3.0)) == 0.0
    assert temporal_noise(np.array([1.0, 3.0])) == pytest.approx(0.5)


def test_stabilization_viscosity_matches_one_stabilization_step() -> None:
    """One step of u += (alpha_s l0/n0) sum |W'| (u_j - u_i) on sin(kx) = dt nu_s lap(u)."""
    from mpsbench.physics.neighbours import build_pairs
    from mpsbench.physics.operators import lattice_pairs
    from mpsbench.physics.weights import get_weight

    n_side, l0, alpha_s, dt = 32, 0.01, 0.01, 1e-4
    pos, box = lattice_pairs(n_side, l0)
    k = 2.0 * math.pi / (n_side * l0)
    u = np.sin(k * pos[:, 0])
    re = RE * l0
    pairs = build_pairs(pos, re, box)
    wf = get_weight("wf2")
    n0 = lattice_constants("wf2", RE, l0)[0]
    du = (alpha_s * l0 / n0) * pairs.sum_antisym(np.abs(wf.dw(pairs.r, re)) * pairs.diff(u))
    nu_s = stabilization_viscosity("wf2", RE, l0, alpha_s, dt)
    expected = -dt * nu_s * k**2 * u
    assert np.max(np.abs(du - expected)) < 0.01 * np.max(np.abs(expected))  # k l0 = 0.2


# --------------------------------------------------------------------------- geometry
def test_geometry_rejects_a_spacing_that_does_not_divide_the_jet() -> None:
    with pytest.raises(ValueError, match="whole multiple"):
        JetGeometry(b=0.1, l0=0.03, nozzle_gap=0.2, plate_length=0.6)


def test_problem_layout() -> None:
    b, l0 = 0.1, 0.01
    geo = JetGeometry(b, l0, 2 * b, 6 * b)
    problem = build_problem(geo, 1.0, FlowPhysics(gravity=(0.0, 0.0)), Models())
    p = problem.particles
    fluid = p.kind == Kind.FLUID
    assert fluid.sum() == 10 * 20  # the pre-filled column b x 2b
    assert np.all(p.vel[fluid] == [0.0, -1.0])
    assert np.all(p.pos[~fluid, 1] < 0.0) and (p.kind == Kind.WALL).sum() == 60
    assert problem.inflow is not None and problem.inflow.velocity == (0.0, -1.0)
    # outflow regions leave the plate centre, the jet and the reservoir alone
    for reg in problem.outflows:
        inside = np.all((p.pos >= reg.lo) & (p.pos <= reg.hi), axis=1)
        assert not inside[fluid].any()
    pts = plate_points(geo, 2.5, 0.1)
    assert len(pts) == 51 and pts[25, 0] == 0.0 and np.all(pts[:, 1] == 0.0)


def test_inflow_rows_sit_upstream_and_feed_the_jet_at_U_b() -> None:
    """Reservoir rows above the inlet, moving down; the fluid gains U b / l0^2 particles/s."""
    b, l0, speed = 0.1, 0.01, 1.0
    geo = JetGeometry(b, l0, 2 * b, 6 * b)
    problem = build_problem(geo, speed, FlowPhysics(gravity=(0.0, 0.0), c0=10.0), Models())
    s = make_solver("reference")
    s.setup(problem)
    st = s.state()
    res = st.kind == Kind.INFLOW
    assert res.sum() == 10 * 4
    assert np.all(st.pos[res, 1] > geo.nozzle_gap)
    assert np.all(st.vel[res] == [0.0, -speed])
    n_start = int((st.kind == Kind.FLUID).sum())
    while s.time < 0.1:  # no fluid reaches the outflow this early
        s.step(min(s.stable_dt(), 0.1 - s.time + 1e-15))
    gained = int((s.state().kind == Kind.FLUID).sum()) - n_start
    expected = speed * s.time * b / l0**2  # 100 particles
    assert abs(gained - expected) <= 10  # one row of the jet


# --------------------------------------------------------------------------- case and study
def test_case_declares_the_study_grid_and_the_record_columns() -> None:
    case = get_case("water-jet")
    names = {p.name for p in case.params}
    assert set(REQUIRED_PARAMS) <= names
    assert set(REQUIRED_METRICS) <= set(case.metrics)
    assert set(case.tiers) == {"smoke", "quick", "paper"}
    paper = case.expand("paper")
    # the full grid, plus b/40 off/on and alpha_s {0.0025, 0.005} x wall neighbours at b/20
    assert len(paper) == 2 * 3 * 4 * 2 * 2 + 2 + 4
    quick = case.expand("quick")
    acceptance = [r for r in quick if r["stabilization"] and r["gradient"] == "pgm1"
                  and r["weight"] == "wf2" and r["b"] / r["l0"] == pytest.approx(20.0)
                  and r["collision_distance"] == 0.0 and r["stabilization_walls"]
                  and r["alpha_s"] == 0.01]
    # the acceptance run, and the same at half the time step (its dt refinement set)
    assert sorted(r["cfl"] for r in acceptance) == [0.1, 0.2]
    # the acceptance model's trend: b/10, b/20, b/40 and alpha_s 0.0025, 0.005, 0.01 at b/20
    trend = [r for r in quick if r["stabilization"] and r["gradient"] == "pgm1"
             and r["collision_distance"] == 0.0 and r["stabilization_walls"] and r["cfl"] == 0.2]
    assert {round(r["b"] / r["l0"]) for r in trend if r["alpha_s"] == 0.01} == {10, 20, 40}
    assert {r["alpha_s"] for r in trend if round(r["b"] / r["l0"]) == 20} == {
        0.0025, 0.005, 0.01}
    assert {r["gradient"] for r in quick} == {"pgm1", "pgm2", "pgm3"}
    assert {r["collision_distance"] for r in quick} == {0.0, 0.5, 0.7, 0.9}


def _check_outputs(out, n_runs: int) -> pd.DataFrame:  # noqa: ANN001
    df = pd.read_csv(out / "results.csv")
    assert len(df) == n_runs and (df["status"] == "completed").all(), df.get("reason")
    for col in (*COMMON_COLUMNS, *REQUIRED_PARAMS, *REQUIRED_METRICS):
        assert col in df.columns, col
    assert (out / "report.md").exists() and (out / "tables" / "noise.md").exists()
    for fig in ("snapshots_pressure", "plate_cp", "stagnation_history", "noise"):
        assert (out / "figures" / f"{fig}.png").exists(), fig
    report = (out / "report.md").read_text()
    assert "What the stabilization does to the noise" in report
    return df


def test_validate_cli_short_run(tmp_path) -> None:  # noqa: ANN001
    """End-to-end through the CLI with a shortened smoke run (about 10 s)."""
    out = tmp_path / "jet"
    code = main(["validate", "water-jet", "--tier", "smoke", "--out", str(out),
                 "--set", "t_end=1.5", "--set", "t_window=0.5"])
    assert code == 0
    df = _check_outputs(out, 3)  # off and on, and on at half the time step (cfl 0.1)
    assert set(df["stabilization"]) == {True, False}
    assert sorted(df["cfl"]) == [0.1, 0.2, 0.2]
    assert (df["penetrations"] >= 0).all()
    assert df["cp_stagnation"].notna().all()


@pytest.mark.slow
def test_validate_cli_smoke_tier(tmp_path) -> None:  # noqa: ANN001
    """The smoke tier as CI runs it (about a minute)."""
    out = tmp_path / "smoke"
    assert main(["validate", "water-jet", "--tier", "smoke", "--out", str(out)]) == 0
    df = _check_outputs(out, 3)
    on = df[df["stabilization"]].iloc[0]
    assert on["penetrations"] == 0


def test_diagnostics_survive_outflow_removal() -> None:
    """Removing outflow particles keeps the other particles' number density and surface flags
    (they used to be zeroed until the next step, so probes saw n = 0 everywhere)."""
    from mpsbench.physics.config import Region
    from mpsbench.physics.particles import Box
    from mpsbench.run.protocol import Problem

    l0 = 0.01
    fluid = block(0.0, 0.0, 12, 12, l0)
    problem = Problem(
        particles=fluid, box=Box((-0.1, -0.1), (0.3, 0.3)), l0=l0,
        physics=FlowPhysics(gravity=(0.0, 0.0)), models=Models(),
        outflows=(Region((0.105, -1.0), (1.0, 1.0)),),  # the last two columns
    )
    s = make_solver("reference")
    s.setup(problem)
    s.step(s.stable_dt())
    assert s.state().n == 10 * 12
    n = s.diagnostics()["number_density"]
    assert len(n) == s.state().n
    n0 = s.diagnostics()["n0"]
    x = s.state().pos[:, 0]
    inner = (x > 0.03) & (x < 0.07) & (np.abs(s.state().pos[:, 1] - 0.06) < 0.02)
    np.testing.assert_allclose(n[inner], n0, rtol=1e-3)
    assert s.diagnostics()["free_surface"][np.argmin(x)]  # the left edge is still flagged


def test_model_choices_come_from_the_registries() -> None:
    """A plugin's weighting function, Laplacian or gradient model is an allowed jet parameter."""
    from mpsbench.physics.gradients import GRADIENTS
    from mpsbench.physics.laplacians import LAPLACIANS
    from mpsbench.physics.weights import WEIGHTS

    case = get_case("water-jet")
    for param, registry in (("weight", WEIGHTS), ("laplacian", LAPLACIANS),
                            ("gradient", GRADIENTS)):
        choices = case.param(param).choices
        assert choices is not None and set(registry.names()) == set(choices), param
    gradients = case.param("gradient").choices
    assert gradients is not None and gradients[:3] == ("pgm1", "pgm2", "pgm3")


def test_plate_profile_folds_the_two_sides_and_cp_errors_measure_it() -> None:
    xb = np.arange(-25, 26) * 0.1
    exact = free_streamline_cp(np.abs(xb))
    tilt = 0.02 * xb  # antisymmetric: folding cancels it
    samples = np.vstack([exact + tilt + 0.05, exact + tilt - 0.05])  # two times, mean exact
    cp, std = plate_profile(samples)
    half = np.arange(26) * 0.1
    np.testing.assert_allclose(cp, free_streamline_cp(half), atol=1e-15)
    np.testing.assert_allclose(std, 0.05, atol=1e-15)
    assert cp_errors(half, cp, 2.0) == pytest.approx((0.0, 0.0), abs=1e-15)
    # +0.1 everywhere on 0..1 b and exact beyond: RMS over the 21 sensors of 0..2 b
    bumped = cp + np.where(half <= 1.0 + 1e-9, 0.1, 0.0)
    rms, worst = cp_errors(half, bumped, 2.0)
    assert rms == pytest.approx(0.1 * math.sqrt(11 / 21), rel=1e-12)
    assert worst == pytest.approx(0.1, rel=1e-12)
