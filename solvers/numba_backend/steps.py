"""numba pieces of the WC-MPS and diffusion steps that are not neighbour operators.

Per-particle updates (predictor, corrector, equation of state fused with the number density),
the setup-time constants (n0, lambda, static number density) and the diffusion operator held
as per-entry coefficients of the CSR list.  Formulas and the order of floating-point operations
follow :mod:`mpsbench.solvers.reference.solver` line by line where that is cheap, so that the two
backends agree to rounding; the conventions (kinds, masks, ``offsets, nbr, pos, period``) are
those of :mod:`.kernels`.  Units are SI.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._jit import kernel
from .cells import half_width
from .kernels import (
    DIM,
    FLUID,
    SUPPORT,
    _coef_in,
    _inside,
    _integer_gamma,
    _sep,
    _state_of,
    _w_in,
    _w_over_r2,
)

# --------------------------------------------------------------------------- setup constants


@njit(cache=True)
def row_constants(offsets, nbr, pos, period, wcode, re, i):
    """(sum_j W_ij, sum_j r_ij^2 W_ij) over the row of particle ``i``: n0 and n0 * lambda."""
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    xi = pos[i, 0]
    yi = pos[i, 1]
    s = 0.0
    s2 = 0.0
    for k in range(offsets[i], offsets[i + 1]):
        _, _, r2 = _sep(pos, nbr[k], xi, yi, px, py, hx, hy)
        r = np.sqrt(r2)
        if _inside(r, r2, re_s):
            w = _w_in(wcode, min(r, re), re, inv_re)
            s += w
            s2 += r * r * w
    return s, s2


@kernel
def static_density(offsets, nbr, pos, period, wcode, re, group, loose, out):
    """sum_j W_ij over the static pairs of each particle (same rigid group, not both loose)."""
    n = offsets.shape[0] - 1
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    for i in prange(n):
        s = 0.0
        gi = group[i]
        if gi >= 0:
            xi = pos[i, 0]
            yi = pos[i, 1]
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                if group[j] != gi or (loose[i] and loose[j]):
                    continue
                _, _, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                w = _w_in(wcode, min(r, re), re, inv_re)
                s += w if _inside(r, r2, re_s) else 0.0
        out[i] = s
    return out


# --------------------------------------------------------------------------- flow step


@kernel
def density_pressure(
    offsets, nbr, pos, period, wcode, re, static_n, kind, n0, tait, prefactor, gamma, clip,
    beta, n_out, p_out, surface, inner,
):
    """Number density, equation of state and free surface in one pass (reference ``_pressure``).

    n_i = sum_j W_ij + static_n_i; the rest as :func:`.kernels._state_of`.
    """
    n = offsets.shape[0] - 1
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    threshold = beta * n0
    igamma = _integer_gamma(gamma)
    for i in prange(n):
        xi = pos[i, 0]
        yi = pos[i, 1]
        s = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            _, _, r2 = _sep(pos, nbr[k], xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            w = _w_in(wcode, min(r, re), re, inv_re)
            s += w if _inside(r, r2, re_s) else 0.0
        _state_of(i, s + static_n[i], kind, n0, tait, prefactor, gamma, igamma, clip, threshold,
                  n_out, p_out, surface, inner)
    return n_out


@kernel
def predictor(pos, vel, lap, use_lap, nu, gx, gy, dt, kind):
    """u* = u + dt (nu lap(u) + g) for fluid particles; every particle moves by dt u*."""
    n = pos.shape[0]
    for i in prange(n):
        if kind[i] == FLUID:
            ax = nu * lap[i, 0] if use_lap else 0.0
            ay = nu * lap[i, 1] if use_lap else 0.0
            vel[i, 0] += dt * (ax + gx)
            vel[i, 1] += dt * (ay + gy)
        pos[i, 0] += dt * vel[i, 0]
        pos[i, 1] += dt * vel[i, 1]


@kernel
def pressure_increment(grad, kind, factor, du):
    """du = factor * grad on fluid particles (factor = -dt / rho0), 0 elsewhere."""
    for i in prange(grad.shape[0]):
        if kind[i] == FLUID:
            du[i, 0] = factor * grad[i, 0]
            du[i, 1] = factor * grad[i, 1]
        else:
            du[i, 0] = 0.0
            du[i, 1] = 0.0


@kernel
def add_into(a, b, out):
    """out = a + b for (n, 2) arrays."""
    for i in prange(a.shape[0]):
        out[i, 0] = a[i, 0] + b[i, 0]
        out[i, 1] = a[i, 1] + b[i, 1]


@kernel
def corrector(pos, vel, du, dt, stab, use_stab):
    """r += dt du; u += stab (the velocity update u += du is done before the stabilization)."""
    for i in prange(pos.shape[0]):
        pos[i, 0] += dt * du[i, 0]
        pos[i, 1] += dt * du[i, 1]
        if use_stab:
            vel[i, 0] += stab[i, 0]
            vel[i, 1] += stab[i, 1]


@njit(cache=True)
def max_over(values, kind, only_fluid):
    """max of ``values`` over fluid particles (or all); 0.0 when there is none."""
    m = -np.inf
    found = False
    for i in range(values.shape[0]):
        if only_fluid and kind[i] != FLUID:
            continue
        found = True
        if values[i] > m:
            m = values[i]
    return m if found else 0.0


@njit(cache=True)
def max_speed(vel):
    """max_i |u_i| (sqrt of the largest u^2 + v^2: the same bits as the max of the norms)."""
    m = 0.0
    for i in range(vel.shape[0]):
        s = vel[i, 0] ** 2 + vel[i, 1] ** 2
        if s > m or s != s:
            m = s
    return np.sqrt(m)


# --------------------------------------------------------------------------- diffusion


@kernel
def operator_entries(
    offsets, nbr, pos, period, model, wcode, re, pref, n0, gcorr, coef, rowsum
):
    """Per-entry coefficients a_ij of the Laplacian: lap(phi)_i = sum_j a_ij (phi_j - phi_i).

    a_ij = c_ij, or with the xu-jin gradient correction c_ij - (D/n0) (W_ij / r_ij^2)
    (B_i . r_ij), B_i = sum_j c_ij r_ij (the reference's L - diag(B) G in one coefficient).
    ``rowsum`` receives the Gershgorin row sum of |L| (off-diagonal |a_ij| plus the diagonal
    |sum_j a_ij|), as the reference takes it from its sparse matrix.
    """
    n = offsets.shape[0] - 1
    f = DIM / n0
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    for i in prange(n):
        xi = pos[i, 0]
        yi = pos[i, 1]
        bx = 0.0
        by = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            dx, dy, r2 = _sep(pos, nbr[k], xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            c = _coef_in(model, wcode, r, min(r, re), r2, re, inv_re, pref)
            c = c if _inside(r, r2, re_s) else 0.0
            coef[k] = c
            bx += c * dx
            by += c * dy
        if gcorr:
            for k in range(offsets[i], offsets[i + 1]):
                dx, dy, r2 = _sep(pos, nbr[k], xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                q = _w_over_r2(wcode, r, r2, re, inv_re, re_s)
                coef[k] -= bx * (f * q * dx) + by * (f * q * dy)
        sa = 0.0
        sd = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            sa += abs(coef[k])
            sd += coef[k]
        rowsum[i] = sa + abs(sd)


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


@njit(cache=True)
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

