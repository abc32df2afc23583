"""Nine bugs injected into the reference backend, one per subclass (issue 16).

Each mutant is the reference backend with one piece of its step changed the way a plugin
author was seen (or could be expected) to get it wrong.  ``tests/test_mutations.py`` holds
each against the conformance kit, the smoke tier and ``mpsbench check --against reference``;
docs/solver-contract.md section 11 lists which check catches which.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from mpsbench.solvers.reference import ReferenceSolver
from numpy.typing import NDArray

from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.gradients import GradientModel
from mpsbench.physics.laplacians import LaplacianModel
from mpsbench.physics.neighbours import PairList
from mpsbench.physics.operators import neighbour_min
from mpsbench.physics.particles import Box, Kind

FloatArray = NDArray[np.float64]


class _ScaledLaplacian(LaplacianModel):
    """Another model's coefficients times ``factor``."""

    def __init__(self, inner: LaplacianModel, factor: float) -> None:
        self.inner, self.factor = inner, factor
        self.name, self.gradient_correction = inner.name, inner.gradient_correction

    def coefficients(self, *args: Any, **kw: Any) -> FloatArray:
        return self.factor * self.inner.coefficients(*args, **kw)

    def apply(self, *args: Any, coef: FloatArray | None = None, **kw: Any) -> FloatArray:
        if coef is None:
            return self.factor * self.inner.apply(*args, **kw)
        # coef by keyword through the dict: mypy cannot tell that *args does not fill it too
        return self.inner.apply(*args, **{**kw, "coef": coef})

    def matrix(self, *args: Any, **kw: Any) -> sp.csr_matrix:
        return sp.csr_matrix(self.factor * self.inner.matrix(*args, **kw))


class LaplacianTimes11(ReferenceSolver):
    """(1) Laplacian coefficients x 1.1."""

    name = "mutant-laplacian-x1.1"
    laplacian: LaplacianModel  # the base's, set up before _setup_diffusion/_setup_flow

    def _setup_diffusion(self, ph: DiffusionPhysics) -> tuple[float, FloatArray]:
        self.laplacian = _ScaledLaplacian(self.laplacian, 1.1)
        return super()._setup_diffusion(ph)

    def _setup_flow(self, ph: FlowPhysics) -> None:
        self.laplacian = _ScaledLaplacian(self.laplacian, 1.1)
        super()._setup_flow(ph)


def _scatter_j_plus(model: GradientModel, pairs: PairList, p: FloatArray, w: FloatArray,
                    n0: float) -> FloatArray:
    """GradientModel.__call__ with the j-side term added with + instead of -."""
    pmin = neighbour_min(pairs, p, w) if model.uses_pmin else p
    c = np.zeros_like(w)
    nz = w != 0
    c[nz] = model.radial(pairs.r[nz], w[nz])
    pi, pj, mi, mj = p[pairs.i], p[pairs.j], pmin[pairs.i], pmin[pairs.j]
    ci = model.pair(pi, pj, mi, mj) * c
    cj = model.pair(pj, pi, mj, mi) * c
    out = np.empty((pairs.n, 2))
    for ax in range(2):
        d = pairs.dx[:, ax]
        out[:, ax] = np.bincount(pairs.i, ci * d, pairs.n) + np.bincount(
            pairs.j, cj * d, pairs.n)
    return model.prefactor(n0) * out


class _WrongScatter(ReferenceSolver):
    targets: tuple[str, ...] = ()

    def _pressure_gradient(self, pres: FloatArray) -> FloatArray:
        if self.gradient.name not in self.targets:
            return super()._pressure_gradient(pres)
        w = np.where(self.neigh.no_dummy, self._w, 0.0)
        return _scatter_j_plus(self.gradient, self.pairs, pres, w, self.n0)


class Pgm1JPlus(_WrongScatter):
    """(2) PGM1's j-side term added with + instead of -."""

    name = "mutant-pgm1-j-plus"
    targets = ("pgm1",)


class Pgm23Symmetric(_WrongScatter):
    """(3) PGM2 and PGM3 scattered symmetrically instead of antisymmetrically."""

    name = "mutant-pgm23-symmetric"
    targets = ("pgm2", "pgm3")


class WallsOutOfDensity(ReferenceSolver):
    """(4) Wall particles left out of the number density."""

    name = "mutant-walls-out-of-n"

    def _number_density(self) -> FloatArray:
        w = self.weight.w(self.pairs.r, self.re)
        self._w = w  # the pressure gradient keeps its weights
        kind = self.p.kind
        wall = (kind[self.pairs.i] == Kind.WALL) | (kind[self.pairs.j] == Kind.WALL)
        assert self.neigh.static_n is not None
        return self.pairs.sum_sym(np.where(wall, 0.0, w)) + self.neigh.static_n


class StableDtTimes2(ReferenceSolver):
    """(5) stable_dt() x 2, always."""

    name = "mutant-dt-x2"

    def stable_dt(self) -> float:
        return 2.0 * super().stable_dt()


class StableDtTimes2Unfixed(ReferenceSolver):
    """(6) stable_dt() x 2 only when the problem does not fix dt."""

    name = "mutant-dt-x2-unfixed"

    def stable_dt(self) -> float:
        dt = super().stable_dt()
        assert self.problem is not None
        return dt if self.problem.time_stepping.dt is not None else 2.0 * dt


class GravityTwice(ReferenceSolver):
    """(7) Gravity applied twice in the predictor."""

    name = "mutant-gravity-twice"

    def _predict(self, dt: float, ph: FlowPhysics) -> float | None:
        fluid = self.p.kind == Kind.FLUID
        self.p.vel[fluid] += dt * np.asarray(ph.gravity)
        return super()._predict(dt, ph)


class StabilizedSurface(ReferenceSolver):
    """(8) The stabilization applied to free-surface fluid particles too."""

    name = "mutant-stabilized-surface"
    free_surface: NDArray[np.bool_]  # the base's, swapped out for the call

    def _stabilization(self, factor: float, with_walls: bool) -> FloatArray:
        saved = self.free_surface
        self.free_surface = np.zeros_like(saved)
        try:
            return super()._stabilization(factor, with_walls)
        finally:
            self.free_surface = saved


class ShortPeriod(ReferenceSolver):
    """(9) The periodic wrap with a period one l0 short."""

    name = "mutant-short-period"

    def _wrap(self) -> None:
        if self.box.any_periodic:
            hi = tuple(h - self.l0 if per else h
                       for h, per in zip(self.box.hi, self.box.periodic, strict=True))
            Box(self.box.lo, (hi[0], hi[1]), self.box.periodic).wrap(self.p.pos)


MUTANTS: tuple[type[ReferenceSolver], ...] = (
    LaplacianTimes11, Pgm1JPlus, Pgm23Symmetric, WallsOutOfDensity, StableDtTimes2,
    StableDtTimes2Unfixed, GravityTwice, StabilizedSurface, ShortPeriod,
)
