"""Weighting functions W(r, r_e) of MPS and their radial derivatives.

Adding a weighting function is one subclass of :class:`WeightFunction` plus one
``WEIGHTS.register`` call (or an entry point in the ``mpsbench.physics.weights`` group).
All functions are vectorised over ``r`` and return 0 outside the support ``r > r_e``.

The support is closed (docs/method.md: sums run over r_ij <= r_e) and, so that it stays closed under
rounding, a distance up to ``r_e (1 + SUPPORT_RTOL)`` counts as ``r_e``.  On a square lattice
with an integer r_e/l0 (2, 3, 4, ...) some neighbours sit exactly on the support boundary; for
weights whose derivative is not zero there (WF1: W' = -1/r_e), the Laplacians that use W' would
otherwise include or drop those neighbours at random depending on the last bit of the
coordinates, and lose the symmetry of the stencil.  The neighbour search uses the same rule.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpsbench.registry import Registry

Array = NDArray[np.float64]

SUPPORT_RTOL = 1e-10
"""Relative slack of the closed support r <= r_e (see the module docstring)."""


def within_support(r: ArrayLike, re: float) -> NDArray[np.bool_]:
    """Mask of distances inside the closed support, ``r <= r_e (1 + SUPPORT_RTOL)``."""
    return np.asarray(r) <= re * (1.0 + SUPPORT_RTOL)


class WeightFunction:
    """Base class: override :meth:`_w`, :meth:`_dw`, :meth:`_d2w` for 0 < r <= r_e."""

    name: str = ""
    description: str = ""
    source: str = ""

    def w(self, r: ArrayLike, re: float) -> Array:
        return self._masked(self._w, r, re)

    def dw(self, r: ArrayLike, re: float) -> Array:
        return self._masked(self._dw, r, re)

    def d2w(self, r: ArrayLike, re: float) -> Array:
        return self._masked(self._d2w, r, re)

    def _masked(self, fn: Any, r: ArrayLike, re: float) -> Array:
        r = np.asarray(r, dtype=float)
        re = float(re)
        inside = within_support(r, re)
        out = np.zeros_like(r)
        # a distance within rounding of r_e is evaluated at r_e exactly
        out[inside] = fn(np.minimum(r[inside], re), re)
        return out

    def _w(self, r: Array, re: float) -> Array:
        raise NotImplementedError

    def _dw(self, r: Array, re: float) -> Array:
        raise NotImplementedError

    def _d2w(self, r: Array, re: float) -> Array:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<WeightFunction {self.name}>"


class WF1(WeightFunction):
    """W = r_e/r - 1: the original MPS weight, singular at r = 0."""

    name = "wf1"
    description = "W = r_e/r - 1 (original MPS weight; singular at r = 0)"
    source = "Koshizuka & Oka 1996; Xu & Jin 2016 Eq. 2"

    def _w(self, r: Array, re: float) -> Array:
        return re / r - 1.0

    def _dw(self, r: Array, re: float) -> Array:
        return -re / r**2

    def _d2w(self, r: Array, re: float) -> Array:
        return 2.0 * re / r**3


class WF2(WeightFunction):
    """W = (1 - r/r_e)^3: smooth, finite at r = 0."""

    name = "wf2"
    description = "W = (1 - r/r_e)^3 (finite at r = 0)"
    source = "Shakibaeinia & Jin 2010; Xu & Jin 2016 Eq. 3"

    def _w(self, r: Array, re: float) -> Array:
        return (1.0 - r / re) ** 3

    def _dw(self, r: Array, re: float) -> Array:
        return -(3.0 / re) * (1.0 - r / re) ** 2

    def _d2w(self, r: Array, re: float) -> Array:
        return (6.0 / re**2) * (1.0 - r / re)


def _validate_weight(obj: Any) -> None:
    inst = obj() if isinstance(obj, type) else obj
    for attr in ("w", "dw", "d2w"):
        if not callable(getattr(inst, attr, None)):
            raise TypeError(f"weighting function has no callable {attr}()")


WEIGHTS: Registry[WeightFunction] = Registry(
    "weighting function", group="mpsbench.weights", validate=_validate_weight
)
for _cls in (WF1, WF2):
    WEIGHTS.register(_cls.name, _cls(), description=_cls.description, source=_cls.source)


def get_weight(name_or_obj: str | WeightFunction) -> WeightFunction:
    """Look a weighting function up by name (or pass an instance through)."""
    if isinstance(name_or_obj, str):
        obj: Any = WEIGHTS.get(name_or_obj)
        return obj() if isinstance(obj, type) else obj
    return name_or_obj
