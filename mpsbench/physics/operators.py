"""MPS operators over a pair list: number density, n0 and lambda, gradients, Laplacians, divergence.

Every operator takes precomputed per-pair quantities so one neighbour list (built at the
largest radius) serves all radii; a weight evaluated at a smaller r_e is simply zero beyond it.
Formulas and their provenance: docs/method.md sections 1-3 (D_s = ``dim`` = 2).

Registries: ``LAPLACIANS`` (``koshizuka-oka``, ``khayyer-gotoh``, ``xu-jin``,
``xu-jin-analytic``) and ``GRADIENTS`` (``pgm1``, ``pgm2``, ``pgm3``).  Adding a Laplacian is one
subclass of :class:`LaplacianModel` that returns its pair coefficients, plus one registration.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mpsbench.physics.neighbours import PairList, build_pairs
from mpsbench.physics.particles import Box
from mpsbench.physics.weights import WeightFunction, get_weight, within_support
from mpsbench.registry import Registry

FloatArray = NDArray[np.float64]


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


def _pair_pressure_force(
    pairs: PairList, pij: FloatArray, w: FloatArray, n0: float, dim: int
) -> FloatArray:
    """(D/n0) sum_j P_ij r_ij W / r^2 for a pair value that is symmetric in (i, j)."""
    coef = pij * _w_over_r2(w, pairs.r)
    # r_ij flips sign for j, P_ij does not: the sum is antisymmetric.
    return (dim / n0) * pairs.sum_vec_antisym(coef[:, None] * pairs.dx)


def pgm1(pairs: PairList, p: FloatArray, w: FloatArray, n0: float, dim: int = 2) -> FloatArray:
    """PGM1 (Eq. 6): (D/n0) sum_j (p_j - pmin_i) r_ij W_ij / r_ij^2."""
    pmin = neighbour_min(pairs, p, w)
    c = _w_over_r2(w, pairs.r)
    ci = (p[pairs.j] - pmin[pairs.i]) * c  # term of i from j, along +dx
    cj = (p[pairs.i] - pmin[pairs.j]) * c  # term of j from i, along -dx
    out = np.empty((pairs.n, 2))
    for ax in range(2):
        d = pairs.dx[:, ax]
        out[:, ax] = np.bincount(pairs.i, ci * d, pairs.n) - np.bincount(pairs.j, cj * d, pairs.n)
    return (dim / n0) * out


def pgm2(pairs: PairList, p: FloatArray, w: FloatArray, n0: float, dim: int = 2) -> FloatArray:
    """PGM2 (Khayyer & Gotoh 2008): (D/n0) sum_j [(p_i+p_j) - (pmin_i+pmin_j)] r_ij W / r^2."""
    pmin = neighbour_min(pairs, p, w)
    pij = (p[pairs.i] + p[pairs.j]) - (pmin[pairs.i] + pmin[pairs.j])
    return _pair_pressure_force(pairs, pij, w, n0, dim)


def pgm3(pairs: PairList, p: FloatArray, w: FloatArray, n0: float, dim: int = 2) -> FloatArray:
    """PGM3 (Toyota et al., symmetric form): (D/n0) sum_j (p_i + p_j) r_ij W / r^2."""
    return _pair_pressure_force(pairs, p[pairs.i] + p[pairs.j], w, n0, dim)


def _w_over_r2(w: FloatArray, r: FloatArray) -> FloatArray:
    out = np.zeros_like(w)
    nz = w != 0
    out[nz] = w[nz] / r[nz] ** 2
    return out


GradientFn = Callable[[PairList, FloatArray, FloatArray, float, int], FloatArray]

GRADIENTS: Registry[GradientFn] = Registry("pressure gradient", group="mpsbench.gradients")
GRADIENTS.register(
    "pgm1",
    pgm1,
    description="(p_j - pmin_i) with artificial repulsion",
    source="Xu & Jin 2016 Eq. 6",
)
GRADIENTS.register(
    "pgm2",
    pgm2,
    description="(p_i + p_j) - (pmin_i + pmin_j), momentum conserving",
    source="Khayyer & Gotoh 2008 (CMPS)",
)
GRADIENTS.register(
    "pgm3",
    pgm3,
    description="(p_i + p_j), symmetric, momentum conserving",
    source="Toyota et al. (reconstructed symmetric form)",
)


# --------------------------------------------------------------------------- Laplacians


class LaplacianModel:
    """A Laplacian of the form lap(phi)_i = sum_j c_ij (phi_j - phi_i) [- B_i . grad(phi)_i].

    Subclasses implement :meth:`coefficients`; a model whose ``gradient_correction`` is true
    also subtracts (sum_j c_ij r_ij) . grad(phi)_i, with grad the original gradient (Eq. 5)
    at the same radius.
    """

    name: str = ""
    description: str = ""
    source: str = ""
    gradient_correction: bool = False

    def coefficients(
        self,
        pairs: PairList,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        dim: int = 2,
    ) -> FloatArray:
        """Per-pair coefficients c_ij (symmetric in i, j), aligned with ``pairs``."""
        raise NotImplementedError

    def apply(
        self,
        pairs: PairList,
        phi: FloatArray,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        dim: int = 2,
        coef: FloatArray | None = None,
    ) -> FloatArray:
        """lap(phi); ``phi`` may be (n,) or (n, k) (each column separately)."""
        c = self.coefficients(pairs, weight, re, n0, lam, dim) if coef is None else coef
        dphi = pairs.diff(phi)
        if dphi.ndim == 1:
            out = pairs.sum_antisym(c * dphi)
        else:
            out = np.column_stack([pairs.sum_antisym(c * dphi[:, k]) for k in range(dphi.shape[1])])
        if self.gradient_correction:
            out = out - self._correction(pairs, phi, weight, re, n0, c, dim)
        return out

    def _correction(
        self, pairs: PairList, phi: FloatArray, weight: WeightFunction, re: float, n0: float,
        c: FloatArray, dim: int,
    ) -> FloatArray:
        # B_i = sum_j c_ij r_ij: c is symmetric, r_ij flips sign for j -> antisymmetric sum.
        b = pairs.sum_vec_antisym(c[:, None] * pairs.dx)
        w = weight.w(pairs.r, re)
        if phi.ndim == 1:
            g = gradient(pairs, phi, w, n0, dim)
            return (b * g).sum(axis=1)
        cols = [
            (b * gradient(pairs, phi[:, k], w, n0, dim)).sum(axis=1) for k in range(phi.shape[1])
        ]
        return np.column_stack(cols)

    def matrix(
        self,
        pairs: PairList,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        dim: int = 2,
    ) -> sp.csr_matrix:
        """The operator as a sparse (n, n) matrix L with lap(phi) = L @ phi."""
        n = pairs.n
        c = self.coefficients(pairs, weight, re, n0, lam, dim)
        rows = np.concatenate([pairs.i, pairs.j])
        cols = np.concatenate([pairs.j, pairs.i])
        vals = np.concatenate([c, c])
        off = sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
        mat = off - sp.diags(np.asarray(off.sum(axis=1)).ravel())
        if self.gradient_correction:
            b = pairs.sum_vec_antisym(c[:, None] * pairs.dx)
            w = weight.w(pairs.r, re)
            for ax in range(2):
                g = gradient_matrix(pairs, w, n0, ax, dim)
                mat = mat - sp.diags(b[:, ax]) @ g
        return sp.csr_matrix(mat)

    def __repr__(self) -> str:
        return f"<LaplacianModel {self.name}>"


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


class KoshizukaOka(LaplacianModel):
    """LM1: (2 D / (lambda n0)) sum_j phi_ij W_ij."""

    name = "koshizuka-oka"
    description = "LM1: (2D/(lambda n0)) sum phi_ij W_ij, the original MPS Laplacian"
    source = "Koshizuka & Oka 1996"

    def coefficients(
        self,
        pairs: PairList,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        dim: int = 2,
    ) -> FloatArray:
        return (2.0 * dim / (lam * n0)) * weight.w(pairs.r, re)


class KhayyerGotoh(LaplacianModel):
    """LM2: (1/n0) sum_j phi_ij (W'' - W'/r) (2-D form)."""

    name = "khayyer-gotoh"
    description = "LM2: (1/n0) sum phi_ij (W'' - W'/r), from the divergence of the SPH gradient"
    source = "Khayyer & Gotoh 2010"

    def coefficients(
        self,
        pairs: PairList,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        dim: int = 2,
    ) -> FloatArray:
        r = pairs.r
        return (weight.d2w(r, re) - (dim - 1) * weight.dw(r, re) / r) / n0


class XuJin(LaplacianModel):
    """LM3 (default reading): (2D/n0) sum_j [phi_ij - grad(phi)_i . r_ij] W_ij / r_ij^2.

    Without gradient correction (default) the gradient term is dropped, which is exact on a
    symmetric neighbourhood.
    """

    name = "xu-jin"
    description = "LM3: (2D/n0) sum phi_ij W/r^2 from the divergence of the MPS gradient"
    source = "Xu & Jin 2016 (reconstructed: divergence of Eq. 5, Taylor closure)"

    def __init__(self, gradient_correction: bool = False) -> None:
        self.gradient_correction = bool(gradient_correction)

    def coefficients(
        self,
        pairs: PairList,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        dim: int = 2,
    ) -> FloatArray:
        return (2.0 * dim / n0) * _w_over_r2(weight.w(pairs.r, re), pairs.r)


class XuJinAnalytic(LaplacianModel):
    """LM3 (variant): (D/n0) sum_j phi_ij [-W'/r - (D-2) W/r^2]."""

    name = "xu-jin-analytic"
    description = "LM3 variant: (D/n0) sum phi_ij [-W'/r - (D-2) W/r^2], analytic divergence"
    source = "Xu & Jin 2016 (reconstructed: analytic divergence of Eq. 5)"

    def coefficients(
        self,
        pairs: PairList,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        dim: int = 2,
    ) -> FloatArray:
        r = pairs.r
        c = -weight.dw(r, re) / r
        if dim != 2:
            c = c - (dim - 2) * _w_over_r2(weight.w(r, re), r)
        return (dim / n0) * c


def _validate_laplacian(obj: Any) -> None:
    inst = obj() if isinstance(obj, type) else obj
    if not callable(getattr(inst, "coefficients", None)):
        raise TypeError("Laplacian model has no coefficients() method")


LAPLACIANS: Registry[Any] = Registry(
    "Laplacian model", group="mpsbench.laplacians", validate=_validate_laplacian
)
for _cls in (KoshizukaOka, KhayyerGotoh, XuJin, XuJinAnalytic):
    LAPLACIANS.register(_cls.name, _cls, description=_cls.description, source=_cls.source)


def get_laplacian(name_or_obj: str | LaplacianModel, **options: Any) -> LaplacianModel:
    """Instantiate a registered Laplacian by name; options go to its constructor.

    ``gradient_correction=True`` is accepted only by models that support it (``xu-jin``).
    """
    if isinstance(name_or_obj, LaplacianModel):
        return name_or_obj
    obj = LAPLACIANS.get(name_or_obj)
    if not isinstance(obj, type):
        if options:
            raise ValueError(f"Laplacian {name_or_obj!r} takes no options, got {sorted(options)}")
        return obj
    options = {k: v for k, v in options.items() if not (k == "gradient_correction" and not v)}
    try:
        return obj(**options)
    except TypeError:
        raise ValueError(
            f"Laplacian {name_or_obj!r} does not accept options {sorted(options)}"
        ) from None


def get_gradient(name: str | GradientFn) -> GradientFn:
    return GRADIENTS.get(name) if isinstance(name, str) else name


def lattice_pairs(n_side: int, l0: float = 1.0) -> tuple[FloatArray, Box]:
    """A fully periodic square lattice of ``n_side``^2 particles, for oracles and tests."""
    box = Box((0.0, 0.0), (n_side * l0, n_side * l0), (True, True))
    ix, iy = np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij")
    pos = np.column_stack([(ix.ravel() + 0.5) * l0, (iy.ravel() + 0.5) * l0])
    return pos, box


__all__ = [
    "GRADIENTS",
    "LAPLACIANS",
    "LaplacianModel",
    "build_pairs",
    "divergence",
    "get_gradient",
    "get_laplacian",
    "gradient",
    "lattice_constants",
    "number_density",
    "particle_constants",
    "pgm1",
    "pgm2",
    "pgm3",
]
