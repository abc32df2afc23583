"""The models' own formulas, compiled: what the kernel factories close over.

Every model of :mod:`mpsbench.physics` writes its formulas once, as static methods in plain
arithmetic (weights: W, W', W'' of (r, re); Laplacians: ``pair`` and ``prefactor``, optionally
``moment``; pressure gradients: ``pair``, ``radial``, ``prefactor``; the stabilization: ``pair``).
This module compiles those same functions with numba (:func:`compile_models`) and composes the
per-pair pieces the kernels call: W, W', W'' inside the closed support (:func:`support`), a
Laplacian's pair coefficient (:func:`laplacian_pair`).  A plugin's model runs here as the
built-ins do; nothing in the kernels names a model.

The support is closed under rounding as in :mod:`mpsbench.physics.weights`: a pair counts when
``0 < r <= re (1 + SUPPORT_RTOL)`` (:func:`inside`), and W, W', W'' are evaluated at
``min(r, re)`` (divisions by r in a pair formula use r itself, as the numpy evaluation does).  A
coincident pair (r = 0) contributes nothing (the reference would produce inf/NaN for it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from numba import njit

from mpsbench.physics.gradients import GradientModel
from mpsbench.physics.laplacians import LaplacianModel
from mpsbench.physics.operators import SHIFTING, STABILIZATION, mps_radial
from mpsbench.physics.weights import SUPPORT_RTOL, WeightFunction

SUPPORT = 1.0 + SUPPORT_RTOL  # a pair is inside when r <= re * SUPPORT

# mpsbench.physics.particles.Kind as plain ints for the kernels
# (checked in tests/test_numba_kernels.py)
FLUID = 0
WALL = 1
DUMMY = 2
INFLOW = 3

_jitted: dict[Any, Any] = {}


def jit(fn: Any) -> Any:
    """The numba build of a model's formula (one per function; the kernels inline it).

    ``arcp`` lets a division by a loop invariant become a multiplication by its reciprocal,
    computed once outside the neighbour loop (``r / re`` in every weight: the hand-written
    kernels did exactly that with a precomputed 1/re); it changes results by an ulp at most.
    ``error_model="numpy"``: no zero-division check (a branch that keeps a loop scalar); a
    coincident pair's ``re / r`` is inf and the closed support selects 0.0 for it.
    """
    if fn not in _jitted:
        _jitted[fn] = njit(fastmath={"arcp"}, error_model="numpy")(fn)
    return _jitted[fn]


@njit(inline="always")
def inside(r: float, r2: float, re_s: float) -> bool:
    """The closed support under rounding: 0 < r <= re (1 + SUPPORT_RTOL) (``re_s``)."""
    return (r <= re_s) & (r2 > 0.0)


@dataclass(frozen=True)
class Weight:
    """A weighting function's W, W', W'' of (r, re) for 0 < r <= re, compiled."""

    name: str
    w: Any
    dw: Any
    d2w: Any


@dataclass(frozen=True)
class Laplacian:
    """A Laplacian's compiled ``pair`` (and ``moment``, or None) with its ``prefactor``."""

    name: str
    pair: Any
    moment: Any
    prefactor: Any  # the Python function (n0, lam) -> float, evaluated once per run

    @property
    def has_moment(self) -> bool:
        return self.moment is not None


@dataclass(frozen=True)
class Gradient:
    """A pressure gradient's compiled ``pair`` and ``radial``, its ``prefactor``, ``uses_pmin``."""

    name: str
    pair: Any
    radial: Any
    prefactor: Any  # (n0) -> float
    uses_pmin: bool


def weight(wf: WeightFunction) -> Weight:
    return Weight(wf.name, jit(wf.w_inside), jit(wf.dw_inside), jit(wf.d2w_inside))


def laplacian(model: LaplacianModel) -> Laplacian:
    moment = model.moment
    return Laplacian(model.name, jit(model.pair), None if moment is None else jit(moment),
                     model.prefactor)


def gradient(model: GradientModel) -> Gradient:
    return Gradient(model.name, jit(model.pair), jit(model.radial), model.prefactor,
                    bool(model.uses_pmin))


STABILIZATION_PAIR = jit(STABILIZATION.pair)
SHIFTING_PAIR = jit(SHIFTING.pair)
SHIFTING_VELOCITY_PAIR = jit(SHIFTING.velocity_pair)
RADIAL = jit(mps_radial)  # W / r^2 of the original gradient (Eq. 5) and divergence


@dataclass(frozen=True)
class Models:
    """The compiled models of one run (what :func:`compile_models` returns)."""

    weight: Weight
    laplacian: Laplacian
    gradient: Gradient


def compile_models(wf: WeightFunction, lap: LaplacianModel, grad: GradientModel) -> Models:
    return Models(weight(wf), laplacian(lap), gradient(grad))


# --------------------------------------------------------------------------- per-pair pieces

_support: dict[Weight, Any] = {}
_pairs: dict[tuple[Weight, Any], Any] = {}


def support(wt: Weight) -> Any:
    """``(r, re) -> (W, W', W'')`` at min(r, re): the weights of a pair inside the support
    (the caller selects 0 outside it with :func:`inside`; unused values are optimised away)."""
    if wt not in _support:
        w, dw, d2w = wt.w, wt.dw, wt.d2w

        @njit(inline="always")
        def weights(r, re):
            rc = min(r, re)
            return w(rc, re), dw(rc, re), d2w(rc, re)

        _support[wt] = weights
    return _support[wt]


def pair_of(wt: Weight, formula: Any) -> Any:
    """``(r, re) -> formula(r, W, W', W'')`` at the pair's distance (support as above)."""
    key = (wt, formula)
    if key not in _pairs:
        weights = support(wt)

        @njit(inline="always")
        def value(r, re):
            w, dw, d2w = weights(r, re)
            return formula(r, w, dw, d2w)

        _pairs[key] = value
    return _pairs[key]


def laplacian_pair(wt: Weight, lap: Laplacian) -> Any:
    """``(r, re, s, i, j) -> c_ij / prefactor``: the Laplacian's pair formula at the pair's
    distance; ``s`` is the per-particle moment S (an empty array without a moment)."""
    key = (wt, lap)
    if key not in _pairs:
        weights = support(wt)
        pair = lap.pair
        if lap.moment is None:

            @njit(inline="always")
            def coefficient(r, re, s, i, j):
                w, dw, d2w = weights(r, re)
                return pair(r, w, dw, d2w)

        else:

            @njit(inline="always")
            def coefficient(r, re, s, i, j):
                w, dw, d2w = weights(r, re)
                return pair(r, w, dw, d2w, s[i], s[j])

        _pairs[key] = coefficient
    return _pairs[key]


@njit(inline="always")
def W_ONLY(r, w, dw, d2w):
    """The number density's pair term: W itself."""
    return w


def number_density_pair(wt: Weight) -> Any:
    """``(r, re) -> W`` (the number density's pair term)."""
    return pair_of(wt, W_ONLY)


def stabilization_pair(wt: Weight) -> Any:
    """``(r, re) -> the stabilization's pair weight`` (W')."""
    return pair_of(wt, STABILIZATION_PAIR)


def shifting_pairs(wt: Weight) -> tuple[Any, Any]:
    """``(r, re) -> `` the shifting's concentration pair (W'/r) and velocity-gradient pair
    (W/r^2)."""
    return pair_of(wt, SHIFTING_PAIR), pair_of(wt, SHIFTING_VELOCITY_PAIR)
