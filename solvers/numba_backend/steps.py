"""numba pieces of the WC-MPS and diffusion steps that are not a fused pass of :mod:`.fused`.

The equation of state (called at the end of each row of the number density), the health
summary the runner asks for after each step, and the diffusion operator held as per-entry
coefficients of the CSR list (the static number density of rigid pairs is numpy, in the
solver).  Formulas and the order of floating-point operations follow
:mod:`mpsbench.run.scheme` and the reference backend where that is cheap, so that the backends
agree to rounding; the conventions (kinds, masks, ``offsets, nbr, pos, period`` with pos
(n, 2)) are those of :mod:`.kernels`.  Units are SI.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange

from mpsbench.physics.powers import whole_exponent, whole_power

from . import formulas as fm
from ._jit import compiled, factory, kernel
from .formulas import DUMMY, FLUID, RADIAL, SUPPORT, inside
from .geometry import half_width
from .geometry import pos_sep as sep

# --------------------------------------------------------------------------- equation of state


_whole_power = njit(inline="always")(whole_power)
integer_gamma = njit(inline="always")(whole_exponent)
"""The ``igamma`` of :func:`power`: gamma when it is a whole number 1..16, else 0 (the core's
:func:`~mpsbench.physics.powers.whole_exponent`, hoisted out of the loops by the kernels)."""


@njit(inline="always")
def power(x, gamma, igamma):
    """x**gamma: the core's :func:`~mpsbench.physics.powers.whole_power` when gamma is a whole
    number 1..16 (``igamma`` > 0), the same multiplications as the reference backend's equation
    of state (so the bits do not depend on the processor); pow() otherwise.  pow() also costs
    about as much as a dozen neighbour terms."""
    if igamma == 0:
        return x**gamma
    return _whole_power(x, igamma)


@njit(inline="always")
def state_of(i, ni, kind, n0, tait, prefactor, gamma, igamma, clip, threshold, n_out, p_out,
             surface, inner):
    """Particle i's number density ``ni`` -> pressure, free surface and inner flags.

    Tait: p = prefactor ((n/n0)^gamma - 1), prefactor rho0 c0^2 / gamma; linear: p =
    prefactor (n/n0 - 1), prefactor rho0 c0^2.  Negative pressure clipped to 0 with ``clip``
    (np.maximum(p, 0): NaN stays NaN).  Fluid, wall and inflow particles carry pressure; those
    with n < ``threshold`` (beta n0) are free surface and get p = 0, as do dummy particles.
    ``inner`` = fluid and not free surface (the particles the stabilization acts on).
    """
    n_out[i] = ni
    ratio = ni / n0
    if tait:
        pres = prefactor * (power(ratio, gamma, igamma) - 1.0)
    else:
        pres = prefactor * (ratio - 1.0)
    if clip and not pres >= 0.0:
        pres = pres if pres != pres else 0.0
    k_i = kind[i]
    carries = k_i != DUMMY
    fs = carries and ni < threshold
    surface[i] = fs
    inner[i] = (k_i == FLUID) and not fs
    p_out[i] = 0.0 if (fs or not carries) else pres


# --------------------------------------------------------------------------- health


@compiled
def health(X, V, pressure, kind, lo, hi, free_axis, margin, field):
    """(all finite, max fluid speed, fluid particles outside the box by more than ``margin``,
    max |field|) in one pass: what the runner checks after every step.  ``X``, ``V``: positions
    and velocities as (2, n) arrays; ``free_axis``: which axes the box bounds (periodic axes do
    not); ``field``: the diffusion scalar or an empty array.  Non-finite values make the speed or
    the field maximum NaN."""
    bad = 0.0  # sum of (a - a) over every value: 0 while all are finite, NaN after inf or NaN
    m2 = 0.0
    out = 0
    for i in range(X.shape[1]):
        x = X[0, i]
        y = X[1, i]
        u = V[0, i]
        v = V[1, i]
        # arithmetic, not a chain of branches: the loop stays straight-line
        bad += ((x - x) + (y - y)) + ((u - u) + (v - v)) + (pressure[i] - pressure[i])
        if kind[i] == FLUID:
            s = u * u + v * v
            if s > m2 or s != s:
                m2 = s
            if (free_axis[0] and (x < lo[0] - margin or x > hi[0] + margin)) or (
                    free_axis[1] and (y < lo[1] - margin or y > hi[1] + margin)):
                out += 1
    fmax = 0.0
    for i in range(field.shape[0]):
        a = abs(field[i])
        if a > fmax or a != a:
            fmax = a
    return bad == 0.0, np.sqrt(m2), out, fmax


# --------------------------------------------------------------------------- diffusion


@factory
def operator_entries(wt: fm.Weight, lap: fm.Laplacian) -> Any:
    """Per-entry coefficients a_ij of the Laplacian: lap(phi)_i = sum_j a_ij (phi_j - phi_i).

    Arguments ``(offsets, nbr, pos, period, re, pref, s, gfactor, gcorr, coef, rowsum)``
    (``pref``, ``s``, ``gfactor`` as in :func:`.kernels.laplacian_field`).  a_ij = c_ij, or
    with the xu-jin gradient correction c_ij - gfactor (W_ij / r_ij^2) (B_i . r_ij),
    B_i = sum_j c_ij r_ij (the reference's L - diag(B) G in one coefficient).  ``rowsum``
    receives the Gershgorin row sum of |L| (off-diagonal |a_ij| plus the diagonal
    |sum_j a_ij|), as the reference takes it from its sparse matrix.
    """
    coef_of = fm.laplacian_pair(wt, lap)
    w_of = fm.number_density_pair(wt)

    def operator_entries(offsets, nbr, pos, period, re, pref, s, gfactor, gcorr, coef, rowsum):
        n = offsets.shape[0] - 1
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        re_s = re * SUPPORT
        for i in prange(n):
            xi = pos[i, 0]
            yi = pos[i, 1]
            bx = 0.0
            by = 0.0
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                dx, dy, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                c = pref * coef_of(r, re, s, i, j)
                c = c if inside(r, r2, re_s) else 0.0
                coef[k] = c
                bx += c * dx
                by += c * dy
            if gcorr:
                for k in range(offsets[i], offsets[i + 1]):
                    dx, dy, r2 = sep(pos, nbr[k], xi, yi, px, py, hx, hy)
                    r = np.sqrt(r2)
                    q = RADIAL(r, w_of(r, re))
                    q = q if inside(r, r2, re_s) else 0.0
                    coef[k] -= bx * (gfactor * q * dx) + by * (gfactor * q * dy)
            sa = 0.0
            sd = 0.0
            for k in range(offsets[i], offsets[i + 1]):
                sa += abs(coef[k])
                sd += coef[k]
            rowsum[i] = sa + abs(sd)

    return operator_entries


@kernel
def operator_apply(offsets, nbr, coef, phi, out):
    """out_i = sum_j a_ij (phi_j - phi_i): the Laplacian from :func:`operator_entries`."""
    for i in prange(offsets.shape[0] - 1):
        phii = phi[i]
        s = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            s += coef[k] * (phi[nbr[k]] - phii)
        out[i] = s
    return out


@kernel
def axpy(phi, factor, work):
    """phi += factor * work (forward Euler with factor = dt kappa)."""
    for i in prange(phi.shape[0]):
        phi[i] += factor * work[i]


@compiled
def symmetric_step(offsets, nbr, coef, phi, factor, work):
    """phi += factor * L phi for a symmetric L held once per pair (serial).

    Row i of (offsets, nbr, coef) lists only the neighbours j > i; each pair term
    a_ij (phi_j - phi_i) goes to i and, negated, to j.  Half the entries of
    :func:`operator_apply` stream through memory, which is what a sparse matrix-vector product
    is limited by (measured 1.5x faster at 6400 particles, r_e = 4 l0).
    """
    n = offsets.shape[0] - 1
    for i in range(n):
        work[i] = 0.0
    for i in range(n):
        phii = phi[i]
        s = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            d = coef[k] * (phi[j] - phii)
            s += d
            work[j] -= d
        work[i] += s
    for i in range(n):
        phi[i] += factor * work[i]
