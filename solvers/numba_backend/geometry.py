"""Geometry of a box as the compiled code sees it, and separations under the minimum image.

A box is passed to the compiled code as one (2,) float64 array ``period``: the period L of each
periodic axis and 0.0 on free axes (:func:`box_period`).  Separations follow
:meth:`mpsbench.physics.particles.Box.minimum_image` bit for bit: ``dx = r_j - r_i``, then on a
periodic axis ``dx - L * rint(dx / L)`` (:func:`min_image`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mpsbench.physics.particles import Box

from ._jit import compiled

FloatArray = NDArray[np.float64]


def box_period(box: Box | None) -> FloatArray:
    """(2,) float64: the box length along each periodic axis, 0.0 along free axes."""
    period = np.zeros(2)
    if box is not None:
        for ax in range(2):
            if box.periodic[ax]:
                period[ax] = box.hi[ax] - box.lo[ax]
    return period


def box_lo(box: Box | None) -> FloatArray:
    """(2,) float64 lower corner of the box (zeros without a box): origin of periodic cells."""
    return np.zeros(2) if box is None else np.asarray(box.lo, dtype=np.float64)


@njit(inline="always")
def half_width(period):
    """Half the period of an axis, +inf on a free axis (period 0): the argument of min_image."""
    return 0.5 * period if period > 0.0 else np.inf


@njit(inline="always")
def min_image(d, period, half):
    """One component of a separation under the minimum-image convention.

    ``half`` = :func:`half_width` (``period``).  Same bits as ``d - L * rint(d / L)``
    (Box.minimum_image): inside half a period nothing changes, up to 1.4 periods the image is
    d -+ L (exactly what rint gives there), beyond that the general form is used (positions
    that are not wrapped into the box).  One well-predicted compare in the common case.
    """
    if abs(d) > half:
        if abs(d) < 1.4 * period:
            return d - period if d > 0.0 else d + period
        return d - period * np.rint(d / period)
    return d


@njit(inline="always")
def pos_sep(pos, j, xi, yi, px, py, hx, hy):
    """(dx, dy, r^2) from (xi, yi) to particle j of an (n, 2) ``pos``, minimum image."""
    dx = min_image(pos[j, 0] - xi, px, hx)
    dy = min_image(pos[j, 1] - yi, py, hy)
    return dx, dy, dx * dx + dy * dy


@compiled
def csr_geometry(pos, offsets, nbr, period, dx, r):
    """Fill ``dx[k] = r_j - r_i`` (minimum image) and ``r[k] = |dx[k]|`` for every CSR entry."""
    hx = half_width(period[0])
    hy = half_width(period[1])
    n = offsets.shape[0] - 1
    for i in range(n):
        xi = pos[i, 0]
        yi = pos[i, 1]
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            d0 = min_image(pos[j, 0] - xi, period[0], hx)
            d1 = min_image(pos[j, 1] - yi, period[1], hy)
            dx[k, 0] = d0
            dx[k, 1] = d1
            r[k] = np.sqrt(d0 * d0 + d1 * d1)


@compiled
def pair_geometry(pos, i, j, period, dx, r):
    """Fill ``dx`` and ``r`` for a pair list (i, j), same formula as ``PairList.refresh``."""
    hx = half_width(period[0])
    hy = half_width(period[1])
    for k in range(i.shape[0]):
        d0 = min_image(pos[j[k], 0] - pos[i[k], 0], period[0], hx)
        d1 = min_image(pos[j[k], 1] - pos[i[k], 1], period[1], hy)
        dx[k, 0] = d0
        dx[k, 1] = d1
        r[k] = np.sqrt(d0 * d0 + d1 * d1)


@compiled
def max_displacement(pos, ref, period):
    """max_i |pos_i - ref_i| under the minimum image (wrapping a particle is not a move).

    NaN positions give NaN, which fails every ``<=`` test and so forces a rebuild.
    """
    hx = half_width(period[0])
    hy = half_width(period[1])
    n = pos.shape[0]
    d2 = np.empty(n)
    for i in range(n):
        d0 = min_image(pos[i, 0] - ref[i, 0], period[0], hx)
        d1 = min_image(pos[i, 1] - ref[i, 1], period[1], hy)
        d2[i] = d0 * d0 + d1 * d1
    if n == 0:
        return 0.0
    return np.sqrt(np.max(d2))


__all__ = [
    "box_lo",
    "box_period",
    "csr_geometry",
    "half_width",
    "max_displacement",
    "min_image",
    "pair_geometry",
    "pos_sep",
]
