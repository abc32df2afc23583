"""Weighting functions W(r, r_e) of MPS and their radial derivatives.

A weighting function is one subclass of :class:`WeightFunction` plus one ``WEIGHTS.register``
call (or an entry point in the ``mpsbench.weights`` group).  The subclass writes W, W' and W''
for 0 < r <= r_e once, as static methods of ``(r, re)`` in plain arithmetic (numpy ufuncs that
numba also compiles, such as ``np.exp``, work too, but numpy's ``exp``, ``log`` and ``power``
round differently on different processors, so whole powers are written as products, see
:mod:`mpsbench.physics.powers`): numpy evaluates the same code on arrays
(the vectorised, masked :meth:`WeightFunction.w` / ``dw`` / ``d2w`` below, which the reference
backend uses) and the numba backend compiles it into its kernels.  Every backend therefore uses
the one definition, and a plugin's weight runs on all of them.

The support is closed (docs/method.md: sums run over r_ij <= r_e) and, so that it stays closed under
rounding, a distance up to ``r_e (1 + SUPPORT_RTOL)`` counts as ``r_e``.  On a square lattice
with an integer r_e/l0 (2, 3, 4, ...) some neighbours sit exactly on the support boundary; for
weights whose derivative is not zero there (WF1: W' = -1/r_e), the Laplacians that use W' would
otherwise include or drop those neighbours at random depending on the last bit of the
coordinates, and lose the symmetry of the stencil.  The neighbour search uses the same rule.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpsbench.registry import Registry

Array = NDArray[np.float64]

SUPPORT_RTOL = 1e-10
"""Relative slack of the closed support r <= r_e (see the module docstring)."""

FORMULAS = ("w_inside", "dw_inside", "d2w_inside")
"""The static methods a weighting function defines: W, W', W'' of (r, re) for 0 < r <= re."""


def within_support(r: ArrayLike, re: float) -> NDArray[np.bool_]:
    """Mask of distances inside the closed support, ``r <= r_e (1 + SUPPORT_RTOL)``."""
    return np.asarray(r) <= re * (1.0 + SUPPORT_RTOL)


class WeightFunction:
    """Base class: override the static methods :meth:`w_inside`, :meth:`dw_inside` and
    :meth:`d2w_inside` (the formulas for 0 < r <= r_e, see the module docstring)."""

    name: str = ""
    description: str = ""
    source: str = ""

    @staticmethod
    def w_inside(r: Any, re: float) -> Any:
        """W(r) for 0 < r <= re."""
        raise NotImplementedError

    @staticmethod
    def dw_inside(r: Any, re: float) -> Any:
        """dW/dr for 0 < r <= re."""
        raise NotImplementedError

    @staticmethod
    def d2w_inside(r: Any, re: float) -> Any:
        """d2W/dr2 for 0 < r <= re."""
        raise NotImplementedError

    def w(self, r: ArrayLike, re: float) -> Array:
        return _masked(self.w_inside, r, re)

    def dw(self, r: ArrayLike, re: float) -> Array:
        return _masked(self.dw_inside, r, re)

    def d2w(self, r: ArrayLike, re: float) -> Array:
        return _masked(self.d2w_inside, r, re)

    def __repr__(self) -> str:
        return f"<WeightFunction {self.name}>"


def _masked(fn: Callable[[Any, float], Any], r: ArrayLike, re: float) -> Array:
    """``fn`` on the distances inside the closed support, 0 beyond it."""
    r = np.asarray(r, dtype=float)
    re = float(re)
    inside = within_support(r, re)
    out = np.zeros_like(r)
    # a distance within rounding of r_e is evaluated at r_e exactly
    out[inside] = fn(np.minimum(r[inside], re), re)
    return out


class WF1(WeightFunction):
    """W = r_e/r - 1: the original MPS weight, singular at r = 0."""

    name = "wf1"
    description = "W = r_e/r - 1 (original MPS weight; singular at r = 0)"
    source = "Koshizuka & Oka 1996; Xu & Jin 2016 Eq. 2"

    @staticmethod
    def w_inside(r: Any, re: float) -> Any:
        return re / r - 1.0

    @staticmethod
    def dw_inside(r: Any, re: float) -> Any:
        return -re / r**2

    @staticmethod
    def d2w_inside(r: Any, re: float) -> Any:
        return 2.0 * re / (r * r * r)


class WF2(WeightFunction):
    """W = (1 - r/r_e)^3: smooth, finite at r = 0."""

    name = "wf2"
    description = "W = (1 - r/r_e)^3 (finite at r = 0)"
    source = "Shakibaeinia & Jin 2010; Xu & Jin 2016 Eq. 3"

    @staticmethod
    def w_inside(r: Any, re: float) -> Any:
        t = 1.0 - r / re
        return t * t * t

    @staticmethod
    def dw_inside(r: Any, re: float) -> Any:
        return -(3.0 / re) * (1.0 - r / re) ** 2

    @staticmethod
    def d2w_inside(r: Any, re: float) -> Any:
        return (6.0 / re**2) * (1.0 - r / re)


def static_formula(cls: type, attr: str, args: str) -> str | None:
    """Why ``cls.attr`` cannot serve as a compiled formula, or None when it can.

    A formula is a static method: the numba backend compiles the function itself, so it must
    not take ``self``.
    """
    raw = inspect.getattr_static(cls, attr, None)
    if raw is None:
        return f"has no {attr}({args})"
    if isinstance(raw, staticmethod):
        return None
    return f"has {attr} as a method: make it a @staticmethod of ({args}) (numba compiles it)"


def _validate_weight(obj: Any) -> None:
    cls = obj if isinstance(obj, type) else type(obj)
    for attr in FORMULAS:
        why = static_formula(cls, attr, "r, re")
        if why is not None:
            raise TypeError(f"weighting function {getattr(cls, 'name', cls.__name__)!r} {why}")


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
