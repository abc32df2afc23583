"""The WC-MPS and diffusion time steps, written once; a backend supplies its kernels and layout.

:class:`SchemeSolver` is a :class:`~mpsbench.run.protocol.SolverBase` that owns everything the
backends share (docs/solver-contract.md sections 2-10, docs/method.md sections 1-5):

* set-up: the models from the registries (weight, Laplacian, pressure gradient), the radii
  r_e and r_e,lap, a copy of the particles with the inflow reservoir rows appended, the wall
  motions, n0, n0_lap and lambda (:func:`reference_constants`), the equation of state;
* the step: diffusion (phi += dt kappa L phi) or WC-MPS in the order of the contract's table
  (predictor, number density and pressure at r*, pressure gradient, collision, stabilization,
  corrector, wrap, open boundaries), with the periodic wrap and the open boundaries
  (:func:`mpsbench.physics.boundaries.update_open_boundaries`) done here;
* ``stable_dt()`` (and which limit set it: ``diagnostics()["dt_limit"]``), ``state()``,
  ``diagnostics()``, ``particle_count()``.

A backend subclasses it and implements the hooks, each one piece of the step on its own data
layout (the reference: numpy over a pair list; numba: compiled kernels over cell lists):

=========================  =====================================================================
``_setup_diffusion(ph)``   assemble the Laplacian at r_e,lap once; return (the Gershgorin bound
                           of its spectral radius, diagonal included; n_i at r_e)
``_diffuse(phi, factor)``  phi += factor L phi in place
``_setup_flow(ph)``        build the neighbour data (the particles are in ``self.p``)
``_update_neighbours()``   make the neighbour data valid for the current positions
``_number_density()``      n_i at r_e (set-up only; the step uses ``_density_pressure``)
``_row_sums()``            max over fluid rows of sum_j |c_ij| of the Laplacian (set-up: the
                           first ``stable_dt``; later steps get it from ``_predict``)
``_predict(dt, ph)``       steps 1-2: u* = u + dt (nu lap(u) + g) on fluid, lap(u) with the
                           boundary velocities mirrored at walls when ``ph.wall_velocity`` is
                           ``mirror``; every particle moves by dt u*.  Return the max over
                           fluid rows of sum_j |c_ij| of that Laplacian (None when nu = 0)
``_density_pressure(eos)`` step 3: n at r*, ``eos`` -> pressure, ``self.number_density``,
                           ``self.free_surface`` (and the inner flags of the stabilization)
``_correct(f, collision)`` steps 4-5: du = f grad(p) on fluid (f = -dt / rho0), 0 elsewhere;
                           with ``collision`` = (distance, restitution): du += the collision
                           increments at u + du; then u += du
``_move(dt, stab)``        step 6: with ``stab`` = (prefactor, with_walls) the stabilization
                           increments at the r* geometry; r += dt du; u += the increments
``_shift(factor, cap)``    step 6b (``FlowPhysics.shifting``): make the neighbour data valid
                           for the moved positions; for inner fluid particles dr = ``factor``
                           sum_j pair_ij r_ij capped at ``cap``, u += (dr . grad) u, r += dr
                           (:class:`~mpsbench.physics.operators.Shifting`)
``_particles_changed(k)``  the particle set changed (``keep`` of the open boundaries)
``rebuild_neighbours()``   rebuild the neighbour data now (timed by ``mpsbench bench``)
=========================  =====================================================================

Steps 1-2, 4-5 and 6 are one hook each so that a backend can fuse a neighbour sum with the
per-particle updates that follow it (the numba backend's kernels do); the order inside a hook is
the one given here, which the reference backend follows line by line.

``_max_speed()`` (max |u| over all particles) and ``health()`` (the runner's per-step check) have
numpy defaults over ``self.p`` that a backend may replace with compiled or on-device ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mpsbench.physics.boundaries import InflowBoundary, carry, update_open_boundaries
from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.gradients import GradientModel, get_gradient
from mpsbench.physics.laplacians import LaplacianModel, get_laplacian
from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.operators import (
    SHIFTING,
    STABILIZATION,
    lattice_constants,
    number_density,
)
from mpsbench.physics.particles import Box, Kind, Particles
from mpsbench.physics.powers import power
from mpsbench.physics.weights import WeightFunction, get_weight
from mpsbench.run.protocol import Capabilities, Health, Problem, SolverBase, health_of

FloatArray = NDArray[np.float64]

#: the boundaries every backend built on this skeleton supports: the protocol's defaults and
#: sliding walls (``WallMotion(displace=False)``, held in place by :meth:`_hold_anchored`)
SCHEME_BOUNDARIES = Capabilities().boundaries | {"sliding-walls"}
#: and the features: the protocol's defaults and particle shifting (the ``_shift`` hook)
SCHEME_FEATURES = Capabilities().features | {"shifting"}


@dataclass(frozen=True)
class EquationOfState:
    """p(n) and the free-surface rule of a WC-MPS run (docs/method.md section 4).

    Tait: p = prefactor ((n/n0)^gamma - 1) with prefactor rho0 c0^2 / gamma; linear: p =
    prefactor (n/n0 - 1) with prefactor rho0 c0^2; negative p clipped to 0 with ``clip``; fluid,
    wall and inflow particles with n < beta n0 are on the free surface (p = 0), dummy particles
    always have p = 0.
    """

    tait: bool
    prefactor: float
    gamma: float
    clip: bool
    beta: float
    n0: float

    @classmethod
    def of(cls, ph: FlowPhysics, n0: float) -> EquationOfState:
        tait = ph.eos == "tait"
        pref = ph.rho0 * ph.c0**2 / ph.gamma if tait else ph.rho0 * ph.c0**2
        return cls(tait, pref, ph.gamma, ph.clip_negative_pressure, ph.surface_beta, n0)

    def pressure(self, n: FloatArray, kind: NDArray[Any]) -> tuple[FloatArray, NDArray[np.bool_]]:
        """(pressure, free-surface flags) of number densities ``n`` (numpy)."""
        ratio = n / self.n0
        if self.tait:
            # products for a whole gamma (powers.power): numpy's power rounds per processor
            pres = self.prefactor * (power(ratio, self.gamma) - 1.0)
        else:
            pres = self.prefactor * (ratio - 1.0)
        if self.clip:
            np.maximum(pres, 0.0, out=pres)
        carries = (kind == Kind.FLUID) | (kind == Kind.WALL) | (kind == Kind.INFLOW)
        surface = carries & (n < self.beta * self.n0)
        pres[surface | ~carries] = 0.0
        return pres, surface


def reference_constants(
    p: Particles, weight: WeightFunction, re: float, l0: float, box: Box, n0_from: str
) -> tuple[float, float]:
    """n0 and lambda at radius ``re`` (docs/solver-contract.md section 3).

    ``lattice``: the ideal square lattice of spacing l0.  ``initial``: at the fluid particle
    with the largest number density of the initial arrangement (the first in index order on a
    tie; any particle when there is no fluid), neighbours of every kind.  Computed here, once,
    for every backend, so they all start from the same n0 to the last bit.
    """
    if n0_from == "lattice":
        return lattice_constants(weight, re / l0, l0)
    pairs = build_pairs(p.pos, re, box)
    w = weight.w(pairs.r, re)
    n = number_density(pairs, w)
    cand = p.kind == Kind.FLUID
    if not cand.any():
        cand = np.ones(p.n, dtype=bool)
    idx = int(np.nonzero(cand)[0][np.argmax(n[cand])])
    mask_i = pairs.i == idx
    mask_j = pairs.j == idx
    r = np.concatenate([pairs.r[mask_i], pairs.r[mask_j]])
    ww = np.concatenate([w[mask_i], w[mask_j]])
    n0 = float(ww.sum())
    if n0 <= 0:
        raise ValueError(f"no particle has neighbours within r_e = {re}")
    return n0, float((r**2 * ww).sum() / n0)


class SchemeSolver(SolverBase):
    """The WC-MPS / diffusion scheme; subclasses supply the kernels (module docstring)."""

    skin_ratio = 0.3  # neighbour-list skin in units of l0

    # ------------------------------------------------------------------ set-up
    def _setup(self, problem: Problem) -> None:
        m = problem.models
        self.l0 = problem.l0
        self.box = problem.box
        self.weight: WeightFunction = get_weight(m.weight)
        self.laplacian: LaplacianModel = get_laplacian(
            m.laplacian, gradient_correction=m.gradient_correction
        )
        self.gradient: GradientModel = get_gradient(m.gradient)
        self.re = m.re_ratio * self.l0
        self.re_lap = m.re_lap_ratio * self.l0
        self.p = problem.particles.copy()
        self.inflow: InflowBoundary | None = None
        if problem.inflow is not None:
            self.inflow = InflowBoundary(problem.inflow, self.l0)
            self.p = Particles.concat([self.p, self.inflow.initial()])
        self.anchored = False
        for motion in problem.wall_motions:
            tagged = self.p.fields.get("wall_tag", np.full(self.p.n, -1.0)) == motion.tag
            tagged &= self.p.kind != Kind.FLUID
            self.p.vel[tagged] = motion.velocity
            if not motion.displace:
                self._anchor(tagged)
        self.n0, _ = reference_constants(self.p, self.weight, self.re, self.l0, self.box,
                                         m.n0_from)
        self.n0_lap, self.lam = reference_constants(self.p, self.weight, self.re_lap, self.l0,
                                                    self.box, m.n0_from)
        self.number_density = np.zeros(self.p.n)
        self.free_surface = np.zeros(self.p.n, dtype=bool)
        self.rho_lap = 0.0  # Gershgorin bound of the Laplacian's spectral radius [1/m^2]
        self.dt_limit = ""
        self.stabilization_alpha = 0.0  # the last step's (FlowPhysics.stabilization_alpha)
        ph = problem.physics
        if isinstance(ph, DiffusionPhysics):
            if ph.field_name not in self.p.fields:
                raise ValueError(
                    f"diffusion needs the scalar field {ph.field_name!r} in "
                    "Problem.particles.fields"
                )
            self.rho_lap, self.number_density = self._setup_diffusion(ph)
            return
        self.eos = EquationOfState.of(ph, self.n0)
        self._setup_flow(ph)
        self._update_neighbours()
        self.number_density = self._number_density()
        # the row sums for the first stable_dt()
        self.rho_lap = 2.0 * self._row_sums()

    # ------------------------------------------------------------------ the step
    def _advance(self, dt: float) -> None:
        ph = self.problem.physics  # type: ignore[union-attr]
        if isinstance(ph, DiffusionPhysics):
            self._diffuse(self.p.fields[ph.field_name], dt * ph.kappa)
            return
        # 1-2: predictor (viscosity with the boundary velocities of step 1, gravity), move
        self._update_neighbours()
        rows = self._predict(dt, ph)
        if self.anchored:
            self._hold_anchored()
        if rows is not None:  # (without viscosity the row sums are not needed either)
            self.rho_lap = 2.0 * rows
        self._wrap()
        # 3: number density at r*, pressure (here the equation of state), free surface
        self._pressure_step(dt, ph)
        # 4-5: corrector without dummy particles, collision on u* + u', u += du
        collision = (ph.collision_distance * self.l0, ph.restitution) if ph.collision else None
        self._correct(-(dt / ph.rho0), collision)
        # 6: stabilization at the r* geometry (velocities only), move
        stab = None
        if ph.stabilization:
            cfl = self.problem.time_stepping.cfl  # type: ignore[union-attr]
            self.stabilization_alpha = ph.stabilization_alpha(dt, self.l0, cfl)
            stab = (STABILIZATION.prefactor(self.stabilization_alpha, self.l0, self.n0),
                    ph.stabilization_walls)
        self._move(dt, stab)
        # 6b: particle shifting at the moved positions
        if ph.shifting:
            factor = SHIFTING.prefactor(ph.shifting_coefficient, self.re, self._max_speed(), dt,
                                        self.n0)
            self._shift(factor, SHIFTING.CAP * self.l0)
        # 7: wrap, open boundaries
        self._wrap()
        self._open_boundaries(dt)

    def _pressure_step(self, dt: float, ph: FlowPhysics) -> None:
        """Step 3 at r*: the number density, the pressure and the free-surface flags.  WC-MPS
        takes the pressure from the equation of state; the semi-implicit scheme
        (:mod:`mpsbench.run.implicit_scheme`) solves a pressure Poisson equation instead."""
        self._update_neighbours()
        self._density_pressure(self.eos)

    def _anchor(self, where: NDArray[np.bool_]) -> None:
        """Sliding walls: remember where these particles are.  In fields, so that a backend
        that reorders its particles, and the open boundaries, carry the marks along (a new
        inflow row gets 0: not anchored)."""
        f = self.p.fields
        if "anchored" not in f:
            f["anchored"] = np.zeros(self.p.n)
            f["anchor_x"] = np.zeros(self.p.n)
            f["anchor_y"] = np.zeros(self.p.n)
        f["anchored"][where] = 1.0
        f["anchor_x"][where] = self.p.pos[where, 0]
        f["anchor_y"][where] = self.p.pos[where, 1]
        self.anchored = True

    def _hold_anchored(self) -> None:
        """Put sliding-wall particles back where they were: the predictor moved every particle
        by dt u, and these carry a velocity without a displacement."""
        f = self.p.fields
        m = f["anchored"] > 0.0
        self.p.pos[m, 0] = f["anchor_x"][m]
        self.p.pos[m, 1] = f["anchor_y"][m]

    def _wrap(self) -> None:
        if self.box.any_periodic:
            self.box.wrap(self.p.pos)

    def _open_boundaries(self, dt: float) -> None:
        assert self.problem is not None
        if self.inflow is None and not self.problem.outflows:
            return
        self.p, keep = update_open_boundaries(self.p, self.inflow, self.problem.outflows, dt)
        if keep is not None:
            self.number_density = carry(self.number_density, keep)
            self.free_surface = carry(self.free_surface, keep)
            self._particles_changed(keep)

    # ------------------------------------------------------------------ protocol
    def stable_dt(self) -> float:
        assert self.problem is not None
        ph = self.problem.physics
        umax = 0.0
        if isinstance(ph, FlowPhysics) and self.p.n:
            umax = self._max_speed()
        dt, self.dt_limit = self.problem.time_stepping.limit(ph, self.l0, umax, self.rho_lap)
        return dt

    def state(self) -> Particles:
        return self.p

    def particle_count(self) -> int:
        return self.p.n

    def diagnostics(self) -> dict[str, Any]:
        return {
            "number_density": self.number_density,
            "n0": self.n0,
            "free_surface": self.free_surface,
            "dt_limit": self.dt_limit,
            "stabilization_alpha": self.stabilization_alpha,
        }

    def health(self, margin: float) -> Health:
        """The runner's per-step check, from the particle arrays themselves (numpy)."""
        problem = self._require_setup("health()")
        return health_of(self.p, self.box, margin, getattr(problem.physics, "field_name", None))

    def _max_speed(self) -> float:
        """max_i |u_i| over every particle (moving walls and inflow included)."""
        return float(np.sqrt((self.p.vel**2).sum(axis=1)).max())

    # ------------------------------------------------------------------ the backend's hooks
    def _setup_diffusion(self, ph: DiffusionPhysics) -> tuple[float, FloatArray]:
        raise NotImplementedError

    def _diffuse(self, phi: FloatArray, factor: float) -> None:
        raise NotImplementedError

    def _setup_flow(self, ph: FlowPhysics) -> None:
        raise NotImplementedError

    def _update_neighbours(self) -> None:
        raise NotImplementedError

    def _number_density(self) -> FloatArray:
        raise NotImplementedError

    def _row_sums(self) -> float:
        raise NotImplementedError

    def _predict(self, dt: float, ph: FlowPhysics) -> float | None:
        raise NotImplementedError

    def _density_pressure(self, eos: EquationOfState) -> None:
        raise NotImplementedError

    def _correct(self, factor: float, collision: tuple[float, float] | None) -> None:
        raise NotImplementedError

    def _move(self, dt: float, stabilization: tuple[float, bool] | None) -> None:
        raise NotImplementedError

    def _shift(self, factor: float, cap: float) -> None:
        raise NotImplementedError

    def _particles_changed(self, keep: NDArray[np.bool_]) -> None:
        raise NotImplementedError

    def rebuild_neighbours(self) -> None:
        """Rebuild the neighbour data now (``mpsbench bench`` times this)."""
        raise NotImplementedError
