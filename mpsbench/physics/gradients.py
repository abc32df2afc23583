"""Pressure-gradient models: PGM1, PGM2, PGM3 and the registry ``GRADIENTS``.

A model is one subclass of :class:`GradientModel` with its pair formula (static methods in plain
arithmetic, see :mod:`mpsbench.physics.weights`) and one registration (or an entry point in the
``mpsbench.gradients`` group).  A call evaluates it on a pair list, vectorised (the reference
backend); the numba backend compiles the same static methods into its kernels.  Formulas:
docs/method.md section 2.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mpsbench.physics.neighbours import PairList
from mpsbench.physics.operators import DIM, mps_radial, neighbour_min
from mpsbench.physics.weights import static_formula
from mpsbench.registry import Registry

FloatArray = NDArray[np.float64]


class GradientModel:
    """A pressure gradient (D/n0) sum_j P_ij r_ij W_ij / r_ij^2 over a pair list.

    ``pair(p_i, p_j, pmin_i, pmin_j)`` is P_ij, the pair value in the term of particle i along
    r_ij = r_j - r_i; particle j gets ``pair(p_j, p_i, pmin_j, pmin_i)`` along r_ji = -r_ij.
    ``uses_pmin``: the formula reads pmin (p_min,i = min(p_i, p_j over neighbours with W > 0)),
    so a backend computes it first.  ``radial(r, w)`` is the W/r^2 of the sum and
    ``prefactor(n0)`` the D/n0 in front.  A call evaluates the model on a pair list (the
    vectorised form the reference backend uses); the numba backend compiles the same static
    methods into its kernels.
    """

    name: str = ""
    description: str = ""
    source: str = ""
    uses_pmin: bool = False

    @staticmethod
    def pair(p_i: Any, p_j: Any, pmin_i: Any, pmin_j: Any) -> Any:
        raise NotImplementedError

    radial = staticmethod(mps_radial)

    @staticmethod
    def prefactor(n0: float) -> float:
        return DIM / n0

    def __call__(self, pairs: PairList, p: FloatArray, w: FloatArray, n0: float) -> FloatArray:
        """The gradient of ``p`` (n, 2); ``w`` per pair (0 drops a pair, also from pmin)."""
        pmin = neighbour_min(pairs, p, w) if self.uses_pmin else p
        c = np.zeros_like(w)
        nz = w != 0
        c[nz] = self.radial(pairs.r[nz], w[nz])
        del nz
        pi, pj, mi, mj = p[pairs.i], p[pairs.j], pmin[pairs.i], pmin[pairs.j]
        ci = self.pair(pi, pj, mi, mj) * c  # term of i from j, along +dx
        cj = self.pair(pj, pi, mj, mi) * c  # term of j from i, along -dx
        # the gathers and c go before the scatter's temporaries come: this call was the
        # reference backend's memory peak (issue 20)
        del pi, pj, mi, mj, c
        out = np.empty((pairs.n, 2))
        for ax in range(2):
            d = pairs.dx[:, ax]
            out[:, ax] = np.bincount(pairs.i, ci * d, pairs.n) - np.bincount(
                pairs.j, cj * d, pairs.n
            )
        return self.prefactor(n0) * out

    def __repr__(self) -> str:
        return f"<GradientModel {self.name}>"


class PGM1(GradientModel):
    """PGM1 (Eq. 6): P_ij = p_j - pmin_i."""

    name = "pgm1"
    description = "(p_j - pmin_i) with artificial repulsion"
    source = "Xu & Jin 2016 Eq. 6"
    uses_pmin = True

    @staticmethod
    def pair(p_i: Any, p_j: Any, pmin_i: Any, pmin_j: Any) -> Any:
        return p_j - pmin_i


class PGM2(GradientModel):
    """PGM2 (Khayyer & Gotoh 2008): P_ij = (p_i + p_j) - (pmin_i + pmin_j)."""

    name = "pgm2"
    description = "(p_i + p_j) - (pmin_i + pmin_j), momentum conserving"
    source = "Khayyer & Gotoh 2008 (CMPS)"
    uses_pmin = True

    @staticmethod
    def pair(p_i: Any, p_j: Any, pmin_i: Any, pmin_j: Any) -> Any:
        return (p_i + p_j) - (pmin_i + pmin_j)


class PGM3(GradientModel):
    """PGM3 (Toyota et al., symmetric form): P_ij = p_i + p_j."""

    name = "pgm3"
    description = "(p_i + p_j), symmetric, momentum conserving"
    source = "Toyota et al. (reconstructed symmetric form)"

    @staticmethod
    def pair(p_i: Any, p_j: Any, pmin_i: Any, pmin_j: Any) -> Any:
        return p_i + p_j


pgm1, pgm2, pgm3 = PGM1(), PGM2(), PGM3()


def _validate_gradient(obj: Any) -> None:
    cls = obj if isinstance(obj, type) else type(obj)
    for attr, args in (("pair", "p_i, p_j, pmin_i, pmin_j"), ("radial", "r, w"),
                       ("prefactor", "n0")):
        why = static_formula(cls, attr, args)
        if why is not None:
            raise TypeError(f"pressure gradient {getattr(cls, 'name', cls.__name__)!r} {why}")


GRADIENTS: Registry[GradientModel] = Registry(
    "pressure gradient", group="mpsbench.gradients", validate=_validate_gradient
)
for _grad in (pgm1, pgm2, pgm3):
    GRADIENTS.register(_grad.name, _grad, description=_grad.description, source=_grad.source)


def get_gradient(name: str | GradientModel) -> GradientModel:
    """A registered pressure gradient by name (an instance; a class is instantiated)."""
    obj: Any = GRADIENTS.get(name) if isinstance(name, str) else name
    return obj() if isinstance(obj, type) else obj
