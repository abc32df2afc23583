"""MPS operators over a pair list: number density, n0 and lambda, the original gradient and
divergence, p_min, and the evaluation of a model's pair formula; the stabilization.

Every operator takes precomputed per-pair quantities so one neighbour list (built at the
largest radius) serves all radii; a weight evaluated at a smaller r_e is simply zero beyond it.
Formulas and their provenance: docs/method.md sections 1-5 (D_s = ``dim`` = 2).  The models with
registries live beside this module: :mod:`.weights`, :mod:`.laplacians`, :mod:`.gradients`.
"""

from __future__ import annotations

import dis
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mpsbench.physics.neighbours import PairList, build_pairs
from mpsbench.physics.particles import Box
from mpsbench.physics.weights import WeightFunction, get_weight, within_support

FloatArray = NDArray[np.float64]

DIM = 2
"""D_s: the dimension (the project is 2-D; the pair formulas are written in their 2-D form)."""


# --------------------------------------------------------------------------- number density


def number_density(pairs: PairList, w: FloatArray) -> FloatArray:
    """n_i = sum_j W_ij (``w`` is the per-pair weight)."""
    return pairs.sum_sym(w)


def lattice_constants(
    weight: str | WeightFunction, re_ratio: float, l0: float = 1.0
) -> tuple[float, float]:
    """n0 and lambda of an interior particle of a square lattice of spacing ``l0``.

    Sums over the actual lattice points within r_e (no continuum approximation).
    """
    wf = get_weight(weight)
    re = re_ratio * l0
    m = int(np.ceil(re_ratio)) + 1
    ix, iy = np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1), indexing="ij")
    r = l0 * np.hypot(ix.ravel(), iy.ravel())
    r = r[(r > 0) & within_support(r, re)]
    w = wf.w(r, re)
    n0 = float(w.sum())
    return n0, float((r**2 * w).sum() / n0)


def particle_constants(
    pos: FloatArray, index: int, weight: str | WeightFunction, re: float, box: Box | None = None
) -> tuple[float, float]:
    """n0 and lambda at particle ``index`` of an arrangement (an interior one with full support)."""
    wf = get_weight(weight)
    d = np.asarray(pos, float) - pos[index]
    if box is not None:
        box.minimum_image(d)
    r = np.hypot(d[:, 0], d[:, 1])
    r = r[(r > 0) & within_support(r, re)]
    w = wf.w(r, re)
    n0 = float(w.sum())
    if n0 <= 0:
        raise ValueError(f"particle {index} has no neighbours within r_e = {re}")
    return n0, float((r**2 * w).sum() / n0)


def interior_index(
    pos: FloatArray, candidates: NDArray[np.bool_], re: float, box: Box | None
) -> int:
    """A candidate particle with full support: the one deepest inside the particle cloud.

    Depth is measured along non-periodic axes from the cloud's bounding box; along periodic
    axes every particle has full support.
    """
    pos = np.asarray(pos, float)
    depth = np.full(len(pos), np.inf)
    for ax in range(2):
        if box is not None and box.periodic[ax]:
            continue
        lo, hi = pos[:, ax].min(), pos[:, ax].max()
        depth = np.minimum(depth, np.minimum(pos[:, ax] - lo, hi - pos[:, ax]))
    idx = np.nonzero(candidates)[0]
    if len(idx) == 0:
        raise ValueError("interior_index: no candidate particles")
    best = int(idx[np.argmax(depth[idx])])
    if np.isfinite(depth[best]) and depth[best] < re:
        raise ValueError(
            f"no particle has full support: deepest candidate is {depth[best]:.3g} from the "
            f"edge of the particle cloud, r_e = {re:.3g}"
        )
    return best


# --------------------------------------------------------------------------- gradients


def gradient(
    pairs: PairList, phi: FloatArray, w: FloatArray, n0: float, dim: int = 2
) -> FloatArray:
    """Original MPS gradient (Eq. 5): (D/n0) sum_j phi_ij r_ij W_ij / r_ij^2, shape (n, 2)."""
    coef = pairs.diff(phi) * _w_over_r2(w, pairs.r)
    return (dim / n0) * pairs.sum_vec_sym(coef[:, None] * pairs.dx)


def divergence(
    pairs: PairList, u: FloatArray, w: FloatArray, n0: float, dim: int = 2
) -> FloatArray:
    """MPS divergence: (D/n0) sum_j (u_j - u_i) . r_ij W_ij / r_ij^2."""
    du = pairs.diff(u)
    proj = (du * pairs.dx).sum(axis=1) * _w_over_r2(w, pairs.r)
    return (dim / n0) * pairs.sum_sym(proj)


def neighbour_min(pairs: PairList, p: FloatArray, w: FloatArray) -> FloatArray:
    """p_min,i = min(p_i, min over neighbours with W_ij > 0 of p_j)."""
    pmin = p.copy()
    act = w > 0
    np.minimum.at(pmin, pairs.i[act], p[pairs.j[act]])
    np.minimum.at(pmin, pairs.j[act], p[pairs.i[act]])
    return pmin


def mps_radial(r: Any, w: Any) -> Any:
    """W_ij / r_ij^2: the radial weight of the original gradient (Eq. 5), the divergence and the
    pressure gradients (a formula in plain arithmetic, compiled by the numba backend too)."""
    return w / (r * r)


def _w_over_r2(w: FloatArray, r: FloatArray) -> FloatArray:
    """:func:`mps_radial` per pair, 0 where W = 0 (no division for pairs beyond the support)."""
    out = np.zeros_like(w)
    nz = w != 0
    out[nz] = mps_radial(r[nz], w[nz])
    return out


# --------------------------------------------------------------------------- model formulas
#
# A model's formulas are static methods in plain arithmetic, evaluated here on arrays and
# compiled by the numba backend; these helpers evaluate them on a pair list.


def reads(fn: Callable[..., Any]) -> tuple[bool, ...]:
    """Which positional parameters of ``fn`` its code reads (True when unsure).

    The vectorised evaluation skips W, W' or W'' when a pair formula does not use them (each
    is a masked evaluation over every pair); numba drops unused values by itself.
    """
    code = getattr(fn, "__code__", None)
    if code is None:
        return (True,) * 8
    names = code.co_varnames[: code.co_argcount]
    used: set[str] = set(code.co_cellvars)  # captured by an inner function: assume read
    for ins in dis.get_instructions(code):
        if ins.opname.startswith("LOAD_FAST") or ins.opname.startswith("DELETE_FAST"):
            arg = ins.argval
            used.update(arg if isinstance(arg, tuple) else (arg,))
    return tuple(name in used for name in names)


def pair_formula(
    fn: Callable[..., Any], weight: WeightFunction, r: FloatArray, re: float,
    *extra: FloatArray,
) -> FloatArray:
    """``fn(r, W, W', W'', *extra)`` per pair inside the closed support of ``re``, 0 beyond it.

    W, W', W'' are evaluated at min(r, re) (the closed support, :mod:`.weights`); ``fn`` gets the
    distance itself, and each ``extra`` array gathered at the pairs inside.
    """
    inside = np.flatnonzero(within_support(r, re))
    out = np.zeros(len(r))
    if len(inside) == 0:
        return out
    ri = r[inside]
    rc = np.minimum(ri, re)
    use = reads(fn) + (True,) * 8
    values = [
        formula(rc, re) if use[k + 1] else 0.0
        for k, formula in enumerate((weight.w_inside, weight.dw_inside, weight.d2w_inside))
    ]
    out[inside] = fn(ri, *values, *(e[inside] for e in extra))
    return out


def gradient_matrix(
    pairs: PairList, w: FloatArray, n0: float, axis: int, dim: int = 2
) -> sp.csr_matrix:
    """Component ``axis`` of the original gradient as a sparse matrix."""
    n = pairs.n
    c = (dim / n0) * _w_over_r2(w, pairs.r) * pairs.dx[:, axis]
    # Both ends get the same term c (phi_j - phi_i), because phi_ji r_ji = phi_ij r_ij:
    # row i has +c on column j, row j has -c on column i (diagonals: minus the row sums).
    rows = np.concatenate([pairs.i, pairs.j])
    cols = np.concatenate([pairs.j, pairs.i])
    off = sp.coo_matrix((np.concatenate([c, -c]), (rows, cols)), shape=(n, n)).tocsr()
    return sp.csr_matrix(off - sp.diags(np.asarray(off.sum(axis=1)).ravel()))


# --------------------------------------------------------------------------- stabilization


class Stabilization:
    """The velocity stabilization (docs/method.md section 5):
    du_i = prefactor * sum_j pair(r, w, dw, d2w) (u_j - u_i) for inner fluid particles, with
    pair = W' and prefactor = -alpha_s l0 / n0 (W' at r_e, the n0 of the number density)."""

    @staticmethod
    def pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        return dw

    @staticmethod
    def prefactor(alpha_s: float, l0: float, n0: float) -> float:
        return -alpha_s * l0 / n0


STABILIZATION = Stabilization()


# --------------------------------------------------------------------------- particle shifting


class Shifting:
    """Particle shifting (docs/method.md section 5b): after the move, every inner fluid
    particle (fluid, not free surface) moves down the gradient of the particle concentration
    C = n / n0 and carries its velocity along to first order:

        grad C_i = -(1/n0) sum_j W'(r_ij) (r_j - r_i) / r_ij
        dr_i = -D grad C_i = prefactor sum_j pair(r_ij) (r_j - r_i),  pair = W' / r,
        prefactor = D / n0,  D = A r_e U dt  (A = ``FlowPhysics.shifting_coefficient``,
        U = max |u| after the move),
        |dr_i| capped at ``CAP`` l0,
        u_i += (dr_i . grad) u_i,  grad u_i = (D_s / n0) sum_j (u_j - u_i) (r_j - r_i)
        ``velocity_pair``(r_ij)  (the original MPS gradient, Eq. 5: W / r^2).

    Both sums use every neighbour within r_e (walls and dummy particles complete the
    concentration's support) at the moved positions, all from the same state (the shifts do
    not see each other).
    """

    CAP = 0.2
    """Largest shift of a step, in l0: the pair term W'/r of a singular weight (WF1) grows as
    1/r^3 for a near-coincident pair; a bounded step keeps one such pair from throwing a
    particle across its neighbours."""

    @staticmethod
    def pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        return dw / r

    @staticmethod
    def velocity_pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        return w / (r * r)

    @staticmethod
    def prefactor(coefficient: float, re: float, speed: float, dt: float, n0: float) -> float:
        return coefficient * re * speed * dt / n0

    @staticmethod
    def gradient_factor(n0: float) -> float:
        return DIM / n0


SHIFTING = Shifting()


def lattice_pairs(n_side: int, l0: float = 1.0) -> tuple[FloatArray, Box]:
    """A fully periodic square lattice of ``n_side``^2 particles, for oracles and tests."""
    box = Box((0.0, 0.0), (n_side * l0, n_side * l0), (True, True))
    ix, iy = np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij")
    pos = np.column_stack([(ix.ravel() + 0.5) * l0, (iy.ravel() + 0.5) * l0])
    return pos, box


__all__ = [
    "DIM",
    "SHIFTING",
    "STABILIZATION",
    "Shifting",
    "Stabilization",
    "build_pairs",
    "divergence",
    "gradient",
    "gradient_matrix",
    "lattice_constants",
    "mps_radial",
    "neighbour_min",
    "number_density",
    "pair_formula",
    "particle_constants",
]
