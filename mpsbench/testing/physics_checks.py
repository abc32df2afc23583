"""Physics checks of the conformance kit: what a backend computes, not only that it runs.

Each check runs a small problem through the solver's own ``setup`` and ``step`` and holds the
result against an oracle the kit computes itself from the model definitions
(:mod:`mpsbench.physics`: the registered Laplacian, gradient and weighting function applied to
the same positions, ``lattice_constants``, the equation of state, the time-step rule), or
against a physical fact (a resting column stays at rest, a uniform drift crosses a periodic box
unchanged, a fluid in free fall accelerates at g).  Tolerances are round-off sized where the
oracle is exact (the kit and the backend evaluate the same formula) and physical where it is
not (the hydrostatic column); each check's docstring says which.

The checks are gated by capability (a backend that ``ignores`` MPS Laplacians, such as an
outside SPH code, skips the Laplacian oracle with that reason).  docs/solver-contract.md
section 11 lists the checks and which injected bug each one catches.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.gradients import GRADIENTS, get_gradient
from mpsbench.physics.laplacians import LAPLACIANS, get_laplacian
from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.operators import SHIFTING, lattice_constants, number_density, pair_formula
from mpsbench.physics.particles import Kind
from mpsbench.physics.weights import get_weight
from mpsbench.run.protocol import Capabilities, Problem
from mpsbench.run.scheme import EquationOfState

from . import problems
from .checks import Check, Factory, SkipCheck, _models, _pick, _supports, _with_dt

G = 9.81


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / max |b| (max |a - b| when b is all zero)."""
    scale = float(np.max(np.abs(b))) if b.size else 0.0
    err = float(np.max(np.abs(a - b))) if a.size else 0.0
    return err / scale if scale > 0 else err


def _one_step(make: Factory, problem: Problem, dt: float) -> Any:
    s = make()
    s.setup(_with_dt(problem, dt))
    s.step(dt)
    return s


def _explicit_only(caps: Capabilities, what: str) -> None:
    """Skip a check that holds the explicit WC-MPS one-step update for another scheme."""
    scheme = getattr(caps, "scheme", "explicit")
    if scheme != "explicit":
        raise SkipCheck(f"{what} holds the explicit WC-MPS scheme; this backend's scheme is "
                        f"{scheme} (docs/method.md section 10)")


def _diag(s: Any, key: str) -> Any:
    value = s.diagnostics().get(key)
    if value is None:
        raise SkipCheck(f"solver reports no {key!r} in diagnostics()")
    return value


# --------------------------------------------------------------------------- Laplacian


def check_laplacian_oracle(make: Factory, caps: Capabilities, laplacian: str) -> None:
    """One step of the solver against the Laplacian's definition on the same particles.

    Diffusion (jittered periodic cloud): phi1 - phi0 = dt kappa L phi0, L assembled by the kit
    from the registered model (``LaplacianModel.matrix``).  Flow (periodic lattice, a shear
    wave u = U sin(2 pi y / L_box), no gravity, a sound speed so low that the pressure of the
    sheared lattice is below round-off): u1 - u0 = dt nu lap(u0).  Round-off tolerance (1e-9
    of the change): the kit and the backend evaluate the same formula.
    """
    _explicit_only(caps, "the one-step Laplacian oracle")
    ran = 0
    weight = _pick(caps, "weights", "wf2")
    wf = get_weight(weight)
    model = get_laplacian(laplacian)
    if _supports(caps, "physics", "diffusion") and _supports(caps, "boundaries", "periodic"):
        ran += 1
        problem = problems.diffusion_problem(laplacian, weight, value=None, re_ratio=3.1)
        ph = problem.physics
        re = problem.models.re_lap_ratio * problem.l0
        n0, lam = lattice_constants(wf, problem.models.re_lap_ratio, problem.l0)
        pairs = build_pairs(problem.particles.pos, re, problem.box)
        mat = model.matrix(pairs, wf, re, n0, lam)
        s0 = make()
        s0.setup(problem)
        dt = 0.5 * float(s0.stable_dt())
        phi0 = problem.particles.fields["phi"].copy()
        s = _one_step(make, problem, dt)
        got = s.state().fields["phi"] - phi0
        want = dt * ph.kappa * (mat @ phi0)  # type: ignore[union-attr]
        err = _rel(got, want)
        assert err <= 1e-9, (
            f"[diffusion] one step of {laplacian!r} differs from dt kappa L phi of the model's "
            f"definition by {err:.3g} (relative to the change; round-off is 1e-12)")
    if _supports(caps, "physics", "flow") and _supports(caps, "boundaries", "periodic"):
        ran += 1
        models = _models(caps, laplacian=laplacian, weight=weight, re_ratio=2.1,
                         re_ratio_laplacian=3.1, n0_from="lattice")
        problem = problems.periodic_flow_problem(amplitude=0.0, models=models, nu=1e-2,
                                                 c0=1e-3, gravity=(0.0, 0.0))
        p0 = problem.particles
        length = problem.box.hi[1] - problem.box.lo[1]
        p0.vel[:, 0] = 1e-5 * np.sin(2 * np.pi * (p0.pos[:, 1] - problem.box.lo[1]) / length)
        re = models.re_lap_ratio * problem.l0
        n0, lam = lattice_constants(wf, models.re_lap_ratio, problem.l0)
        pairs = build_pairs(p0.pos, re, problem.box)
        mat = model.matrix(pairs, wf, re, n0, lam)
        dt = 1e-4
        u0 = p0.vel.copy()
        s = _one_step(make, problem, dt)
        got = s.state().vel - u0
        want = np.column_stack([dt * 1e-2 * (mat @ u0[:, 0]), dt * 1e-2 * (mat @ u0[:, 1])])
        err = _rel(got, want)
        assert err <= 1e-9, (
            f"[flow] the viscous step of {laplacian!r} on a shear wave differs from dt nu "
            f"lap(u) of the model's definition by {err:.3g} (relative; round-off is 1e-12)")
    if not ran:
        raise SkipCheck("solver declares neither periodic diffusion nor periodic flow")


# --------------------------------------------------------------------------- pressure gradient


def check_gradient_oracle(make: Factory, caps: Capabilities, gradient: str) -> None:
    """One step from rest of a compressed periodic lattice against the gradient's definition.

    The lattice is displaced by 0.1 l0 sin(2 pi x / L_box) along x (density +-5 %, no free
    surface: beta 0.5, no clipping), without gravity or viscosity, so after one step from rest
    u = -(dt / rho0) grad(p) with p the equation of state of n at these positions.  The kit
    evaluates n, p and the registered gradient model itself; round-off tolerance (1e-9).
    """
    _explicit_only(caps, "the one-step pressure-gradient oracle")
    models = _models(caps, gradient=gradient, n0_from="lattice")
    problem = problems.periodic_flow_problem(
        amplitude=0.0, models=models, nu=0.0, surface_beta=0.5, clip_negative_pressure=False)
    p0 = problem.particles
    length = problem.box.hi[0] - problem.box.lo[0]
    p0.pos[:, 0] += 0.1 * problem.l0 * np.sin(2 * np.pi * (p0.pos[:, 0] - problem.box.lo[0])
                                               / length)
    ph = problem.physics
    assert isinstance(ph, FlowPhysics)
    wf = get_weight(models.weight)
    re = models.re_ratio * problem.l0
    n0, _ = lattice_constants(wf, models.re_ratio, problem.l0)
    pairs = build_pairs(p0.pos, re, problem.box)
    w = wf.w(pairs.r, re)
    pres, surface = EquationOfState.of(ph, n0).pressure(number_density(pairs, w), p0.kind)
    assert not surface.any()
    dt = 1e-4
    want = -(dt / ph.rho0) * get_gradient(gradient)(pairs, pres, w, n0)
    s = _one_step(make, problem, dt)
    got = s.state().vel
    err = _rel(got, want)
    assert err <= 1e-9, (
        f"[{gradient}] the velocity after one step from rest differs from -(dt/rho0) grad(p) "
        f"of the model's definition by {err:.3g} (relative; round-off is 1e-12)")


# --------------------------------------------------------------------------- time step


def check_stable_dt_rule(make: Factory, caps: Capabilities) -> None:
    """``stable_dt()`` without a fixed dt is the contract's rule (docs/solver-contract.md 9).

    Flow (jittered periodic fluid with velocities): min(cfl l0 / (c0 + |u|max), c_nu 2 /
    (nu rho)), rho = 2 max over fluid rows of sum_j |c_ij| of the Laplacian at the initial
    positions; diffusion: c_nu 2 / (kappa rho), rho the largest absolute row sum of the
    assembled Laplacian.  The kit computes both from the model definitions; tolerance 1e-9.
    """
    _explicit_only(caps, "the sound-speed time-step rule")
    ran = 0
    weight = _pick(caps, "weights", "wf2")
    wf = get_weight(weight)
    if _supports(caps, "physics", "flow") and _supports(caps, "boundaries", "periodic"):
        ran += 1
        lap = _pick(caps, "laplacians", "xu-jin")
        models = _models(caps, laplacian=lap, n0_from="lattice", re_ratio_laplacian=3.1)
        # nu large enough that the viscous limit decides, then small enough that the CFL does
        for nu in (5e-3, 1e-6):
            problem = problems.periodic_flow_problem(velocity=0.2, models=models, nu=nu)
            ph = problem.physics
            p0 = problem.particles
            re = models.re_lap_ratio * problem.l0
            n0, lam = lattice_constants(wf, models.re_lap_ratio, problem.l0)
            pairs = build_pairs(p0.pos, re, problem.box)
            c = get_laplacian(lap).coefficients(pairs, wf, re, n0, lam)
            rows = pairs.sum_sym(np.abs(c))
            rho = 2.0 * float(rows[p0.kind == Kind.FLUID].max())
            umax = float(np.sqrt((p0.vel**2).sum(axis=1)).max())
            want, which = problem.time_stepping.limit(ph, problem.l0, umax, rho)
            s = make()
            s.setup(problem)
            got = float(s.stable_dt())
            assert math.isclose(got, want, rel_tol=1e-9), (
                f"[flow, nu = {nu:g}] stable_dt() = {got:.6g} s, the rule gives {want:.6g} s "
                f"(the {which} limit)")
    if _supports(caps, "physics", "diffusion") and _supports(caps, "boundaries", "periodic"):
        ran += 1
        lap = _pick(caps, "laplacians", "xu-jin")
        problem = problems.diffusion_problem(lap, weight, value=None, re_ratio=3.1)
        re = problem.models.re_lap_ratio * problem.l0
        n0, lam = lattice_constants(wf, problem.models.re_lap_ratio, problem.l0)
        mat = get_laplacian(lap).matrix(build_pairs(problem.particles.pos, re, problem.box),
                                        wf, re, n0, lam)
        rho = float(np.max(np.asarray(abs(mat).sum(axis=1)).ravel()))
        want = problem.time_stepping.stable_dt(problem.physics, problem.l0, 0.0, rho)
        s = make()
        s.setup(problem)
        got = float(s.stable_dt())
        assert math.isclose(got, want, rel_tol=1e-9), (
            f"[diffusion] stable_dt() = {got:.6g} s, the rule gives {want:.6g} s")
    if not ran:
        raise SkipCheck("solver declares neither periodic flow nor periodic diffusion")


# --------------------------------------------------------------------------- n0, walls


def check_n0_lattice(make: Factory, caps: Capabilities) -> None:
    """n0 and the number density of a lattice with walls that continue it.

    A column at rest in the corner of a tank (every particle on one square lattice): n0 in
    ``diagnostics()`` must be the ideal lattice's value, and every fluid particle farther than
    r_e from the free surface must have that number density (walls included in the sum);
    tolerance 1e-12.  A backend that picks n0 on the free surface, or leaves a kind of
    boundary particle out of n, fails here.
    """
    problem = problems.column_in_tank_problem(models=_models(caps))
    s = make()
    s.setup(problem)
    n0 = float(_diag(s, "n0"))
    m = problem.models
    want, _ = lattice_constants(m.weight, m.re_ratio, problem.l0)
    assert math.isclose(n0, want, rel_tol=1e-12), (
        f"n0 = {n0:.12g}, the ideal lattice gives {want:.12g} (r_e = {m.re_ratio} l0): n0 must "
        "be the largest number density of a fluid particle (docs/solver-contract.md 3)")
    n = np.asarray(_diag(s, "number_density"), float)
    p = problem.particles
    re = m.re_ratio * problem.l0
    top = p.pos[p.kind == Kind.FLUID, 1].max() + 0.5 * problem.l0
    right = p.pos[p.kind == Kind.FLUID, 0].max() + 0.5 * problem.l0
    inner = (p.kind == Kind.FLUID) & (p.pos[:, 1] < top - re) & (p.pos[:, 0] < right - re)
    assert inner.any()
    bad = np.abs(n[inner] - want) > 1e-12 * want
    if bad.any():
        k = int(np.flatnonzero(inner)[np.argmax(bad)])
        raise AssertionError(
            f"{int(bad.sum())} of {int(inner.sum())} fluid particles away from the free surface "
            f"have n != n0 (particle {k} at {tuple(np.round(p.pos[k], 4))}: n = {n[k]:.6g}, "
            f"n0 = {want:.6g}): wall and dummy particles must count in the number density")


def check_hydrostatic(make: Factory, caps: Capabilities, periods: float = 3.0) -> None:
    """A water column filling a tank, released at rest under gravity, stays at rest.

    10 x 10 particles, c0 = 10 sqrt(2 g H), run for three acoustic periods 4 H / c0 with the
    solver's own time step.  Physical tolerances: the fluid speed stays below 10 % of
    sqrt(2 g H) (the start from the uncompressed lattice gives a few per cent), no fluid
    particle goes below the floor, and the mean fluid pressure over the last two periods is
    rho0 g H / 2 within 30 % (the mean of the hydrostatic pressure; MPS pressure is noisy).
    """
    nx = ny = 10
    problem = problems.column_in_tank_problem(nx=nx, ny=ny, width_cells=nx,
                                              models=_models(caps))
    ph = problem.physics
    assert isinstance(ph, FlowPhysics)
    height = ny * problem.l0
    v_ref = math.sqrt(2 * G * height)
    period = 4.0 * height / ph.c0
    end = periods * period
    s = make()
    s.setup(problem)
    fluid = problem.particles.kind == Kind.FLUID
    umax, pressures, steps = 0.0, [], 0
    while s.time < end and steps < 20_000:
        s.step(float(s.stable_dt()))
        steps += 1
        st = s.state()
        f = st.kind == Kind.FLUID
        umax = max(umax, float(np.sqrt((st.vel[f] ** 2).sum(axis=1)).max()))
        if s.time >= end - 2 * period:
            pressures.append(float(st.pressure[f].mean()))
        assert umax <= 0.1 * v_ref, (
            f"a column at rest reached {umax:.3g} m/s (> 10 % of sqrt(2 g H) = {v_ref:.3g}) "
            f"at t = {s.time:.4g} s, step {steps}")
        low = float(st.pos[f, 1].min())
        assert low >= 0.0, f"a fluid particle went below the floor (y = {low:.3g} m)"
    assert fluid.sum() == int((s.state().kind == Kind.FLUID).sum())
    want = ph.rho0 * np.linalg.norm(ph.gravity) * height / 2
    got = float(np.mean(pressures))
    assert abs(got - want) <= 0.3 * want, (
        f"mean fluid pressure {got:.4g} Pa over the last two acoustic periods, hydrostatic "
        f"mean rho0 g H / 2 = {want:.4g} Pa (tolerance 30 %)")


# --------------------------------------------------------------------------- motion


def check_free_fall(make: Factory, caps: Capabilities) -> None:
    """A periodic lattice under gravity (no walls) falls as one: after one step u = g dt
    everywhere (pressure uniform, the Laplacian of a uniform field zero; any consistent
    integrator gives it under a constant force) and r = r0 + dt u, the MPS update (the velocity
    first, then the positions with it); tolerance 1e-6 of g dt and of g dt^2.

    A backend with its own time integration (``"time-stepping"`` in ``Capabilities.ignores``:
    PySPH's predictor-corrector, say) need not move its particles as MPS does: every particle
    must still move by the same vector, r0 + dt (u0 + theta g dt) with 0 <= theta <= 1 (theta
    = 1 the MPS update, 1/2 the trapezoidal rule of a predictor-corrector, 0 forward Euler).
    Gravity applied twice, or not at all, fails either form through u."""
    models = _models(caps, n0_from="lattice")
    problem = problems.periodic_flow_problem(amplitude=0.0, models=models, gravity=(0.0, -G))
    p0 = problem.particles.pos.copy()
    dt = 1e-4
    s = _one_step(make, problem, dt)
    st = s.state()
    want = np.array([0.0, -G * dt])
    err = float(np.abs(st.vel - want).max()) / (G * dt)
    assert err <= 1e-6, (
        f"after one step of free fall u differs from g dt by {err:.3g} of g dt (max over "
        f"particles; u_y = {st.vel[:, 1].mean():.6g} m/s, g dt = {-G * dt:.6g} m/s)")
    d = st.pos - p0
    problem.box.minimum_image(d)
    if "time-stepping" not in caps.ignores:
        moved = float(np.abs(d - dt * want).max()) / (G * dt * dt)
        assert moved <= 1e-6, f"positions after one step of free fall are off by {moved:.3g} g dt^2"
        return
    spread = float(np.abs(d - d.mean(axis=0)).max()) / (G * dt * dt)
    assert spread <= 1e-6, (
        f"after one step of free fall the particles moved by different amounts (spread "
        f"{spread:.3g} g dt^2): the lattice does not fall as one")
    theta = float(-d[:, 1].mean()) / (G * dt * dt)
    sideways = float(np.abs(d[:, 0]).max()) / (G * dt * dt)
    assert -1e-6 <= theta <= 1 + 1e-6 and sideways <= 1e-6, (
        f"after one step of free fall the particles moved by ({d[:, 0].mean():.3g}, "
        f"{d[:, 1].mean():.3g}) m: {theta:.3g} g dt^2 down (allowed: 0 to 1, from forward "
        f"Euler to the MPS update), {sideways:.3g} g dt^2 sideways (allowed: 0)")


def check_periodic_crossing(make: Factory, caps: Capabilities) -> None:
    """A uniform drift (0.5, 0.25) m/s of a periodic lattice crosses both periodic edges
    (2 l0 in x) and comes out unchanged: every particle at r0 + u t (minimum image, 1e-6 l0),
    inside the box, at the same velocity (1e-9 relative).  A wrap with the wrong period puts
    particles onto their neighbours."""
    models = _models(caps, n0_from="lattice")
    problem = problems.periodic_flow_problem(amplitude=0.0, models=models)
    drift = np.array([0.5, 0.25])
    problem.particles.vel[:] = drift
    p0 = problem.particles.pos.copy()
    end = 2.0 * problem.l0 / drift[0]
    s = make()
    s.setup(problem)
    steps = 0
    while s.time < end * (1 - 1e-12) and steps < 10_000:
        s.step(min(float(s.stable_dt()), end - s.time))
        steps += 1
    st = s.state()
    box = problem.box
    lo, hi = np.asarray(box.lo), np.asarray(box.hi)
    outside = (st.pos < lo) | (st.pos >= hi)
    assert not outside.any(), f"{int(outside.any(axis=1).sum())} particles outside the box"
    d = st.pos - (p0 + s.time * drift)
    box.minimum_image(d)
    off = float(np.abs(d).max()) / problem.l0
    assert off <= 1e-6, (
        f"after crossing the periodic edges (t = {s.time:.4g} s, {steps} steps) a particle is "
        f"{off:.3g} l0 from where the drift puts it")
    dv = float(np.abs(st.vel - drift).max())
    assert dv <= 1e-9 * float(np.abs(drift).max()), f"the drift velocity changed by {dv:.3g} m/s"


def check_stabilization_inner_only(make: Factory, caps: Capabilities) -> None:
    """The stabilization changes velocities of inner fluid particles only.

    A column in a tank with seeded random velocities, one step with and one without the
    stabilization (same fixed dt): positions are the same (it does not move particles in its
    step), the velocities of free-surface particles are the same (1e-12 relative), and some
    inner particle's differs (else the check would test nothing).
    """
    problem = problems.column_in_tank_problem(models=_models(caps), gravity=(0.0, 0.0))
    ph = problem.physics
    assert isinstance(ph, FlowPhysics)
    rng = np.random.default_rng(7)
    f = problem.particles.kind == Kind.FLUID
    problem.particles.vel[f] = rng.uniform(-0.05, 0.05, size=(int(f.sum()), 2))
    s0 = make()
    s0.setup(problem)
    dt = 0.5 * float(s0.stable_dt())
    plain = _one_step(make, problem, dt)
    stab = _one_step(make, dataclasses.replace(
        problem, physics=dataclasses.replace(ph, stabilization=True)), dt)
    surface = np.asarray(_diag(stab, "free_surface"), bool)
    a, b = plain.state(), stab.state()
    moved = float(np.abs(a.pos - b.pos).max()) / problem.l0
    assert moved <= 1e-12, f"the stabilization moved particles by {moved:.3g} l0 in its step"
    du = np.sqrt(((b.vel - a.vel) ** 2).sum(axis=1))
    scale = float(np.abs(a.vel).max())
    fs = surface & (b.kind == Kind.FLUID)
    inner = ~surface & (b.kind == Kind.FLUID)
    assert fs.any() and inner.any()
    assert float(du[inner].max()) > 1e-9 * scale, "the stabilization changed nothing"
    worst = float(du[fs].max())
    assert worst <= 1e-12 * scale, (
        f"the stabilization changed the velocity of {int((du[fs] > 1e-12 * scale).sum())} "
        f"free-surface particle(s) by up to {worst:.3g} m/s: it applies to inner fluid only")


SHIFT_COEFFICIENT = 4.0  # A of check_shifting_oracle: a shift of ~1e-3 l0 in its one step


def check_shifting_oracle(make: Factory, caps: Capabilities) -> None:
    """Particle shifting moves and corrects particles as its definition says.

    A jittered periodic box with seeded random velocities, one step with and one without
    shifting (same fixed dt, coefficient 4): the step without it is the state the shift
    starts from, and the kit applies :class:`~mpsbench.physics.operators.Shifting` to that
    state itself (its pair formulas over a pair list the kit builds, n0 of the lattice, the
    step's free-surface flags).  The shifted step must equal it to round-off (1e-9 l0 in the
    positions, 1e-9 relative in the velocities), and the shift must be visible (above 1e-4
    l0), else the check would test nothing.
    """
    problem = problems.periodic_flow_problem(models=_models(caps, n0_from="lattice"),
                                             velocity=0.2)
    ph = problem.physics
    assert isinstance(ph, FlowPhysics)
    s0 = make()
    s0.setup(problem)
    dt = 0.5 * float(s0.stable_dt())
    plain = _one_step(make, problem, dt)
    shifted = _one_step(make, dataclasses.replace(problem, physics=dataclasses.replace(
        ph, shifting=True, shifting_coefficient=SHIFT_COEFFICIENT)), dt)
    a, b = plain.state(), shifted.state()
    assert a.n == b.n, f"the runs have {a.n} and {b.n} particles"
    weight = get_weight(problem.models.weight)
    l0, box = problem.l0, problem.box
    re = problem.models.re_ratio * l0
    n0 = lattice_constants(weight, problem.models.re_ratio, l0)[0]
    pairs = build_pairs(a.pos, re, box)
    c = pair_formula(SHIFTING.pair, weight, pairs.r, re)
    g = pair_formula(SHIFTING.velocity_pair, weight, pairs.r, re)
    speed = float(np.sqrt((a.vel**2).sum(axis=1)).max())
    factor = SHIFTING.prefactor(SHIFT_COEFFICIENT, re, speed, dt, n0)
    dr = factor * pairs.sum_vec_antisym(c[:, None] * pairs.dx)
    norm = np.sqrt((dr**2).sum(axis=1))
    cap = SHIFTING.CAP * l0
    over = norm > cap
    dr[over] *= (cap / norm[over])[:, None]
    surface = np.asarray(_diag(shifted, "free_surface"), bool)
    dr[(a.kind != Kind.FLUID) | surface] = 0.0
    du = pairs.diff(a.vel)
    vel = a.vel.copy()
    for k in range(2):
        grad = pairs.sum_vec_sym((du[:, k] * g)[:, None] * pairs.dx)
        vel[:, k] += SHIFTING.gradient_factor(n0) * (grad * dr).sum(axis=1)
    carried = _rel(vel, a.vel)
    assert float(np.abs(dr).max()) > 1e-4 * l0 and carried > 1e-6, (
        f"the oracle's shift is only {float(np.abs(dr).max()) / l0:.3g} l0 and changes the "
        f"velocities by {carried:.3g} (relative): the check would test nothing")
    off = b.pos - (a.pos + dr)
    box.minimum_image(off)
    moved = float(np.abs(off).max()) / l0
    assert moved <= 1e-9, (
        f"shifted positions are {moved:.3g} l0 from the definition's (the shift itself is up "
        f"to {float(np.abs(dr).max()) / l0:.3g} l0)")
    dv = _rel(b.vel, vel)
    assert dv <= 1e-9, f"shifted velocities differ from the definition's by {dv:.3g} (relative)"


def check_sliding_wall(make: Factory, caps: Capabilities, n_steps: int = 40) -> None:
    """A sliding lid (``WallMotion(displace=False)``) keeps its particles in place, carries its
    velocity and drags the fluid.

    The x-periodic channel with its lid sliding at 0.01 m/s: after ``n_steps`` every lid
    particle is where it started (1e-12 l0) with the lid velocity (1e-12 relative), the floor
    is at rest, and the fluid row under the lid moves in +x, faster than the row above the
    floor (viscosity carries the lid's velocity in).  A backend that moves the lid shows a
    displacement of n dt U; one that drops its velocity leaves the fluid at rest.
    """
    u_lid = (0.01, 0.0)
    problem = problems.channel_problem(models=_models(caps), top_velocity=u_lid, sliding=True,
                                       nu=1.0e-4)
    lid = problem.particles.fields["wall_tag"] == 1
    x0 = problem.particles.pos.copy()
    s = make()
    s.setup(problem)
    for _ in range(n_steps):
        s.step(float(s.stable_dt()))
    st = s.state()
    # the state in the problem's order: match lid particles by kind and tag
    tag = st.fields.get("wall_tag")
    if tag is None or st.n != problem.particles.n:
        raise SkipCheck("solver state carries no 'wall_tag' field in the problem's order")
    lid_now = tag == 1
    assert _same_rows(st.pos[lid_now], x0[lid]), (
        "a sliding lid moved: its particles are up to "
        f"{float(np.abs(st.pos[lid_now] - x0[lid]).max()) / problem.l0:.3g} l0 from where they "
        f"started after {n_steps} steps")
    dv = float(np.abs(st.vel[lid_now] - np.asarray(u_lid)).max())
    assert dv <= 1e-12 * u_lid[0], f"the sliding lid's velocity changed by {dv:.3g} m/s"
    fluid = st.kind == Kind.FLUID
    y = st.pos[fluid, 1]
    u = st.vel[fluid, 0]
    top = u[y > y.max() - 0.5 * problem.l0].mean()
    bottom = u[y < y.min() + 0.5 * problem.l0].mean()
    assert top > 0.0 and top > bottom, (
        f"the fluid under a sliding lid is not dragged: mean u {top:.3g} m/s under the lid, "
        f"{bottom:.3g} m/s above the floor after {n_steps} steps")


def _same_rows(a: np.ndarray, b: np.ndarray) -> bool:
    """The same positions, up to order (a backend may reorder its particles)."""
    if a.shape != b.shape:
        return False
    ka = a[np.lexsort(a.T[::-1])]
    kb = b[np.lexsort(b.T[::-1])]
    return bool(np.abs(ka - kb).max() <= 1e-12 * max(1.0, float(np.abs(kb).max())))


# --------------------------------------------------------------------------- the catalogue


def physics_checks() -> list[Check]:
    """The physics checks, model-specific ones once per registered model."""
    flow_periodic = {"physics": frozenset({"flow"}), "boundaries": frozenset({"periodic"})}
    flow_walls = {"physics": frozenset({"flow"}), "boundaries": frozenset({"walls"})}
    out = []
    for lap in LAPLACIANS.names():
        out.append(Check(f"check_laplacian_oracle_{lap}", check_laplacian_oracle,
                         f"one step with {lap} against its definition (diffusion, viscosity)",
                         needs={"laplacians": frozenset({lap}),
                                "boundaries": frozenset({"periodic"})},
                         kwargs={"laplacian": lap}))
    for grad in GRADIENTS.names():
        out.append(Check(f"check_gradient_oracle_{grad}", check_gradient_oracle,
                         f"one step from rest with {grad} against its definition",
                         needs={**flow_periodic, "gradients": frozenset({grad})},
                         kwargs={"gradient": grad}))
    out += [
        Check("check_stable_dt_rule", check_stable_dt_rule,
              "stable_dt() follows the CFL and viscous/diffusion rule",
              needs={"time-stepping": frozenset({"rule"}),
                     "boundaries": frozenset({"periodic"})}),
        Check("check_n0_lattice", check_n0_lattice,
              "n0 and the number density of a lattice with walls are the lattice value",
              needs={**flow_walls, "radii": frozenset({"r_e"})}),
        Check("check_hydrostatic", check_hydrostatic,
              "a column at rest in a tank under gravity stays at rest, hydrostatic pressure",
              needs=flow_walls),
        Check("check_free_fall", check_free_fall,
              "a periodic fluid under gravity falls at g", needs=flow_periodic),
        Check("check_periodic_crossing", check_periodic_crossing,
              "a uniform drift crosses the periodic edges unchanged", needs=flow_periodic),
        Check("check_stabilization_inner_only", check_stabilization_inner_only,
              "the stabilization acts on inner fluid particles only",
              needs={**flow_walls, "features": frozenset({"stabilization"})}),
        Check("check_shifting_oracle", check_shifting_oracle,
              "one step with particle shifting against its definition",
              needs={**flow_periodic, "features": frozenset({"shifting"})}),
        Check("check_sliding_wall", check_sliding_wall,
              "a sliding lid stays in place, keeps its velocity and drags the fluid",
              needs={"physics": frozenset({"flow"}),
                     "boundaries": frozenset({"periodic-x", "walls", "sliding-walls"})}),
    ]
    return out
