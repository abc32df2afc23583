"""The pressure Poisson equation of semi-implicit MPS: sources, free surface, assembly.

docs/method.md section 10.  The Laplacian of the PPE is a registered Laplacian model assembled
as a sparse matrix (:meth:`mpsbench.physics.laplacians.LaplacianModel.matrix`) over the pairs of
the particles that carry a pressure (fluid, wall, inflow; dummy particles are left out of the
operator entirely).  :func:`assemble` restricts it to the unknowns, moves the Dirichlet values
(p = 0 on the free surface, or the given values) to the right-hand side and returns the system
in the sign that makes it symmetric positive (semi)definite for the built-in models:

    M x = y,   M = -L_UU (+ kappa I on closed groups),   y = -(b_U - L_UD p_D)

A connected group of unknowns that reaches no Dirichlet particle (a periodic box, a closed
channel) leaves L_UU singular: its pressure level is undetermined.  Such a group gets the
quasi-compressibility term kappa = 1 / (c0^2 dt^2) (Tanaka & Masunaga 2010 introduce it to
stabilise the PPE; here it is only the reference pressure of the closed groups), which ties
the group's mean pressure to the linear equation of state of its mean density deviation,
mean(p) = rho0 c0^2 mean((n* - n0)/n0) with the density source, and leaves the differences
within the group incompressible up to O((l0 / (c0 dt))^2).  ``compressibility="all"`` applies
the same term to every unknown.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from mpsbench.physics.particles import Kind

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SOURCES = ("density", "divergence", "mixed")
"""PPE sources (docs/method.md section 10): number density (Koshizuka & Oka 1996), velocity
divergence, and the mixed form of Tanaka & Masunaga (2010) with relaxation weight gamma."""

SURFACE_RULES = ("density", "distribution")
"""Free-surface tests: ``density`` n* < beta n0 (Koshizuka & Oka 1996); ``distribution``
additionally asks that the neighbours sit off-centre, |sum_j r_ij W_ij| / sum_j W_ij >
``offset`` l0, for fluid particles (after Khayyer, Gotoh & Shao 2009), so interior particles
whose number density dips for a step keep an unknown pressure."""

COMPRESSIBILITY = ("closed", "all")


def carries_pressure(kind: NDArray[np.integer]) -> BoolArray:
    """Fluid, wall and inflow particles carry a pressure; dummy particles never do."""
    return (kind == Kind.FLUID) | (kind == Kind.WALL) | (kind == Kind.INFLOW)


def source(
    rule: str,
    n: FloatArray,
    n0: float,
    rho0: float,
    dt: float,
    div: FloatArray | None = None,
    relaxation: float = 0.01,
    density_relaxation: float = 1.0,
    dt_ref: float | None = None,
) -> FloatArray:
    """The right-hand side b of lap(p) = b per particle (docs/method.md section 10).

    ``density``: -alpha (rho0/dt_ref^2) (n - n0)/n0 with alpha = ``density_relaxation`` (1 in
    Koshizuka & Oka 1996; below 1 corrects a density error over several steps, as MPS codes
    commonly do); ``divergence``: (rho0/dt) div(u*); ``mixed``: (rho0/dt) div(u*) - gamma
    (rho0/dt_ref^2) (n - n0)/n0 with gamma = ``relaxation`` (Tanaka & Masunaga 2010).

    ``dt_ref``: the step of the 1/dt^2 of the density term when it is longer than dt (None:
    dt, the papers' form).  The semi-implicit scheme passes the previous step in a sliver step
    (``SemiImplicitScheme._density_step``): the pressure that holds a fluid in equilibrium does
    not depend on the step, and with 1/dt^2 a step of 6.2 us between two samples, after steps
    of 0.41 ms, raised the pressure 4,400-fold and blew the Lobovsky dam break up.
    """
    if rule not in SOURCES:
        raise ValueError(f"PPE source = {rule!r} is not allowed: one of {', '.join(SOURCES)}")
    ref = dt if dt_ref is None else max(dt, dt_ref)
    density = -(rho0 / ref**2) * (n - n0) / n0
    if rule == "density":
        return density_relaxation * density
    if div is None:
        raise ValueError(f"the {rule!r} PPE source needs the velocity divergence")
    out = (rho0 / dt) * div
    if rule == "mixed":
        out = out + relaxation * density
    return out


def free_surface(
    rule: str,
    n: FloatArray,
    n0: float,
    beta: float,
    kind: NDArray[np.integer],
    offset: FloatArray | None = None,
    offset_limit: float = 0.0,
) -> BoolArray:
    """Free-surface flags of the particles that carry a pressure (dummy particles: False).

    ``offset``: |sum_j r_ij W_ij| / sum_j W_ij per particle [m], needed by ``distribution``,
    compared with ``offset_limit`` [m] for fluid particles (wall and inflow particles use the
    density test alone: their neighbourhood is one-sided by construction).
    """
    if rule not in SURFACE_RULES:
        raise ValueError(f"free-surface rule = {rule!r} is not allowed: one of "
                         f"{', '.join(SURFACE_RULES)}")
    surface = carries_pressure(kind) & (n < beta * n0)
    if rule == "distribution":
        if offset is None:
            raise ValueError("the 'distribution' free-surface rule needs the neighbour offset")
        fluid = kind == Kind.FLUID
        surface &= ~fluid | (offset > offset_limit)
    return surface


@dataclass
class PPESystem:
    """The system M x = y of :func:`assemble`, with what maps x back to particles.

    ``unknown``: (N,) mask of the particles solved for; ``symmetric``: M is symmetric (the
    built-in Laplacians without gradient correction), so conjugate gradients apply;
    ``closed_groups``: connected groups of unknowns without a Dirichlet neighbour (they got the
    compressibility term); ``kappa``: that term [1/m^2]; ``closed_labels``: per unknown, the
    index of its closed group (-1 for unknowns of anchored groups), None without closed groups.
    """

    matrix: sp.csr_matrix
    rhs: FloatArray
    unknown: BoolArray
    symmetric: bool
    closed_groups: int
    kappa: float
    closed_labels: NDArray[np.intp] | None = None

    def level(self, x0: FloatArray) -> FloatArray:
        """x0 with the pressure level of each closed group corrected (a start for the solver).

        On a closed group G the term kappa I is all that sets the level: with zero column sums
        of -L_GG (symmetric coefficients) 1^T M = kappa 1^T there, so the mean residual of G
        vanishes once mean(x0_G) moves by mean(y - M x0)_G / kappa.  Krylov methods then work
        on the differences alone; a uniformly compressed closed fluid starts (and stays) exactly
        uniform, with no round-off pressure gradient.  Without closed groups: x0 unchanged.
        """
        x = np.array(x0, dtype=float)
        if self.closed_labels is None or self.kappa <= 0 or not len(x):
            return x
        r = self.rhs - self.matrix @ x
        closed = self.closed_labels >= 0
        lab = self.closed_labels[closed]
        count = np.bincount(lab)
        shift = np.bincount(lab, r[closed]) / (count * self.kappa)
        x[closed] += shift[lab]
        return x

    def expand(self, x: FloatArray, dirichlet: FloatArray | None = None) -> FloatArray:
        """Per-particle pressure: x on the unknowns, the Dirichlet values (or 0) elsewhere."""
        p = np.zeros(len(self.unknown)) if dirichlet is None else np.array(dirichlet, float)
        p[self.unknown] = x
        return p


def assemble(
    lap: sp.csr_matrix,
    unknown: BoolArray,
    b: FloatArray,
    *,
    kappa: float = 0.0,
    compressibility: str = "closed",
    dirichlet: FloatArray | None = None,
    symmetric: bool | None = None,
) -> PPESystem:
    """Restrict lap(p) = b to the unknowns (module docstring).

    ``lap``: the (N, N) Laplacian over the particles that carry a pressure (rows and columns
    of the others are empty); ``unknown``: which particles are solved for; the rest are
    Dirichlet particles with p = ``dirichlet`` (default 0).  ``kappa``: the
    quasi-compressibility 1/(c0^2 dt^2), added to the closed groups (``compressibility =
    "closed"``) or to every unknown (``"all"``).  ``symmetric``: whether ``lap`` is symmetric
    (None: tested).
    """
    if compressibility not in COMPRESSIBILITY:
        raise ValueError(f"compressibility = {compressibility!r} is not allowed: one of "
                         f"{', '.join(COMPRESSIBILITY)}")
    lap = sp.csr_matrix(lap)
    idx = np.flatnonzero(unknown)
    fixed = np.flatnonzero(~unknown)
    rows = lap[idx]
    a_uu = rows[:, idx]
    a_ud = rows[:, fixed]
    y = -np.asarray(b, float)[idx]
    if dirichlet is not None:
        y = y + a_ud @ np.asarray(dirichlet, float)[fixed]
    m = sp.csr_matrix(-a_uu)
    if symmetric is None:
        symmetric = abs(m - m.T).max() <= 1e-12 * max(abs(m).max(), 1e-300) if m.nnz else True
    closed = 0
    closed_labels = None
    shift = np.zeros(len(idx))
    if len(idx):
        n_groups, labels = connected_components(m, directed=False)
        anchored = np.zeros(n_groups, dtype=bool)
        anchored[labels[np.asarray(abs(a_ud).sum(axis=1)).ravel() > 0]] = True
        closed = int((~anchored).sum())
        if closed:
            group = np.cumsum(~anchored) - 1  # closed groups numbered 0, 1, ...
            closed_labels = np.where(anchored[labels], -1, group[labels])
        if compressibility == "all":
            shift[:] = kappa
        else:
            shift[~anchored[labels]] = kappa
        if shift.any():
            m = sp.csr_matrix(m + sp.diags(shift))
    return PPESystem(m, y, np.asarray(unknown, bool), bool(symmetric), closed, kappa,
                     closed_labels)


def neighbour_offset(centroid_sum: FloatArray, n: FloatArray) -> FloatArray:
    """|sum_j r_ij W_ij| / sum_j W_ij per particle (0 without neighbours) [m]."""
    mag = np.sqrt(centroid_sum[:, 0] ** 2 + centroid_sum[:, 1] ** 2)
    out = np.zeros_like(mag)
    np.divide(mag, n, out=out, where=n > 0)
    return out
