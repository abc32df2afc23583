"""The ``mirror`` wall-velocity treatment, compiled (same method as the reference backend's).

Each boundary particle with wall geometry (``wall_nx``, ``wall_ny``, ``wall_dist``) is
reflected across its wall line; the fluid velocity u_f at the mirror point is the value at that
point of the kernel-weighted linear least-squares fit to the fluid particles within r_e (exact
for a linear field), and the boundary particle gets u_b = 2 u_wall - u_f.  Where the fit is
ill-posed (fewer than three data points, or a moment matrix with |det| <= 1e-8 den^3) the Shepard
average is used; without any fluid neighbour the prescribed velocity is kept.  See
:func:`mpsbench.physics.boundaries.mirror_velocity` for the reasoning.

Fluid particles near each mirror point come from one cell-list build over the fluid positions
and the mirror points together, with fluid-fluid and mirror-mirror pairs left out (rigid groups
0 and 1 of :func:`.cells.build_csr`).  The 3x3 solve is Gaussian elimination with partial
pivoting, as LAPACK's, so the two backends agree to rounding.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from mpsbench.physics.boundaries import extrapolate_through_wall, mirror_points
from mpsbench.physics.particles import Box, Particles

from . import formulas as fm
from ._jit import factory, pick
from .cells import build_csr
from .geometry import box_period, half_width, min_image
from .neighbour_list import CellNeighbourList

FloatArray = NDArray[np.float64]


@njit(cache=True, inline="always")
def _solve3(m, b0, b1, b2):
    """(det, x0) of the 3x3 system m x = b (first unknown only) by elimination with pivoting.

    ``m`` is a (3, 3) work array (overwritten); b0, b1, b2 are (2,) right-hand sides.  Returns
    det and the two components of x[0].
    """
    b = np.empty((3, 2))
    b[0, 0] = b0[0]
    b[0, 1] = b0[1]
    b[1, 0] = b1[0]
    b[1, 1] = b1[1]
    b[2, 0] = b2[0]
    b[2, 1] = b2[1]
    det = 1.0
    for c in range(3):
        p = c
        for r in range(c + 1, 3):
            if abs(m[r, c]) > abs(m[p, c]):
                p = r
        if p != c:
            det = -det
            for k in range(3):
                t = m[c, k]
                m[c, k] = m[p, k]
                m[p, k] = t
            for k in range(2):
                t = b[c, k]
                b[c, k] = b[p, k]
                b[p, k] = t
        piv = m[c, c]
        det *= piv
        if piv == 0.0:
            return 0.0, 0.0, 0.0
        for r in range(c + 1, 3):
            f = m[r, c] / piv
            for k in range(c, 3):
                m[r, k] -= f * m[c, k]
            for k in range(2):
                b[r, k] -= f * b[c, k]
    x = np.empty((3, 2))
    for r in range(2, -1, -1):
        for k in range(2):
            s = b[r, k]
            for q in range(r + 1, 3):
                s -= m[r, q] * x[q, k]
            x[r, k] = s / m[r, r]
    return det, x[0, 0], x[0, 1]


@factory
def mirror_fit(wt: fm.Weight) -> Any:
    """Fluid velocity at each mirror point (rows nf.. of ``pos``) from fluid rows 0..nf-1:
    ``(offsets, nbr, pos, period, nf, vel, re, out)``, out (n_mirror, 2); NaN where a mirror
    point has no fluid particle within ``re``."""
    wfun = wt.w

    def mirror_fit(offsets, nbr, pos, period, nf, vel, re, out):
        nm = offsets.shape[0] - 1 - nf
        hx = half_width(period[0])
        hy = half_width(period[1])
        floor = 0.05 * re
        for q in prange(nm):
            i = nf + q
            xi = pos[i, 0]
            yi = pos[i, 1]
            m00 = m01 = m02 = m11 = m12 = m22 = 0.0
            r00 = r01 = r10 = r11 = r20 = r21 = 0.0
            count = 0
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                if j >= nf:
                    continue
                dx = min_image(pos[j, 0] - xi, period[0], hx)
                dy = min_image(pos[j, 1] - yi, period[1], hy)
                r = np.sqrt(dx * dx + dy * dy)
                if not r <= re:
                    continue
                count += 1
                sx = dx / re
                sy = dy / re
                w = wfun(max(r, floor), re)
                m00 += w
                m01 += w * sx
                m02 += w * sy
                m11 += w * sx * sx
                m12 += w * sx * sy
                m22 += w * sy * sy
                u = vel[j, 0]
                v = vel[j, 1]
                r00 += w * u
                r01 += w * v
                r10 += w * sx * u
                r11 += w * sx * v
                r20 += w * sy * u
                r21 += w * sy * v
            if not m00 > 0.0:
                out[q, 0] = np.nan
                out[q, 1] = np.nan
                continue
            out[q, 0] = r00 / m00
            out[q, 1] = r01 / m00
            if count >= 3:
                mat = np.empty((3, 3))
                mat[0, 0] = m00
                mat[0, 1] = m01
                mat[0, 2] = m02
                mat[1, 0] = m01
                mat[1, 1] = m11
                mat[1, 2] = m12
                mat[2, 0] = m02
                mat[2, 1] = m12
                mat[2, 2] = m22
                det, a0, a1 = _solve3(
                    mat, np.array([r00, r01]), np.array([r10, r11]), np.array([r20, r21])
                )
                if abs(det) > 1e-8 * m00 * m00 * m00:
                    out[q, 0] = a0
                    out[q, 1] = a1

    return mirror_fit


def mirror_velocity(
    p: Particles, wt: fm.Weight, re: float, box: Box, serial: bool = False
) -> FloatArray:
    """Boundary velocities extrapolated so the wall velocity holds on the wall line.

    Returns a copy of ``p.vel`` with the boundary rows replaced (see the module docstring).
    """
    vel = p.vel.copy()
    bnd, fluid, mirror = mirror_points(p)
    if len(bnd) == 0:
        return vel
    nf = len(fluid)
    both = np.ascontiguousarray(np.vstack([p.pos[fluid], mirror]))
    group = np.zeros(len(both), np.int64)
    group[nf:] = 1
    csr = build_csr(both, CellNeighbourList.padded(re, 0.0), box, group=group, serial=serial)
    u_mirror = np.empty((len(bnd), 2))
    pick(mirror_fit(wt), serial)(
        csr.offsets, csr.nbr, both, box_period(box), nf, np.ascontiguousarray(p.vel[fluid]),
        float(re), u_mirror,
    )
    vel[bnd] = extrapolate_through_wall(p.vel[bnd], u_mirror)
    return vel


__all__ = ["mirror_fit", "mirror_velocity"]
