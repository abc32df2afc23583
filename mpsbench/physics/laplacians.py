"""Laplacian models: LM1 (``koshizuka-oka``), LM2 (``khayyer-gotoh``), LM3 (``xu-jin``, with
an optional gradient correction) and its analytic variant (``xu-jin-analytic``), and the registry
``LAPLACIANS``.

Adding a Laplacian is one subclass of :class:`LaplacianModel` with its pair formula and prefactor
(static methods in plain arithmetic, see :mod:`mpsbench.physics.weights`) and one registration
(or an entry point in the ``mpsbench.laplacians`` group).  :meth:`LaplacianModel.coefficients`,
``apply`` and ``matrix`` evaluate it on a pair list (the reference backend); the numba backend
compiles the same static methods into its kernels.  Formulas and provenance: docs/method.md
section 3 (D_s = 2).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mpsbench.physics.neighbours import PairList
from mpsbench.physics.operators import DIM, gradient, gradient_matrix, pair_formula
from mpsbench.physics.weights import WeightFunction, static_formula
from mpsbench.registry import Registry

FloatArray = NDArray[np.float64]


class LaplacianModel:
    """A Laplacian lap(phi)_i = sum_j c_ij (phi_j - phi_i) [- B_i . grad(phi)_i].

    c_ij = ``prefactor(n0, lam)`` * ``pair(r, w, dw, d2w)``: the pair formula of r_ij and of
    W, W', W'' at r_ij, symmetric in i and j, in its 2-D form.  A model normalised per
    particle declares ``moment(r, w, dw, d2w)``: S_i = sum_j moment(r_ij, ...) is summed over
    each particle's pairs first, and the pair formula gets the values at both ends,
    ``pair(r, w, dw, d2w, s_i, s_j)`` (symmetric in them).  The formulas are static methods in
    plain arithmetic: :meth:`coefficients` evaluates them on a pair list, the numba backend
    compiles them into its kernels.

    A model whose ``gradient_correction`` is true (``xu-jin`` with the option) also subtracts
    (sum_j c_ij r_ij) . grad(phi)_i, with grad the original gradient (Eq. 5) at the same radius.
    """

    name: str = ""
    description: str = ""
    source: str = ""
    gradient_correction: bool = False
    moment: Callable[..., Any] | None = None

    @staticmethod
    def pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        raise NotImplementedError

    @staticmethod
    def prefactor(n0: float, lam: float) -> float:
        raise NotImplementedError

    def coefficients(
        self, pairs: PairList, weight: WeightFunction, re: float, n0: float, lam: float
    ) -> FloatArray:
        """Per-pair coefficients c_ij (symmetric in i, j), aligned with ``pairs``."""
        if self.moment is None:
            c = pair_formula(self.pair, weight, pairs.r, re)
        else:
            s = pairs.sum_sym(pair_formula(self.moment, weight, pairs.r, re))
            c = pair_formula(self.pair, weight, pairs.r, re, s[pairs.i], s[pairs.j])
        return self.prefactor(n0, lam) * c

    def apply(
        self,
        pairs: PairList,
        phi: FloatArray,
        weight: WeightFunction,
        re: float,
        n0: float,
        lam: float,
        coef: FloatArray | None = None,
    ) -> FloatArray:
        """lap(phi); ``phi`` may be (n,) or (n, k) (each column separately)."""
        c = self.coefficients(pairs, weight, re, n0, lam) if coef is None else coef
        dphi = pairs.diff(phi)
        if dphi.ndim == 1:
            out = pairs.sum_antisym(c * dphi)
        else:
            out = np.column_stack([pairs.sum_antisym(c * dphi[:, k]) for k in range(dphi.shape[1])])
        if self.gradient_correction:
            out = out - self._correction(pairs, phi, weight, re, n0, c)
        return out

    def _correction(
        self, pairs: PairList, phi: FloatArray, weight: WeightFunction, re: float, n0: float,
        c: FloatArray,
    ) -> FloatArray:
        # B_i = sum_j c_ij r_ij: c is symmetric, r_ij flips sign for j -> antisymmetric sum.
        b = pairs.sum_vec_antisym(c[:, None] * pairs.dx)
        w = weight.w(pairs.r, re)
        if phi.ndim == 1:
            g = gradient(pairs, phi, w, n0)
            return (b * g).sum(axis=1)
        cols = [(b * gradient(pairs, phi[:, k], w, n0)).sum(axis=1) for k in range(phi.shape[1])]
        return np.column_stack(cols)

    def matrix(
        self, pairs: PairList, weight: WeightFunction, re: float, n0: float, lam: float
    ) -> sp.csr_matrix:
        """The operator as a sparse (n, n) matrix L with lap(phi) = L @ phi."""
        n = pairs.n
        c = self.coefficients(pairs, weight, re, n0, lam)
        rows = np.concatenate([pairs.i, pairs.j])
        cols = np.concatenate([pairs.j, pairs.i])
        vals = np.concatenate([c, c])
        off = sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
        mat = off - sp.diags(np.asarray(off.sum(axis=1)).ravel())
        if self.gradient_correction:
            b = pairs.sum_vec_antisym(c[:, None] * pairs.dx)
            w = weight.w(pairs.r, re)
            for ax in range(2):
                g = gradient_matrix(pairs, w, n0, ax)
                mat = mat - sp.diags(b[:, ax]) @ g
        return sp.csr_matrix(mat)

    def __repr__(self) -> str:
        return f"<LaplacianModel {self.name}>"


class KoshizukaOka(LaplacianModel):
    """LM1: (2 D / (lambda n0)) sum_j phi_ij W_ij."""

    name = "koshizuka-oka"
    description = "LM1: (2D/(lambda n0)) sum phi_ij W_ij, the original MPS Laplacian"
    source = "Koshizuka & Oka 1996"

    @staticmethod
    def pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        return w

    @staticmethod
    def prefactor(n0: float, lam: float) -> float:
        return 2.0 * DIM / (lam * n0)


class KhayyerGotoh(LaplacianModel):
    """LM2: (1/n0) sum_j phi_ij (W'' - W'/r) (2-D form)."""

    name = "khayyer-gotoh"
    description = "LM2: (1/n0) sum phi_ij (W'' - W'/r), from the divergence of the SPH gradient"
    source = "Khayyer & Gotoh 2010"

    @staticmethod
    def pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        return d2w - dw / r

    @staticmethod
    def prefactor(n0: float, lam: float) -> float:
        return 1.0 / n0


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

    @staticmethod
    def pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        return w / (r * r)

    @staticmethod
    def prefactor(n0: float, lam: float) -> float:
        return 2.0 * DIM / n0


class XuJinAnalytic(LaplacianModel):
    """LM3 (variant): (D/n0) sum_j phi_ij [-W'/r - (D-2) W/r^2] (2-D: -W'/r)."""

    name = "xu-jin-analytic"
    description = "LM3 variant: (D/n0) sum phi_ij [-W'/r - (D-2) W/r^2], analytic divergence"
    source = "Xu & Jin 2016 (reconstructed: analytic divergence of Eq. 5)"

    @staticmethod
    def pair(r: Any, w: Any, dw: Any, d2w: Any) -> Any:
        return -dw / r

    @staticmethod
    def prefactor(n0: float, lam: float) -> float:
        return DIM / n0


def _validate_laplacian(obj: Any) -> None:
    cls = obj if isinstance(obj, type) else type(obj)
    label = f"Laplacian model {getattr(cls, 'name', cls.__name__)!r}"
    for attr, args in (("pair", "r, w, dw, d2w"), ("prefactor", "n0, lam")):
        why = static_formula(cls, attr, args)
        if why is not None:
            raise TypeError(f"{label} {why}")
    if inspect.getattr_static(cls, "moment", None) is not None:
        why = static_formula(cls, "moment", "r, w, dw, d2w")
        if why is not None:
            raise TypeError(f"{label} {why}")


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
