"""The reference backend: vectorised numpy + scipy, readable first, no loops over particles.

Physics and models follow docs/method.md sections 2-5:

* diffusion: phi <- phi + dt kappa L phi, L the chosen Laplacian assembled once (particles fixed);
* flow (WC-MPS): predictor (viscosity + gravity), number density at r*, equation of state,
  free-surface detection, corrector with pgm1/2/3, optional collision, optional stabilization.

Boundary conventions: WALL particles take part in pressure (EOS) and every operator; DUMMY
particles complete the number density and carry the wall velocity into the viscous term but are
left out of the pressure gradient; INFLOW particles act like wall particles until they cross the
inlet.  Boundary particles advect with their prescribed velocity (moving walls move); only fluid
velocities are ever updated, so ``vel`` of a boundary particle always is its wall velocity.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mpsbench.physics.boundaries import (
    InflowBoundary,
    carry,
    mirror_velocity,
    update_open_boundaries,
)
from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.neighbours import PairList, build_pairs
from mpsbench.physics.operators import (
    get_gradient,
    get_laplacian,
    lattice_constants,
    number_density,
)
from mpsbench.physics.particles import Kind, Particles
from mpsbench.physics.weights import get_weight
from mpsbench.run.protocol import Capabilities, Problem, SolverBase

from .neighbours import SkinnedPairs

FloatArray = NDArray[np.float64]


class ReferenceSolver(SolverBase):
    """Vectorised numpy/scipy WC-MPS and diffusion backend (the reference for all others)."""

    name = "reference"
    version = "1.0"
    capabilities = Capabilities()
    skin_ratio = 0.3  # neighbour-list skin in units of l0

    # ------------------------------------------------------------------ setup
    def _setup(self, problem: Problem) -> None:
        m = problem.models
        self.l0 = problem.l0
        self.box = problem.box
        self.weight = get_weight(m.weight)
        self.laplacian = get_laplacian(m.laplacian, gradient_correction=m.gradient_correction)
        self.re = m.re_ratio * self.l0
        self.re_lap = m.re_lap_ratio * self.l0
        self.p = problem.particles.copy()
        self.inflow: InflowBoundary | None = None
        if problem.inflow is not None:
            self.inflow = InflowBoundary(problem.inflow, self.l0)
            self.p = Particles.concat([self.p, self.inflow.initial()])
        for motion in problem.wall_motions:
            tagged = self.p.fields.get("wall_tag", np.full(self.p.n, -1.0)) == motion.tag
            self.p.vel[tagged & (self.p.kind != Kind.FLUID)] = motion.velocity
        self.n0, _ = self._reference_constants(self.re)
        self.n0_lap, self.lam = self._reference_constants(self.re_lap)
        self.number_density = np.zeros(self.p.n)
        self.free_surface = np.zeros(self.p.n, dtype=bool)
        self._lap_rowsum = 0.0
        if isinstance(problem.physics, DiffusionPhysics):
            self._setup_diffusion(problem.physics)
        else:
            self._setup_flow(problem.physics)

    def _reference_constants(self, re: float) -> tuple[float, float]:
        """n0 and lambda: ideal lattice, or the fullest-support particle of the initial state."""
        if self.problem is not None and self.problem.models.n0_from == "lattice":
            return lattice_constants(self.weight, re / self.l0, self.l0)
        pairs = build_pairs(self.p.pos, re, self.box)
        w = self.weight.w(pairs.r, re)
        n = number_density(pairs, w)
        cand = self.p.kind == Kind.FLUID
        if not cand.any():
            cand = np.ones(self.p.n, dtype=bool)
        idx = int(np.nonzero(cand)[0][np.argmax(n[cand])])
        mask_i = pairs.i == idx
        mask_j = pairs.j == idx
        r = np.concatenate([pairs.r[mask_i], pairs.r[mask_j]])
        ww = np.concatenate([w[mask_i], w[mask_j]])
        n0 = float(ww.sum())
        if n0 <= 0:
            raise ValueError(f"no particle has neighbours within r_e = {re}")
        return n0, float((r**2 * ww).sum() / n0)

    # ------------------------------------------------------------------ diffusion
    def _setup_diffusion(self, physics: DiffusionPhysics) -> None:
        if physics.field_name not in self.p.fields:
            raise ValueError(
                f"diffusion needs the scalar field {physics.field_name!r} "
                "in Problem.particles.fields"
            )
        pairs = build_pairs(self.p.pos, self.re_lap, self.box)
        self.counters["neighbour_builds"] += 1
        self.matrix: sp.csr_matrix = self.laplacian.matrix(
            pairs, self.weight, self.re_lap, self.n0_lap, self.lam
        )
        # Gershgorin bound of the spectral radius of L
        self._lap_rowsum = float(np.max(np.asarray(abs(self.matrix).sum(axis=1)).ravel()))
        if self.re > self.re_lap:
            pairs = build_pairs(self.p.pos, self.re, self.box)
        self.number_density = number_density(pairs, self.weight.w(pairs.r, self.re))

    def _advance_diffusion(self, dt: float, physics: DiffusionPhysics) -> None:
        phi = self.p.fields[physics.field_name]
        phi += (dt * physics.kappa) * (self.matrix @ phi)

    # ------------------------------------------------------------------ flow
    def _setup_flow(self, physics: FlowPhysics) -> None:
        self.gradient = get_gradient(self.problem.models.gradient)  # type: ignore[union-attr]
        self.neigh = SkinnedPairs(max(self.re, self.re_lap), self.skin_ratio * self.l0, self.box)
        pairs = self.neigh.get(self.p, self.weight, self.re)
        self.counters["neighbour_builds"] = self.neigh.builds
        self.number_density = self._density(pairs)
        self._update_lap_rowsum(pairs)

    def _density(self, pairs: PairList) -> FloatArray:
        w = self.weight.w(pairs.r, self.re)
        self._w = w
        assert self.neigh.static_n is not None
        return number_density(pairs, w) + self.neigh.static_n

    def _update_lap_rowsum(self, pairs: PairList) -> FloatArray:
        c = self.laplacian.coefficients(pairs, self.weight, self.re_lap, self.n0_lap, self.lam)
        fluid = self.p.kind == Kind.FLUID
        rows = pairs.sum_sym(np.abs(c))
        self._lap_rowsum = float(rows[fluid].max()) if fluid.any() else 0.0
        return c

    def _advance_flow(self, dt: float, ph: FlowPhysics) -> None:
        p = self.p
        fluid = p.kind == Kind.FLUID
        # ---- predictor: viscosity + gravity, then move
        pairs = self.neigh.get(p, self.weight, self.re)
        c = self._update_lap_rowsum(pairs)
        u_visc = p.vel
        if ph.wall_velocity == "mirror":
            u_visc = mirror_velocity(p, self.weight, self.re, self.box)
        acc = np.zeros_like(p.vel)
        if ph.nu > 0:
            acc = ph.nu * self.laplacian.apply(
                pairs, u_visc, self.weight, self.re_lap, self.n0_lap, self.lam, coef=c
            )
        acc += np.asarray(ph.gravity)
        p.vel[fluid] += dt * acc[fluid]
        disp = dt * p.vel
        p.pos += disp
        self.neigh.note_motion(disp)
        self.box.wrap(p.pos)
        # ---- number density at r*, equation of state, free surface
        pairs = self.neigh.get(p, self.weight, self.re)
        n = self._density(pairs)
        self.number_density = n
        p.pressure[:] = self._pressure(n, ph)
        # ---- corrector: pressure gradient without dummy particles
        grad = self._pressure_gradient(pairs, p.pressure)
        du = np.zeros_like(p.vel)
        du[fluid] = -(dt / ph.rho0) * grad[fluid]
        if ph.collision:
            du += self._collision(pairs, p.vel + du, ph)
        p.vel += du
        disp = dt * du
        p.pos += disp
        self.neigh.note_motion(disp)
        if ph.stabilization:
            p.vel += self._stabilization(pairs, ph)
        self.box.wrap(p.pos)
        self._update_open_boundaries(dt)

    def _pressure(self, n: FloatArray, ph: FlowPhysics) -> FloatArray:
        ratio = n / self.n0
        if ph.eos == "tait":
            pres = (ph.rho0 * ph.c0**2 / ph.gamma) * (ratio**ph.gamma - 1.0)
        else:
            pres = ph.rho0 * ph.c0**2 * (ratio - 1.0)
        if ph.clip_negative_pressure:
            np.maximum(pres, 0.0, out=pres)
        kind = self.p.kind
        carries = (kind == Kind.FLUID) | (kind == Kind.WALL) | (kind == Kind.INFLOW)
        self.free_surface = carries & (n < ph.surface_beta * self.n0)
        pres[self.free_surface | ~carries] = 0.0
        return pres

    def _pressure_gradient(self, pairs: PairList, pres: FloatArray) -> FloatArray:
        # Dummy particles only complete the number density: a zero weight drops their pairs
        # (cheaper than building a sub-list every step).
        w = np.where(self.neigh.no_dummy, self._w, 0.0)
        return self.gradient(pairs, pres, w, self.n0, 2)

    def _collision(self, pairs: PairList, vel: FloatArray, ph: FlowPhysics) -> FloatArray:
        """Lee et al. (2011): remove the approaching normal velocity of too-close pairs."""
        kind = self.p.kind
        fi = kind[pairs.i] == Kind.FLUID
        fj = kind[pairs.j] == Kind.FLUID
        close = (pairs.r < ph.collision_distance * self.l0) & (fi | fj)
        du_rel = vel[pairs.i] - vel[pairs.j]
        approach = (du_rel * pairs.dx).sum(axis=1)
        act = close & (approach > 0)
        out = np.zeros_like(vel)
        if not act.any():
            return out
        # equal masses between fluid particles; a boundary particle is infinitely heavy
        share_i = np.where(fj, 0.5, 1.0)[act]
        share_j = np.where(fi, 0.5, 1.0)[act]
        imp = ((1.0 + ph.restitution) * approach[act] / pairs.r[act] ** 2)[:, None] * pairs.dx[act]
        ii, jj = pairs.i[act], pairs.j[act]
        for ax in range(2):
            out[:, ax] -= np.bincount(ii, share_i * imp[:, ax], self.p.n)
            out[:, ax] += np.bincount(jj, share_j * imp[:, ax], self.p.n)
        out[kind != Kind.FLUID] = 0.0
        return out

    def _stabilization(self, pairs: PairList, ph: FlowPhysics) -> FloatArray:
        """u_i -= (alpha_s l0 / n0) sum_j W'_ij (u_j - u_i) for inner fluid particles."""
        kind = self.p.kind
        use = np.ones(len(pairs), dtype=bool)
        if not ph.stabilization_walls:
            use = (kind[pairs.i] == Kind.FLUID) & (kind[pairs.j] == Kind.FLUID)
        dw = np.where(use, self.weight.dw(pairs.r, self.re), 0.0)
        du = pairs.diff(self.p.vel)
        out = np.empty_like(self.p.vel)
        for ax in range(2):
            out[:, ax] = pairs.sum_antisym(dw * du[:, ax])
        out *= -ph.alpha_s * self.l0 / self.n0
        inner = (kind == Kind.FLUID) & ~self.free_surface
        out[~inner] = 0.0
        return out

    def _update_open_boundaries(self, dt: float) -> None:
        assert self.problem is not None
        self.p, keep = update_open_boundaries(self.p, self.inflow, self.problem.outflows, dt)
        if keep is not None:
            self.number_density = carry(self.number_density, keep)
            self.free_surface = carry(self.free_surface, keep)
            self.neigh.invalidate()

    # ------------------------------------------------------------------ protocol
    def _advance(self, dt: float) -> None:
        ph = self.problem.physics  # type: ignore[union-attr]
        if isinstance(ph, DiffusionPhysics):
            self._advance_diffusion(dt, ph)
        else:
            self._advance_flow(dt, ph)
            self.counters["neighbour_builds"] = self.neigh.builds

    def stable_dt(self) -> float:
        assert self.problem is not None
        ph = self.problem.physics
        if isinstance(ph, DiffusionPhysics):
            # the assembled matrix's row sums already include the diagonal: 2 sum_j |c_ij|
            return self.problem.time_stepping.stable_dt(ph, self.l0, 0.0, self._lap_rowsum)
        umax = float(np.sqrt((self.p.vel**2).sum(axis=1)).max()) if self.p.n else 0.0
        return self.problem.time_stepping.stable_dt(ph, self.l0, umax, 2.0 * self._lap_rowsum)

    def state(self) -> Particles:
        return self.p

    def rebuild_neighbours(self) -> None:
        """Rebuild the neighbour list now (``mpsbench bench`` times this)."""
        if self.problem is None or isinstance(self.problem.physics, DiffusionPhysics):
            return
        self.neigh.invalidate()
        self.neigh.get(self.p, self.weight, self.re)

    def diagnostics(self) -> dict[str, Any]:
        return {
            "number_density": self.number_density,
            "n0": self.n0,
            "free_surface": self.free_surface,
        }
