"""The reference backend: vectorised numpy + scipy, readable first, no loops over particles.

The scheme (set-up, the order of a step, time step, open boundaries) is
:class:`mpsbench.run.scheme.SchemeSolver`; this backend supplies its pieces over a pair list
(:class:`.neighbours.SkinnedPairs`), with the models evaluated by their own vectorised methods
(:mod:`mpsbench.physics.laplacians`, :mod:`mpsbench.physics.gradients`,
:mod:`mpsbench.physics.operators`):

* diffusion: L, the chosen Laplacian, assembled once as a sparse matrix (particles are fixed);
* flow (WC-MPS): predictor (viscosity + gravity), number density at r*, equation of state,
  free-surface detection, corrector with the pressure-gradient model, optional collision,
  optional stabilization, optional particle shifting.

Boundary conventions: WALL particles take part in pressure (EOS) and every operator; DUMMY
particles complete the number density and carry the wall velocity into the viscous term but are
left out of the pressure gradient; INFLOW particles act like wall particles until they cross the
inlet.  Boundary particles advect with their prescribed velocity (moving walls move); only fluid
velocities are ever updated, so ``vel`` of a boundary particle always is its wall velocity.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mpsbench.physics.boundaries import mirror_velocity
from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.neighbours import PairList, build_pairs
from mpsbench.physics.operators import SHIFTING, STABILIZATION, number_density, pair_formula
from mpsbench.physics.particles import Kind
from mpsbench.run.protocol import Capabilities
from mpsbench.run.scheme import SCHEME_BOUNDARIES, SCHEME_FEATURES, EquationOfState, SchemeSolver

from .neighbours import SkinnedPairs

FloatArray = NDArray[np.float64]


class ReferenceSolver(SchemeSolver):
    """Vectorised numpy/scipy WC-MPS and diffusion backend (the reference for all others)."""

    name = "reference"
    version = "1.0"
    capabilities = Capabilities(boundaries=SCHEME_BOUNDARIES, features=SCHEME_FEATURES)

    # ------------------------------------------------------------------ diffusion
    def _setup_diffusion(self, ph: DiffusionPhysics) -> tuple[float, FloatArray]:
        pairs = build_pairs(self.p.pos, self.re_lap, self.box)
        self.counters["neighbour_builds"] += 1
        self.matrix: sp.csr_matrix = self.laplacian.matrix(
            pairs, self.weight, self.re_lap, self.n0_lap, self.lam
        )
        # Gershgorin bound of the spectral radius of L (the row sums include the diagonal)
        rho = float(np.max(np.asarray(abs(self.matrix).sum(axis=1)).ravel()))
        if self.re > self.re_lap:
            pairs = build_pairs(self.p.pos, self.re, self.box)
        return rho, number_density(pairs, self.weight.w(pairs.r, self.re))

    def _diffuse(self, phi: FloatArray, factor: float) -> None:
        phi += factor * (self.matrix @ phi)

    # ------------------------------------------------------------------ flow
    def _setup_flow(self, ph: FlowPhysics) -> None:
        self.neigh = SkinnedPairs(max(self.re, self.re_lap), self.skin_ratio * self.l0, self.box)
        self.du = np.zeros_like(self.p.vel)

    def _update_neighbours(self) -> None:
        if self.neigh.stale(self.p) and hasattr(self, "pairs"):
            # let the old list and its weights go before the new one is built (memory peak);
            # _number_density computes the weights again before the gradient needs them
            del self.pairs
            self._w = np.zeros(0)
        self.pairs: PairList = self.neigh.get(self.p, self.weight, self.re)
        self.counters["neighbour_builds"] = self.neigh.builds

    def _number_density(self) -> FloatArray:
        w = self.weight.w(self.pairs.r, self.re)
        self._w = w
        assert self.neigh.static_n is not None
        return number_density(self.pairs, w) + self.neigh.static_n

    def _laplacian_coefficients(self) -> FloatArray:
        return self.laplacian.coefficients(self.pairs, self.weight, self.re_lap, self.n0_lap,
                                           self.lam)

    def _fluid_row_max(self, c: FloatArray) -> float:
        fluid = self.p.kind == Kind.FLUID
        rows = self.pairs.sum_sym(np.abs(c))
        return float(rows[fluid].max()) if fluid.any() else 0.0

    def _row_sums(self) -> float:
        return self._fluid_row_max(self._laplacian_coefficients())

    def _predict(self, dt: float, ph: FlowPhysics) -> float | None:
        """Viscosity (the boundary velocities mirrored at walls with ``mirror``) and gravity on
        fluid, then every particle moves by dt u*; returns the Laplacian's max fluid row sum."""
        p = self.p
        fluid = p.kind == Kind.FLUID
        rows = None
        if ph.nu > 0:
            c = self._laplacian_coefficients()
            rows = self._fluid_row_max(c)
            mirror = ph.wall_velocity == "mirror"
            u = mirror_velocity(p, self.weight, self.re, self.box) if mirror else p.vel
            lap = self.laplacian.apply(
                self.pairs, u, self.weight, self.re_lap, self.n0_lap, self.lam, coef=c
            )
            acc = ph.nu * lap
        else:
            acc = np.zeros_like(p.vel)
        acc += np.asarray(ph.gravity)
        p.vel[fluid] += dt * acc[fluid]
        disp = dt * p.vel
        p.pos += disp
        self.neigh.note_motion(disp)
        return rows

    def _density_pressure(self, eos: EquationOfState) -> None:
        n = self._number_density()
        self.number_density = n
        self.p.pressure[:], self.free_surface = eos.pressure(n, self.p.kind)

    def _pressure_gradient(self, pres: FloatArray) -> FloatArray:
        # Dummy particles only complete the number density: a zero weight drops their pairs
        # (cheaper than building a sub-list every step).
        w = np.where(self.neigh.no_dummy, self._w, 0.0)
        return self.gradient(self.pairs, pres, w, self.n0)

    def _correct(self, factor: float, collision: tuple[float, float] | None) -> None:
        """du = factor grad(p) on fluid; with ``collision`` its increments at u + du; u += du."""
        grad = self._pressure_gradient(self.p.pressure)
        fluid = self.p.kind == Kind.FLUID
        self.du = np.zeros_like(self.p.vel)
        self.du[fluid] = factor * grad[fluid]
        if collision is not None:
            self._collision(*collision)
        self.p.vel += self.du

    def _collision(self, distance: float, restitution: float) -> None:
        """Lee et al. (2011): remove the approaching normal velocity of too-close pairs."""
        pairs, kind = self.pairs, self.p.kind
        vel = self.p.vel + self.du
        fi = kind[pairs.i] == Kind.FLUID
        fj = kind[pairs.j] == Kind.FLUID
        close = (pairs.r < distance) & (fi | fj)
        du_rel = vel[pairs.i] - vel[pairs.j]
        approach = (du_rel * pairs.dx).sum(axis=1)
        act = close & (approach > 0)
        if not act.any():
            return
        out = np.zeros_like(vel)
        # equal masses between fluid particles; a boundary particle is infinitely heavy
        share_i = np.where(fj, 0.5, 1.0)[act]
        share_j = np.where(fi, 0.5, 1.0)[act]
        imp = ((1.0 + restitution) * approach[act] / pairs.r[act] ** 2)[:, None] * pairs.dx[act]
        ii, jj = pairs.i[act], pairs.j[act]
        for ax in range(2):
            out[:, ax] -= np.bincount(ii, share_i * imp[:, ax], self.p.n)
            out[:, ax] += np.bincount(jj, share_j * imp[:, ax], self.p.n)
        out[kind != Kind.FLUID] = 0.0
        self.du += out

    def _stabilization(self, factor: float, with_walls: bool) -> FloatArray:
        """du_i = factor sum_j W'_ij (u_j - u_i) for inner fluid particles (the pair weight of
        :class:`mpsbench.physics.operators.Stabilization`), at the r* geometry of the pairs."""
        pairs, kind = self.pairs, self.p.kind
        term = pair_formula(STABILIZATION.pair, self.weight, pairs.r, self.re)
        if not with_walls:
            use = (kind[pairs.i] == Kind.FLUID) & (kind[pairs.j] == Kind.FLUID)
            term = np.where(use, term, 0.0)
        du = pairs.diff(self.p.vel)
        out = np.empty_like(self.p.vel)
        for ax in range(2):
            out[:, ax] = pairs.sum_antisym(term * du[:, ax])
        out *= factor
        inner = (kind == Kind.FLUID) & ~self.free_surface
        out[~inner] = 0.0
        return out

    def _move(self, dt: float, stabilization: tuple[float, bool] | None) -> None:
        stab = None if stabilization is None else self._stabilization(*stabilization)
        disp = dt * self.du
        self.p.pos += disp
        self.neigh.note_motion(disp)
        if stab is not None:
            self.p.vel += stab

    def _shift(self, factor: float, cap: float) -> None:
        """Particle shifting (:class:`mpsbench.physics.operators.Shifting`) at the moved
        positions: both sums from the same state, then u += (dr . grad) u and r += dr on inner
        fluid particles."""
        self._update_neighbours()
        pairs, p = self.pairs, self.p
        c = pair_formula(SHIFTING.pair, self.weight, pairs.r, self.re)
        g = pair_formula(SHIFTING.velocity_pair, self.weight, pairs.r, self.re)
        dr = np.empty_like(p.pos)
        for ax in range(2):
            dr[:, ax] = factor * pairs.sum_antisym(c * pairs.dx[:, ax])
        norm = np.sqrt(dr[:, 0] * dr[:, 0] + dr[:, 1] * dr[:, 1])
        over = norm > cap
        dr[over] *= (cap / norm[over])[:, None]
        dr[(p.kind != Kind.FLUID) | self.free_surface] = 0.0
        du = pairs.diff(p.vel)
        gf = SHIFTING.gradient_factor(self.n0)
        grad = [[pairs.sum_sym(du[:, a] * pairs.dx[:, b] * g) for b in range(2)]
                for a in range(2)]
        for a in range(2):
            p.vel[:, a] += gf * (grad[a][0] * dr[:, 0] + grad[a][1] * dr[:, 1])
        p.pos += dr
        self.neigh.note_motion(dr)

    def _particles_changed(self, keep: NDArray[np.bool_]) -> None:
        self.neigh.invalidate()

    def rebuild_neighbours(self) -> None:
        """Rebuild the neighbour list now (``mpsbench bench`` times this)."""
        if self.problem is None or isinstance(self.problem.physics, DiffusionPhysics):
            return
        self.neigh.invalidate()
        self.neigh.get(self.p, self.weight, self.re)
