"""The reference backend (issue 3): diffusion decay rates, dam break, neighbour upkeep, boundaries.

Oracles are computed here independently of :mod:`mpsbench.physics.operators`: the weighting
functions
and Laplacian coefficients are written out from docs/method.md sections 1 and 3.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest
from mpsbench.solvers.reference import ReferenceSolver

from mpsbench.physics.config import FlowPhysics, Models, TimeStepping
from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.operators import number_density
from mpsbench.physics.particles import Box, Kind, Particles
from mpsbench.run.probes import Callback, LayerAverage, SurgeFront
from mpsbench.run.protocol import Problem, Status
from mpsbench.run.runner import run
from mpsbench.testing import problems

LAPLACIANS = ("koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic")
RE_RATIOS = (2.1, 3.1, 4.0)

# docs/method.md section 3, ratio of each model to the exact Laplacian on a square lattice (l0 = 1):
# "quad" phi = x^2, "mode" phi = sin(kx) sin(ky) with k l0 = 0.2.  xu-jin-analytic has no
# "mode" column in the table.
TABLE = {
    ("wf1", 2.1): {
        "koshizuka-oka": (1.000, 0.992),
        "khayyer-gotoh": (2.126, 2.108),
        "xu-jin": (1.000, 0.993),
        "xu-jin-analytic": (1.418, None),
    },
    ("wf1", 3.1): {
        "koshizuka-oka": (1.000, 0.981),
        "khayyer-gotoh": (1.857, 1.821),
        "xu-jin": (1.000, 0.988),
        "xu-jin-analytic": (1.238, None),
    },
    ("wf1", 4.0): {
        "koshizuka-oka": (1.000, 0.968),
        "khayyer-gotoh": (1.761, 1.708),
        "xu-jin": (1.000, 0.982),
        "xu-jin-analytic": (1.174, None),
    },
    ("wf2", 2.1): {
        "koshizuka-oka": (1.000, 0.993),
        "khayyer-gotoh": (3.463, 3.432),
        "xu-jin": (1.000, 0.995),
        "xu-jin-analytic": (1.718, None),
    },
    ("wf2", 3.1): {
        "koshizuka-oka": (1.000, 0.987),
        "khayyer-gotoh": (2.588, 2.535),
        "xu-jin": (1.000, 0.991),
        "xu-jin-analytic": (1.296, None),
    },
    ("wf2", 4.0): {
        "koshizuka-oka": (1.000, 0.978),
        "khayyer-gotoh": (2.358, 2.279),
        "xu-jin": (1.000, 0.987),
        "xu-jin-analytic": (1.180, None),
    },
}
# Three "quad" entries of the table sit 5.3e-4 to 6.5e-4 above the lattice sum, just beyond the
# rounding of their last digit: LM2 / WF2 / 2.1 is 3.4624 (table 3.463), LM3-analytic / WF1 / 2.1
# is 1.4175 (1.418) and LM3-analytic / WF2 / 4.0 is 1.1794 (1.180).  Every "mode" entry agrees
# to rounding.  The slips are listed here rather than hidden in a looser tolerance.
TABLE_SLIPS = {
    ("wf2", 2.1, "khayyer-gotoh", "quad"): 7e-4,
    ("wf1", 2.1, "xu-jin-analytic", "quad"): 7e-4,
    ("wf2", 4.0, "xu-jin-analytic", "quad"): 7e-4,
}


# --------------------------------------------------------------------------- lattice oracle


def _weight(wf: str, r: np.ndarray, re: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """W, W', W'' of docs/method.md section 1, written out again (independent of
    mpsbench.physics.weights)."""
    if wf == "wf1":
        return re / r - 1.0, -re / r**2, 2.0 * re / r**3
    q = 1.0 - r / re
    return q**3, -(3.0 / re) * q**2, (6.0 / re**2) * q


def lattice_coefficients(laplacian: str, wf: str, re_ratio: float):
    """Offsets (dx, dy) of the neighbours of a square-lattice particle (l0 = 1) and c_j."""
    m = int(math.ceil(re_ratio)) + 1
    ix, iy = np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1), indexing="ij")
    dx, dy = ix.ravel().astype(float), iy.ravel().astype(float)
    r = np.hypot(dx, dy)
    keep = (r > 0) & (r <= re_ratio)
    dx, dy, r = dx[keep], dy[keep], r[keep]
    w, dw, d2w = _weight(wf, r, re_ratio)
    n0 = w.sum()
    lam = (r**2 * w).sum() / n0
    dim = 2
    c = {
        "koshizuka-oka": 2 * dim / (lam * n0) * w,
        "khayyer-gotoh": (d2w - dw / r) / n0,
        "xu-jin": 2 * dim / n0 * w / r**2,
        "xu-jin-analytic": dim / n0 * (-dw / r),
    }[laplacian]
    return dx, dy, c


def mode_eigenvalue(laplacian: str, wf: str, re_ratio: float, kl0: float) -> float:
    """Eigenvalue of the lattice operator for sin(kx) sin(ky), l0 = 1.

    Per neighbour, sin(k(x+dx)) sin(k(y+dy)) - sin(kx) sin(ky) = [cos(k dx) cos(k dy) - 1]
    sin(kx) sin(ky) + terms odd in dx or dy, which cancel over the symmetric lattice stencil:
    lambda = sum_j c_j (cos(k dx_j) cos(k dy_j) - 1).  Exact: -2 k^2.
    """
    dx, dy, c = lattice_coefficients(laplacian, wf, re_ratio)
    return float((c * (np.cos(kl0 * dx) * np.cos(kl0 * dy) - 1.0)).sum())


@pytest.mark.parametrize("wf, re_ratio", sorted(TABLE))
def test_lattice_sum_reproduces_method_table(wf: str, re_ratio: float) -> None:
    """The oracle used below reproduces docs/method.md's table at k l0 = 0.2 (to its rounding)."""
    for lap, (quad, mode) in TABLE[(wf, re_ratio)].items():
        dx, _, c = lattice_coefficients(lap, wf, re_ratio)
        got_quad = float((c * dx**2).sum()) / 2.0  # lap(x^2) = sum c dx^2, exact 2
        tol = TABLE_SLIPS.get((wf, re_ratio, lap, "quad"), 5e-4) + 1e-9
        assert got_quad == pytest.approx(quad, abs=tol), (lap, "quad")
        if mode is not None:
            got_mode = mode_eigenvalue(lap, wf, re_ratio, 0.2) / (-2 * 0.2**2)
            assert got_mode == pytest.approx(mode, abs=5e-4 + 1e-9), (lap, "mode")


# --------------------------------------------------------------------------- diffusion decay


def _decay_rate(laplacian: str, wf: str, re_ratio: float, n_side: int, dt: float, n: int) -> float:
    """Measured decay rate of sin(2 pi x) sin(2 pi y) after ``n`` steps of ``dt`` (kappa = 1).

    The amplitude is the projection on the initial field; the mode is an exact eigenvector of
    the operator on the periodic lattice, so the projection is (1 + dt lambda)^n to round-off.
    """
    problem = problems.diffusion_problem(
        laplacian, wf, n_side=n_side, amplitude=0.0, value=None, re_ratio=re_ratio, dt=dt
    )
    phi0 = problem.particles.fields["phi"].copy()
    result = run("reference", problem, max_steps=n)
    assert result.status == Status.COMPLETED, result.reason
    assert result.final is not None
    amplitude = float(result.final.fields["phi"] @ phi0 / (phi0 @ phi0))
    return -math.log(amplitude) / result.time


@pytest.mark.parametrize("wf", ["wf1", "wf2"])
@pytest.mark.parametrize("laplacian", LAPLACIANS)
def test_diffusion_decay_rate_matches_lattice_eigenvalue(laplacian: str, wf: str) -> None:
    """Decay rate of the mode on a periodic unit square, every Laplacian x WF x r_e/l0.

    Reasoning.  On the periodic unit square sin(2 pi x) sin(2 pi y) has k = 2 pi and the
    lattice must hold whole periods, so k l0 = 2 pi / n_side can never be exactly 0.2 (the table's
    value, 2 pi / 0.2 = 31.4 is not an integer).  We take n_side = 32 (k l0 = 0.196, closest),
    compute the model's exact discrete eigenvalue lambda for that mode from the lattice sum
    (independent code above; checked against the table at k l0 = 0.2 by the test above), and
    require the measured decay rate kappa |lambda| to 1e-3 relative (it holds to 1e-4, and to
    1e-7 after Richardson extrapolation in dt); the decay-rate ratio
    rate / (8 pi^2 kappa) then is the table's "mode" ratio at k l0 = 0.196.

    Time stepping: forward Euler decays the mode as (1 + dt lambda)^n, a relative rate error of
    about dt |lambda| / 2.  With dt |lambda| = 1e-4 that is 5e-5 < 1e-4; we check it by running
    dt and dt/2 (the difference estimates half the error of the dt run).
    """
    n_side = 32
    kl0 = 2 * math.pi / n_side
    l0 = 1.0 / n_side
    for re_ratio in RE_RATIOS:
        lam = mode_eigenvalue(laplacian, wf, re_ratio, kl0) / l0**2  # units 1/m^2
        dt = 1e-4 / abs(lam)
        rate = _decay_rate(laplacian, wf, re_ratio, n_side, dt, 200)
        rate_half = _decay_rate(laplacian, wf, re_ratio, n_side, dt / 2, 400)
        time_error = 2.0 * abs(rate - rate_half) / rate_half  # Richardson, first order
        assert time_error < 1e-4, (re_ratio, time_error)
        assert rate_half == pytest.approx(-lam, rel=1e-4), re_ratio  # asked: 1e-3
        # Richardson-extrapolated, the solver's operator and the oracle agree far closer
        assert 2 * rate_half - rate == pytest.approx(-lam, rel=1e-7), re_ratio
        ratio = rate_half / (8 * math.pi**2)
        assert ratio == pytest.approx(lam / (-2 * (2 * math.pi) ** 2), rel=1e-3)
        # and the table itself (k l0 = 0.2 there, 0.196 here: within a few 1e-3)
        mode = TABLE[(wf, re_ratio)][laplacian][1]
        if mode is not None:
            assert ratio == pytest.approx(mode, rel=3e-3), re_ratio


def test_diffusion_stable_dt_is_stable_for_every_model() -> None:
    """Running at the solver's own dt (c_nu = 0.5 of the Gershgorin limit) never amplifies."""
    for laplacian in LAPLACIANS:
        problem = problems.diffusion_problem(
            laplacian, "wf2", n_side=16, value=None, re_ratio=2.1, amplitude=0.1
        )
        result = run("reference", problem, max_steps=200)
        assert result.status == Status.COMPLETED, (laplacian, result.reason)
        assert result.final is not None
        phi = result.final.fields["phi"]
        assert np.max(np.abs(phi)) <= np.max(np.abs(problem.particles.fields["phi"]))


# --------------------------------------------------------------------------- dam break


def test_dam_break_runs_to_half_a_second_with_xu_jin_and_stabilization() -> None:
    """Koshizuka & Oka geometry, l0 = 1 cm, c0 = 10 sqrt(2 g H), WF2, PGM1, 2.1 / 3.1 l0.

    The column is 15 x 29 particles (0.146 / 0.01 and 0.292 / 0.01 rounded).
    """
    problem = problems.dam_break_problem(stabilization=True)
    assert problem.models == Models(
        weight="wf2", laplacian="xu-jin", gradient="pgm1", re_ratio=2.1, re_ratio_laplacian=3.1
    )
    front = SurgeFront("front", axis=0, below=0.1, at=[0.1, 0.2])
    result = run("reference", problem, end_time=0.5, probes=[front])
    assert result.status == Status.COMPLETED, result.reason
    assert result.time == 0.5
    assert result.final is not None
    assert result.final.n == problem.particles.n
    fluid = result.final.kind == Kind.FLUID
    assert np.all(result.final.pos[fluid, 1] > 0.0)  # nothing fell through the floor
    assert np.all((result.final.pos[fluid, 0] > 0.0) & (result.final.pos[fluid, 0] < 0.584))
    # sanity of the surge (Martin & Moyce: Z = z/L ~ 2.8 at T = t sqrt(2g/L) = 2.32, t = 0.2 s)
    z = np.asarray(front.values) / 0.146
    assert 1.5 < z[0] < 2.5 and 2.2 < z[1] < 3.2, z


def test_dam_break_with_a_huge_fixed_dt_is_reported_as_diverged() -> None:
    problem = problems.dam_break_problem(stabilization=True)
    solver = ReferenceSolver()
    solver.setup(problem)
    cfl_dt = solver.stable_dt()
    ph = problem.physics
    assert isinstance(ph, FlowPhysics)
    assert cfl_dt == pytest.approx(problem.time_stepping.cfl * problem.l0 / ph.c0)
    unstable = dataclasses.replace(problem, time_stepping=TimeStepping(dt=20 * cfl_dt))
    result = run("reference", unstable, end_time=0.5)
    assert result.status == Status.DIVERGED
    assert result.reason and result.time < 0.5
    assert "step" in result.reason  # where it happened


# --------------------------------------------------------------------------- neighbour upkeep


class DensitySpy(ReferenceSolver):
    """Compares every number density against a fresh full neighbour build at the same positions."""

    def _setup(self, problem: Problem) -> None:
        self.worst = 0.0
        self.checked = 0
        super()._setup(problem)

    def _number_density(self) -> np.ndarray:
        n = super()._number_density()
        fresh = build_pairs(self.p.pos, self.re, self.box)
        n_fresh = number_density(fresh, self.weight.w(fresh.r, self.re))
        self.worst = max(self.worst, float(np.max(np.abs(n - n_fresh))))
        self.checked += 1
        return n


@pytest.mark.parametrize(
    "make_problem",
    [
        lambda: problems.column_in_tank_problem(nx=10, ny=16, stabilization=True),
        lambda: problems.periodic_flow_problem(velocity=2.0, models=Models(n0_from="lattice")),
        lambda: problems.channel_problem(top_velocity=(0.5, 0.0), nu=1e-3, c0=5.0),
    ],
    ids=["dam-break", "periodic-drift", "moving-lid"],
)
def test_skinned_neighbour_list_is_never_stale(make_problem: Callable[[], Problem]) -> None:
    problem = make_problem()
    solver = DensitySpy()
    result = run(solver, problem, max_steps=400)
    assert result.status == Status.COMPLETED, result.reason
    assert solver.checked >= 400
    assert solver.worst <= 1e-12
    builds = result.counters["neighbour_builds"]
    assert 3 <= builds < 200, builds  # rebuilt as particles move, but reused in between


class GradientSpy(ReferenceSolver):
    """Compares every pressure gradient on fluid particles with one from a fresh full build."""

    def _setup(self, problem: Problem) -> None:
        self.worst = 0.0
        super()._setup(problem)

    def _pressure_gradient(self, pres: np.ndarray) -> np.ndarray:
        grad = super()._pressure_gradient(pres)
        fresh = build_pairs(self.p.pos, self.re, self.box)
        kind = self.p.kind
        keep = (kind[fresh.i] != Kind.DUMMY) & (kind[fresh.j] != Kind.DUMMY)
        w = np.where(keep, self.weight.w(fresh.r, self.re), 0.0)
        want = self.gradient(fresh, pres, w, self.n0)
        fluid = kind == Kind.FLUID
        scale = float(np.abs(want[fluid]).max()) or 1.0
        self.worst = max(self.worst, float(np.abs(grad[fluid] - want[fluid]).max()) / scale)
        return grad


@pytest.mark.parametrize("gradient", ["pgm1", "pgm2", "pgm3"])
def test_pressure_gradient_near_walls_matches_a_full_neighbour_build(gradient: str) -> None:
    """Regression: wall-wall pairs were dropped as static, so pmin of a wall particle (PGM2)
    missed its wall neighbours and the wall force on nearby fluid was off by up to 85 %."""
    models = Models(gradient=gradient, re_ratio=2.1, re_ratio_laplacian=3.1)
    problem = problems.column_in_tank_problem(nx=10, ny=16, models=models, stabilization=True)
    solver = GradientSpy()
    result = run(solver, problem, max_steps=300)
    assert result.status == Status.COMPLETED, result.reason
    assert solver.worst <= 1e-12


# --------------------------------------------------------------------------- boundaries


@pytest.mark.parametrize("wall_velocity", ["prescribed", "mirror"])
def test_moving_wall_develops_a_linear_couette_profile(wall_velocity: str) -> None:
    """x-periodic channel, lid moving at U (WallMotion); steady u(y) is linear.

    With ``prescribed`` every boundary row carries the wall velocity, so the no-slip points sit
    near the first wall rows (y = -l0/2 and H + l0/2); with ``mirror`` they sit on the wall lines
    y = 0 and y = H.  nu = 0.01 m^2/s over H = 0.1 m: diffusion time H^2/nu = 1 s, so after 1 s
    the slowest transient mode is down to about exp(-pi^2) ~ 1e-4 U.  Measured: both within
    0.1 % of U of their exact profiles (a Shepard average at the mirror points, first order near
    the wall, was 0.7 % of U off).
    """
    l0, ny, u_lid = 0.01, 10, 0.01
    height = ny * l0
    problem = problems.channel_problem(
        nx=12,
        ny=ny,
        l0=l0,
        top_velocity=(u_lid, 0.0),
        nu=0.01,
        c0=1.0,
        wall_velocity=wall_velocity,
    )
    layers = LayerAverage("u", 1, list(np.linspace(0.0, height, ny + 1)), "u", at=[1.0])
    result = run("reference", problem, end_time=1.0, probes=[layers])
    assert result.status == Status.COMPLETED, result.reason
    u = np.asarray(layers.values[-1]) / u_lid
    y = layers.centres
    slope, offset = np.polyfit(y, u, 1)
    assert np.max(np.abs(slope * y + offset - u)) < 0.005  # linear to 0.5 % of U
    if wall_velocity == "prescribed":
        exact = (y + 0.5 * l0) / (height + l0)
    else:
        exact = y / height
    assert np.max(np.abs(u - exact)) < 0.003, (u, exact)  # 0.3 % of U


def test_inflow_and_outflow_keep_a_steady_particle_count() -> None:
    """Fluid enters at x = 0 and leaves through the outflow region: the count stays steady
    while every original fluid particle is flushed out (both boundaries really worked)."""
    problem = problems.open_channel_problem(nx=12, ny=6, speed=0.2)
    problem.particles.fields["dye"] = (problem.particles.kind == Kind.FLUID).astype(float)
    n_fluid0 = int((problem.particles.kind == Kind.FLUID).sum())
    count = Callback("n_fluid", lambda s: int((s.state().kind == Kind.FLUID).sum()), every=0.05)
    result = run("reference", problem, end_time=0.8, probes=[count])
    assert result.status == Status.COMPLETED, result.reason
    counts = np.asarray(count.values)
    assert np.all(np.abs(counts - n_fluid0) <= 6), counts  # within one row of 6 particles
    final = result.final
    assert final is not None
    fluid = final.kind == Kind.FLUID
    assert final.fields["dye"][fluid].sum() == 0  # 0.16 m travelled > 0.12 m channel
    inflow = final.kind == Kind.INFLOW
    assert 6 * 3 <= inflow.sum() <= 6 * 5  # the reservoir keeps about `layers` rows


def _pair_problem(collision: bool, vel: tuple[tuple[float, float], tuple[float, float]]) -> Problem:
    l0 = 0.01
    p = Particles.from_positions(np.array([[0.0, 0.0], [0.5 * l0, 0.1 * l0]]))
    p.vel[:] = vel
    ph = FlowPhysics(
        gravity=(0.0, 0.0),
        nu=0.0,
        c0=10.0,
        collision=collision,
        collision_distance=0.8,
        restitution=0.2,
    )
    box = Box((-1.0, -1.0), (1.0, 1.0))
    return Problem(p, box, l0, ph, Models(n0_from="lattice"), TimeStepping(dt=1e-6))


def test_collision_removes_the_approaching_velocity_of_a_close_pair() -> None:
    """Lee et al.: the normal relative velocity of an approaching close pair turns into
    -e times itself; the tangential part and the total momentum are unchanged."""
    vel = ((0.1, 0.02), (-0.1, 0.0))
    e = 0.2
    states = {}
    for collision in (False, True):
        s = ReferenceSolver()
        s.setup(_pair_problem(collision, vel))
        s.step(1e-6)
        states[collision] = s.state().copy()
    without, with_ = states[False], states[True]
    np.testing.assert_array_equal(without.vel, np.array(vel))  # no pressure, no viscosity
    d = with_.pos[1] - with_.pos[0]
    n = d / np.linalg.norm(d)
    rel_before = np.array(vel[0]) - np.array(vel[1])
    rel_after = with_.vel[0] - with_.vel[1]
    assert rel_before @ n > 0  # approaching
    assert rel_after @ n == pytest.approx(-e * (rel_before @ n), rel=1e-9)
    t = np.array([-n[1], n[0]])
    assert rel_after @ t == pytest.approx(rel_before @ t, rel=1e-9)
    np.testing.assert_allclose(with_.vel.sum(axis=0), np.array(vel).sum(axis=0), atol=1e-15)


def test_collision_leaves_a_separating_pair_alone() -> None:
    vel = ((-0.1, 0.0), (0.1, 0.0))
    s = ReferenceSolver()
    s.setup(_pair_problem(True, vel))
    s.step(1e-6)
    np.testing.assert_array_equal(s.state().vel, np.array(vel))


def test_stabilization_reduces_velocity_noise_of_a_resting_periodic_fluid() -> None:
    """A jittered fluid at rest in a periodic box: pressure noise sets it moving; the
    stabilization (alpha_s = 0.01) keeps the RMS speed an order of magnitude lower."""
    rms = {}
    for stab in (False, True):
        problem = problems.periodic_flow_problem(
            n_side=16, amplitude=0.1, models=Models(n0_from="lattice"), stabilization=stab
        )
        result = run("reference", problem, max_steps=300)
        assert result.status == Status.COMPLETED, result.reason
        assert result.final is not None
        fluid = result.final.kind == Kind.FLUID
        rms[stab] = float(np.sqrt((result.final.vel[fluid] ** 2).sum(axis=1).mean()))
    assert rms[False] > 0.01  # the noise is real
    assert rms[True] < 0.25 * rms[False], rms


def test_setup_copies_the_problem_and_rejects_a_missing_field() -> None:
    problem = problems.diffusion_problem(value=None)
    del problem.particles.fields["phi"]
    with pytest.raises(ValueError, match="phi"):
        ReferenceSolver().setup(problem)
