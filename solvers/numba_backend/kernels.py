"""numba per-particle MPS kernels over a CSR neighbour list (both directions of every pair).

Every kernel loops over particles in parallel (``prange``); particle ``i`` only reads its own
row ``nbr[offsets[i]:offsets[i + 1]]`` and writes ``out[i]``, so there are no write conflicts
and the result does not depend on the number of threads.  Separations ``dx = r_j - r_i``
(minimum image through ``period``, see :mod:`.cells`) and ``r = |dx|`` are recomputed from the
positions in each kernel; weights are evaluated inline and are zero beyond the kernel's own
``re``, so one list built at ``r_max + skin`` serves every radius.

Formulas are those of :mod:`mpsbench.physics.operators` (docs/method.md sections 2-5, D_s = 2) and
agree with
them to rounding (per-particle summation order differs).  Integer codes select models:

* weight ``wcode``: :data:`WEIGHT_CODES` (``wf1`` = 1, ``wf2`` = 2);
* Laplacian ``model``: :data:`LAPLACIAN_CODES` (``koshizuka-oka`` 1, ``khayyer-gotoh`` 2,
  ``xu-jin`` 3, ``xu-jin-analytic`` 4) with ``pref`` = :func:`laplacian_prefactor`; ``gcorr``
  adds the xu-jin gradient correction;
* pressure gradient ``model``: :data:`GRADIENT_CODES` (``pgm1`` 1, ``pgm2`` 2, ``pgm3`` 3).

Compiled kernels (call them from other numba code too): :func:`number_density`,
:func:`gradient`, :func:`divergence`, :func:`neighbour_min`, :func:`pressure_gradient`,
:func:`laplacian_field`, :func:`collision`, :func:`stabilization`.  Plain-Python wrappers with
the operator names: :func:`pgm1`, :func:`pgm2`, :func:`pgm3` (one compiled kernel for the three),
:func:`laplacian` (scalar), :func:`laplacian_vec`, :func:`laplacian_abs_rowsum` (one compiled
kernel for all: fewer kernels compile faster).

Conventions: ``offsets, nbr, pos, period`` come first (:mod:`.cells`); ``out`` arrays are passed
in (no allocation in the hot path) and also returned; ``mask`` arguments are boolean
per-particle arrays: a particle whose mask is false neither receives nor contributes (the
reference backend leaves dummy particles out of the pressure gradient this way); ``kind`` is
the int8 :class:`mpsbench.physics.particles.Kind` array (0 = fluid).  A coincident pair (r = 0)
contributes nothing (the reference would produce inf/NaN for it).  Units follow the inputs (SI
in the solvers).

The support is closed under rounding exactly as in :mod:`mpsbench.physics.weights`: a pair counts
when
``0 < r <= re (1 + SUPPORT_RTOL)``, and W, W', W'' are evaluated at ``min(r, re)`` (divisions by
r use r itself, as the numpy models do).  On a square lattice with an integer r_e/l0 about half
of the neighbours at r_e sit a rounding error outside it; W' of wf1 is not zero there, so
dropping them would change khayyer-gotoh, xu-jin-analytic and the stabilization.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from mpsbench.physics.weights import SUPPORT_RTOL

from ._jit import kernel
from .cells import half_width, min_image

DIM = 2.0  # D_s
SUPPORT = 1.0 + SUPPORT_RTOL  # a pair is inside when r <= re * SUPPORT

WEIGHT_CODES = {"wf1": 1, "wf2": 2}
LAPLACIAN_CODES = {"koshizuka-oka": 1, "khayyer-gotoh": 2, "xu-jin": 3, "xu-jin-analytic": 4}
GRADIENT_CODES = {"pgm1": 1, "pgm2": 2, "pgm3": 3}

# mpsbench.physics.particles.Kind as plain ints for the kernels
# (checked in tests/test_numba_kernels.py)
FLUID = 0
WALL = 1
DUMMY = 2
INFLOW = 3


def weight_code(name: str) -> int:
    try:
        return WEIGHT_CODES[name]
    except KeyError:
        raise ValueError(
            f"numba backend: weighting function {name!r} not compiled; known: "
            + ", ".join(WEIGHT_CODES)
        ) from None


def laplacian_code(name: str) -> int:
    try:
        return LAPLACIAN_CODES[name]
    except KeyError:
        raise ValueError(
            f"numba backend: Laplacian {name!r} not compiled; known: " + ", ".join(LAPLACIAN_CODES)
        ) from None


def laplacian_prefactor(model: int, n0: float, lam: float) -> float:
    """The constant in front of each model's pair coefficient (see :func:`lap_coef`)."""
    if model == 1:
        return 2.0 * DIM / (lam * n0)
    if model == 2:
        return 1.0 / n0
    if model == 3:
        return 2.0 * DIM / n0
    if model == 4:
        return DIM / n0
    raise ValueError(f"unknown Laplacian code {model}")


# --------------------------------------------------------------------------- inline pieces
#
# The _*_in helpers are the formulas for 0 < r <= re; callers pass rc = min(r, re) and select
# the result with the closed-support test ``0 < r <= re * SUPPORT`` on r = sqrt(dx^2 + dy^2).
# ``inv_re`` = 1 / re.


@njit(cache=True, inline="always")
def _w_in(wcode, r, re, inv_re):
    if wcode == 1:
        return re / r - 1.0
    t = 1.0 - r * inv_re
    return t * t * t


@njit(cache=True, inline="always")
def _dw_in(wcode, r, re, inv_re):
    if wcode == 1:
        return -re / (r * r)
    t = 1.0 - r * inv_re
    return -(3.0 * inv_re) * (t * t)


@njit(cache=True, inline="always")
def _d2w_in(wcode, r, re, inv_re):
    if wcode == 1:
        return 2.0 * re / (r * r * r)
    return (6.0 * inv_re * inv_re) * (1.0 - r * inv_re)


@njit(cache=True, inline="always")
def _coef_in(model, wcode, r, rc, r2, re, inv_re, pref):
    """Laplacian pair coefficient: weights at ``rc`` = min(r, re), divisions by ``r``."""
    if model == 1:
        return pref * _w_in(wcode, rc, re, inv_re)
    if model == 2:
        return pref * (_d2w_in(wcode, rc, re, inv_re) - _dw_in(wcode, rc, re, inv_re) / r)
    if model == 3:
        return pref * (_w_in(wcode, rc, re, inv_re) / r2)
    return pref * (-_dw_in(wcode, rc, re, inv_re) / r)


@njit(cache=True, inline="always")
def _inside(r, r2, re_s):
    """The closed support under rounding: 0 < r <= re (1 + SUPPORT_RTOL) (``re_s``)."""
    return (r <= re_s) & (r2 > 0.0)


@njit(cache=True, inline="always")
def _power(x, gamma, igamma):
    """x**gamma; by repeated squaring when gamma is a whole number 1..16 (``igamma`` > 0).

    pow() costs about as much as a dozen neighbour terms; squaring is a few multiplications
    and differs from it by a few ulp (Tait's gamma = 7: x * x^2 * x^4).
    """
    if igamma == 0:
        return x**gamma
    result = 1.0
    base = x
    e = igamma
    while e > 0:
        if e & 1:
            result *= base
        base *= base
        e >>= 1
    return result


@njit(cache=True, inline="always")
def _integer_gamma(gamma):
    """The ``igamma`` of :func:`_power`: gamma when it is a whole number 1..16, else 0."""
    return int(gamma) if gamma == np.floor(gamma) and 1.0 <= gamma <= 16.0 else 0


@njit(cache=True, inline="always")
def _state_of(i, ni, kind, n0, tait, prefactor, gamma, igamma, clip, threshold, n_out, p_out,
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
        pres = prefactor * (_power(ratio, gamma, igamma) - 1.0)
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


@njit(cache=True, inline="always")
def _w_over_r2(wcode, r, r2, re, inv_re, re_s):
    """W_ij / r_ij^2 of the gradient, divergence and PGM sums; 0 outside the support."""
    q = _w_in(wcode, min(r, re), re, inv_re) / r2
    return q if _inside(r, r2, re_s) else 0.0


@njit(cache=True)
def weight(wcode, r, re):
    """W(r): wf1 = re/r - 1, wf2 = (1 - r/re)^3; 0 beyond the support (and at r = 0)."""
    if not r <= re * SUPPORT or r <= 0.0:
        return 0.0
    return _w_in(wcode, min(r, re), re, 1.0 / re)


@njit(cache=True)
def dweight(wcode, r, re):
    """W'(r): wf1 = -re/r^2, wf2 = -(3/re)(1 - r/re)^2; 0 beyond the support (and at r = 0)."""
    if not r <= re * SUPPORT or r <= 0.0:
        return 0.0
    return _dw_in(wcode, min(r, re), re, 1.0 / re)


@njit(cache=True)
def d2weight(wcode, r, re):
    """W''(r): wf1 = 2 re/r^3, wf2 = (6/re^2)(1 - r/re); 0 beyond the support (and at r = 0)."""
    if not r <= re * SUPPORT or r <= 0.0:
        return 0.0
    return _d2w_in(wcode, min(r, re), re, 1.0 / re)


@njit(cache=True)
def lap_coef(model, wcode, r, re, pref):
    """Pair coefficient c_ij of a Laplacian; ``pref`` from :func:`laplacian_prefactor`.

    1 koshizuka-oka: pref W; 2 khayyer-gotoh: pref (W'' - W'/r); 3 xu-jin: pref W / r^2;
    4 xu-jin-analytic: pref (-W'/r)  (2-D forms).  0 beyond the support (and at r = 0).
    """
    if not r <= re * SUPPORT or r <= 0.0:
        return 0.0
    return _coef_in(model, wcode, r, min(r, re), r * r, re, 1.0 / re, pref)


# --------------------------------------------------------------------------- number density
#
# Inner loops are branch-free where it pays: every term is computed and then selected with
# ``inside`` (0 < r <= re (1 + SUPPORT_RTOL), the reference's own test), which avoids mispredicted
# branches on the ragged edge of the support (measured ~20% faster than skipping).  A selected
# 0.0 adds nothing, so results equal the skipping form bit for bit.


@njit(cache=True, inline="always")
def _sep(pos, j, xi, yi, px, py, hx, hy):
    dx = min_image(pos[j, 0] - xi, px, hx)
    dy = min_image(pos[j, 1] - yi, py, hy)
    return dx, dy, dx * dx + dy * dy


@kernel
def number_density(offsets, nbr, pos, period, wcode, re, out):
    """n_i = sum_j W_ij."""
    n = offsets.shape[0] - 1
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    for i in prange(n):
        xi = pos[i, 0]
        yi = pos[i, 1]
        s = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            _, _, r2 = _sep(pos, nbr[k], xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            w = _w_in(wcode, min(r, re), re, inv_re)
            s += w if _inside(r, r2, re_s) else 0.0
        out[i] = s
    return out


# --------------------------------------------------------------------------- gradients


@kernel
def gradient(offsets, nbr, pos, period, phi, wcode, re, n0, out):
    """Original gradient (Eq. 5): (D/n0) sum_j (phi_j - phi_i) r_ij W_ij / r_ij^2; out (n, 2)."""
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
        phii = phi[i]
        gx = 0.0
        gy = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            q = _w_over_r2(wcode, r, r2, re, inv_re, re_s)
            c = (phi[j] - phii) * q
            gx += c * dx
            gy += c * dy
        out[i, 0] = f * gx
        out[i, 1] = f * gy
    return out


@kernel
def divergence(offsets, nbr, pos, period, u, wcode, re, n0, out):
    """(D/n0) sum_j (u_j - u_i) . r_ij W_ij / r_ij^2 for a (n, 2) field ``u``."""
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
        ui = u[i, 0]
        vi = u[i, 1]
        s = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            q = _w_over_r2(wcode, r, r2, re, inv_re, re_s)
            s += ((u[j, 0] - ui) * dx + (u[j, 1] - vi) * dy) * q
        out[i] = f * s
    return out


@njit(cache=True)
def _pmin(offsets, nbr, pos, px, py, p, mask, wcode, re, inv_re, i):
    """min(p_i, p_j over neighbours with W_ij > 0 and mask_j).

    W > 0 means 0 < r < re up to rounding at r ~ re; only there is W itself evaluated.
    """
    hx = half_width(px)
    hy = half_width(py)
    m = p[i]
    xi = pos[i, 0]
    yi = pos[i, 1]
    sure_in = re * re * (1.0 - 1e-9)
    sure_out = re * re * (1.0 + 1e-9)
    for k in range(offsets[i], offsets[i + 1]):
        j = nbr[k]
        pj = p[j]
        if not mask[j] or pj >= m:  # most neighbours stop here: no geometry needed
            continue
        _, _, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
        if r2 == 0.0 or r2 > sure_out:
            continue
        if r2 < sure_in:
            m = pj
        else:
            r = np.sqrt(r2)
            if r <= re and _w_in(wcode, r, re, inv_re) > 0.0:
                m = pj
    return m


@kernel
def neighbour_min(offsets, nbr, pos, period, p, mask, wcode, re, out):
    """p_min,i = min(p_i, min of p_j over neighbours with W_ij > 0 and mask_j); masked i: p_i."""
    n = offsets.shape[0] - 1
    inv_re = 1.0 / re
    for i in prange(n):
        if mask[i]:
            out[i] = _pmin(offsets, nbr, pos, period[0], period[1], p, mask, wcode, re, inv_re, i)
        else:
            out[i] = p[i]
    return out


@kernel
def pressure_gradient(offsets, nbr, pos, period, p, pmin, mask, model, wcode, re, n0, out, rows):
    """PGM ``model`` (:data:`GRADIENT_CODES`) of the pressure ``p``; out (n, 2).

    (D/n0) sum_j P_ij r_ij W_ij / r_ij^2 over neighbours with ``mask`` set, with
    1 pgm1 (Eq. 6): P = p_j - pmin_i (p_min,i computed here, ``pmin`` unused);
    2 pgm2 (Khayyer & Gotoh 2008): P = (p_i + p_j) - (pmin_i + pmin_j), ``pmin`` from
    :func:`neighbour_min` with the same mask, weight and re;
    3 pgm3 (symmetric form): P = p_i + p_j (``pmin`` unused).
    Masked-out rows get 0.  ``rows``: a boolean array of the rows wanted (the others get 0;
    a solver needs fluid rows only), or an empty one for all.  The wrappers :func:`pgm1`,
    :func:`pgm2`, :func:`pgm3` name the models.
    """
    n = offsets.shape[0] - 1
    f = DIM / n0
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    some = rows.shape[0] > 0
    for i in prange(n):
        gx = 0.0
        gy = 0.0
        if mask[i] and (not some or rows[i]):
            xi = pos[i, 0]
            yi = pos[i, 1]
            pi = p[i]
            pm = 0.0
            if model == 1:
                pm = _pmin(offsets, nbr, pos, px, py, p, mask, wcode, re, inv_re, i)
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                if not mask[j]:
                    continue
                dx, dy, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                q = _w_over_r2(wcode, r, r2, re, inv_re, re_s)
                if model == 2:
                    pij = (pi + p[j]) - (pmin[i] + pmin[j])
                elif model == 1:
                    pij = p[j] - pm
                else:
                    pij = pi + p[j]
                c = pij * q
                gx += c * dx
                gy += c * dy
        out[i, 0] = f * gx
        out[i, 1] = f * gy
    return out


_ALL_ROWS = np.zeros(0, dtype=np.bool_)


def pgm1(offsets, nbr, pos, period, p, mask, wcode, re, n0, out):
    """PGM1 (Eq. 6): (D/n0) sum_j (p_j - pmin_i) r_ij W / r^2, p_min,i fused in; out (n, 2)."""
    return pressure_gradient(
        offsets, nbr, pos, period, p, p, mask, 1, wcode, re, n0, out, _ALL_ROWS
    )


def pgm2(offsets, nbr, pos, period, p, pmin, mask, wcode, re, n0, out):
    """PGM2: (D/n0) sum_j [(p_i + p_j) - (pmin_i + pmin_j)] r_ij W / r^2; out (n, 2)."""
    return pressure_gradient(
        offsets, nbr, pos, period, p, pmin, mask, 2, wcode, re, n0, out, _ALL_ROWS
    )


def pgm3(offsets, nbr, pos, period, p, mask, wcode, re, n0, out):
    """PGM3 (symmetric form): (D/n0) sum_j (p_i + p_j) r_ij W / r^2; out (n, 2)."""
    return pressure_gradient(
        offsets, nbr, pos, period, p, p, mask, 3, wcode, re, n0, out, _ALL_ROWS
    )


# --------------------------------------------------------------------------- Laplacians


@kernel
def laplacian_field(
    offsets, nbr, pos, period, phi, model, wcode, re, pref, n0, gcorr, out, rowsum, rows
):
    """Laplacian ``model`` of each column of ``phi`` (n, k), k = 1 or 2; out (n, k).

    lap(phi)_i = sum_j c_ij (phi_j - phi_i) [- B_i . grad(phi)_i]: ``pref`` =
    :func:`laplacian_prefactor`; with ``gcorr`` (xu-jin gradient correction),
    B_i = sum_j c_ij r_ij and grad is the original gradient (D/n0) sum phi_ij r_ij W / r^2 at
    the same ``re`` (``n0`` is used only there).  ``rowsum``: an (n,) array that receives
    sum_j |c_ij| (fused: the stable time step comes with the viscous term), or an empty array.
    ``rows``: a boolean array of the rows wanted (the others get 0), or an empty one for all.
    The wrappers :func:`laplacian` (scalar), :func:`laplacian_vec` and
    :func:`laplacian_abs_rowsum` call this one kernel.
    """
    n = offsets.shape[0] - 1
    two = phi.shape[1] == 2
    want_rows = rowsum.shape[0] > 0
    f = DIM / n0
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    some = rows.shape[0] > 0
    for i in prange(n):
        if some and not rows[i]:
            out[i, 0] = 0.0
            if two:
                out[i, 1] = 0.0
            if want_rows:
                rowsum[i] = 0.0
            continue
        xi = pos[i, 0]
        yi = pos[i, 1]
        ui = phi[i, 0]
        vi = phi[i, 1] if two else 0.0
        s0 = 0.0
        s1 = 0.0
        sa = 0.0
        bx = 0.0
        by = 0.0
        g0x = 0.0
        g0y = 0.0
        g1x = 0.0
        g1y = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            rc = min(r, re)
            inside = _inside(r, r2, re_s)
            c = _coef_in(model, wcode, r, rc, r2, re, inv_re, pref)
            c = c if inside else 0.0
            d0 = phi[j, 0] - ui
            s0 += c * d0
            d1 = 0.0
            if two:
                d1 = phi[j, 1] - vi
                s1 += c * d1
            sa += abs(c)
            if gcorr:
                bx += c * dx
                by += c * dy
                q = _w_in(wcode, rc, re, inv_re) / r2
                q = q if inside else 0.0
                g0x += d0 * q * dx
                g0y += d0 * q * dy
                if two:
                    g1x += d1 * q * dx
                    g1y += d1 * q * dy
        if gcorr:
            s0 -= bx * (f * g0x) + by * (f * g0y)
            s1 -= bx * (f * g1x) + by * (f * g1y)
        out[i, 0] = s0
        if two:
            out[i, 1] = s1
        if want_rows:
            rowsum[i] = sa
    return out


_NO_ROWS = np.empty(0)


def laplacian(offsets, nbr, pos, period, phi, model, wcode, re, pref, n0, gcorr, out):
    """lap(phi) of a scalar field ``phi`` (n,) into ``out`` (n,) (see :func:`laplacian_field`)."""
    n = len(phi)
    res = np.empty((n, 1)) if not out.flags.c_contiguous else out.reshape(n, 1)
    laplacian_field(
        offsets,
        nbr,
        pos,
        period,
        np.ascontiguousarray(phi, dtype=np.float64).reshape(n, 1),
        model,
        wcode,
        re,
        pref,
        n0,
        gcorr,
        res,
        _NO_ROWS,
        _ALL_ROWS,
    )
    if not out.flags.c_contiguous:
        out[:] = res[:, 0]
    return out


def laplacian_vec(
    offsets, nbr, pos, period, u, model, wcode, re, pref, n0, gcorr, out, rowsum=_NO_ROWS
):
    """lap(u) of a (n, 2) field into ``out`` (n, 2); ``rowsum`` as in :func:`laplacian_field`."""
    return laplacian_field(
        offsets, nbr, pos, period, u, model, wcode, re, pref, n0, gcorr, out, rowsum, _ALL_ROWS
    )


def laplacian_abs_rowsum(offsets, nbr, pos, period, model, wcode, re, pref, out):
    """sum_j |c_ij| per particle: the off-diagonal row sum of |L| into ``out`` (n,).

    The diagonal of L is minus the row sum of c, so the Gershgorin bound of the spectral radius
    is twice this when every c >= 0 (as the reference solver's stable_dt uses it).  The xu-jin
    gradient correction is not included.  (The same numbers come free from
    :func:`laplacian_vec` with a ``rowsum`` array.)
    """
    n = offsets.shape[0] - 1
    zero = np.zeros((n, 1))
    laplacian_field(
        offsets, nbr, pos, period, zero, model, wcode, re, pref, 1.0, False, zero.copy(), out,
        _ALL_ROWS,
    )
    return out


# ---------------------------------------------------------------- collision, stabilization


@kernel
def collision(offsets, nbr, pos, period, vel, kind, distance, restitution, wall_share, out):
    """Velocity increments of the Lee et al. (2011) collision model (docs/method.md section 4).

    For a fluid particle i and a neighbour j closer than ``distance`` (alpha_c l0) that
    approaches it, (u_i - u_j) . r_ij > 0 with r_ij = r_j - r_i:
    du_i = -(1 + e) s_ij [(u_i - u_j) . r_ij / r_ij^2] r_ij, with s_ij = m_j/(m_i + m_j) = 1/2
    for a fluid j and ``wall_share`` for a boundary j (1.0: infinitely heavy wall, the
    reference backend's choice; 0.5: equal masses).  All pairs use the input velocities
    (Jacobi update, order independent).  Non-fluid rows get 0.  out (n, 2).
    """
    n = offsets.shape[0] - 1
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    reject = distance * distance * (1.0 + 1e-9)  # beyond this r2, r < distance is impossible
    for i in prange(n):
        ax = 0.0
        ay = 0.0
        if kind[i] == FLUID:
            xi = pos[i, 0]
            yi = pos[i, 1]
            ui = vel[i, 0]
            vi = vel[i, 1]
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                dx, dy, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
                if r2 > reject or r2 == 0.0 or not np.sqrt(r2) < distance:
                    continue  # nearly every pair: the branch predicts well
                approach = (ui - vel[j, 0]) * dx + (vi - vel[j, 1]) * dy
                if approach > 0.0:
                    share = 0.5 if kind[j] == FLUID else wall_share
                    c = share * ((1.0 + restitution) * approach / r2)
                    ax -= c * dx
                    ay -= c * dy
        out[i, 0] = ax
        out[i, 1] = ay
    return out


@kernel
def stabilization(
    offsets, nbr, pos, period, vel, kind, inner, with_walls, wcode, re, n0, l0, alpha_s, out
):
    """Velocity increments of the stabilization (docs/method.md section 5).

    du_i = -(alpha_s l0 / n0) sum_j W'_ij (u_j - u_i) for particles with ``inner`` set (fluid,
    not free surface), 0 elsewhere.  ``with_walls``: boundary particles are neighbours in the
    sum (their ``vel`` is the wall velocity); otherwise only fluid neighbours count.  out (n, 2).
    """
    n = offsets.shape[0] - 1
    f = -alpha_s * l0 / n0
    px = period[0]
    py = period[1]
    hx = half_width(px)
    hy = half_width(py)
    inv_re = 1.0 / re
    re_s = re * SUPPORT
    for i in prange(n):
        s0 = 0.0
        s1 = 0.0
        if inner[i]:
            xi = pos[i, 0]
            yi = pos[i, 1]
            ui = vel[i, 0]
            vi = vel[i, 1]
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                if not with_walls and kind[j] != FLUID:
                    continue
                _, _, r2 = _sep(pos, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                dw = _dw_in(wcode, min(r, re), re, inv_re)
                dw = dw if _inside(r, r2, re_s) else 0.0
                s0 += dw * (vel[j, 0] - ui)
                s1 += dw * (vel[j, 1] - vi)
        out[i, 0] = f * s0
        out[i, 1] = f * s1
    return out


__all__ = [
    "GRADIENT_CODES",
    "LAPLACIAN_CODES",
    "WEIGHT_CODES",
    "collision",
    "d2weight",
    "divergence",
    "dweight",
    "gradient",
    "lap_coef",
    "laplacian",
    "laplacian_abs_rowsum",
    "laplacian_code",
    "laplacian_field",
    "laplacian_prefactor",
    "laplacian_vec",
    "neighbour_min",
    "number_density",
    "pgm1",
    "pgm2",
    "pgm3",
    "pressure_gradient",
    "stabilization",
    "weight",
    "weight_code",
]
