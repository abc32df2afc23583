"""Row kernels over a CSR neighbour list (both directions of every pair), one factory each.

Every kernel loops over particles in parallel (``prange``); particle ``i`` only reads its own
row ``nbr[offsets[i]:offsets[i + 1]]`` and writes ``out[i]``, so there are no write conflicts
and the result does not depend on the number of threads.  Separations ``dx = r_j - r_i``
(minimum image through ``period``, see :mod:`.cells`) and ``r = |dx|`` are recomputed from the
positions in each kernel; weights are zero beyond the kernel's own ``re``, so one list built at
``r_max + skin`` serves every radius.

A kernel is made by a factory (:func:`._jit.factory`) from the compiled models it needs
(:mod:`.formulas`: a weight, a Laplacian, a pressure gradient), e.g.
``number_density(models.weight)(offsets, nbr, pos, period, re, out)``; the models' formulas are
those of :mod:`mpsbench.physics` (docs/method.md sections 2-5, D_s = 2), so the kernels agree with
the numpy operators to rounding (per-particle summation order differs).  Factories here:
:func:`pair_sum` (sum_j of a pair formula: the number density, a Laplacian's moment),
:func:`number_density`, :func:`gradient`, :func:`divergence`, :func:`neighbour_min`,
:func:`pressure_gradient`, :func:`laplacian_field`, :func:`stabilization`; :func:`collision`
needs no model.

Conventions: ``offsets, nbr, pos, period`` come first (:mod:`.cells`); ``out`` arrays are passed
in (no allocation in the hot path) and also returned; ``mask`` arguments are boolean
per-particle arrays: a particle whose mask is false neither receives nor contributes (the
reference backend leaves dummy particles out of the pressure gradient this way); ``kind`` is
the int8 :class:`mpsbench.physics.particles.Kind` array (0 = fluid).  Units follow the inputs.

Inner loops are branch-free where it pays: every term is computed and then selected with
:func:`.formulas.inside` (0 < r <= re (1 + SUPPORT_RTOL), the reference's own test), which avoids
mispredicted branches on the ragged edge of the support (measured ~20% faster than skipping).  A
selected 0.0 adds nothing, so results equal the skipping form bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange

from . import formulas as fm
from ._jit import factory, kernel
from .formulas import FLUID, RADIAL, SUPPORT, inside
from .geometry import half_width, min_image

NO_MOMENT = np.zeros(0)
"""The moment array a Laplacian without a moment is given (never read)."""


@njit(inline="always")
def sep(pos, j, xi, yi, px, py, hx, hy):
    """(dx, dy, r^2) from particle (xi, yi) to particle j, minimum image."""
    dx = min_image(pos[j, 0] - xi, px, hx)
    dy = min_image(pos[j, 1] - yi, py, hy)
    return dx, dy, dx * dx + dy * dy


# --------------------------------------------------------------------------- sums of a pair term


@factory
def pair_sum(wt: fm.Weight, formula: Any) -> Any:
    """out_i = sum_j formula(r_ij, W, W', W'') over the support of ``re``."""
    term = fm.pair_of(wt, formula)

    def pair_sum(offsets, nbr, pos, period, re, out):
        n = offsets.shape[0] - 1
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        re_s = re * SUPPORT
        for i in prange(n):
            xi = pos[i, 0]
            yi = pos[i, 1]
            s = 0.0
            for k in range(offsets[i], offsets[i + 1]):
                _, _, r2 = sep(pos, nbr[k], xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                v = term(r, re)
                s += v if inside(r, r2, re_s) else 0.0
            out[i] = s
        return out

    return pair_sum


def number_density(wt: fm.Weight) -> Any:
    """n_i = sum_j W_ij: ``(offsets, nbr, pos, period, re, out)``."""
    return pair_sum(wt, fm.W_ONLY)


def moments(wt: fm.Weight, lap: fm.Laplacian) -> Any:
    """S_i = sum_j moment(r_ij, ...) of a Laplacian with a moment (the kernel of
    :func:`pair_sum`)."""
    return pair_sum(wt, lap.moment)


# --------------------------------------------------------------------------- gradients


@factory
def gradient(wt: fm.Weight) -> Any:
    """Original gradient (Eq. 5): (D/n0) sum_j (phi_j - phi_i) r_ij W_ij / r_ij^2; out (n, 2).
    Arguments ``(offsets, nbr, pos, period, phi, re, factor, out)``, factor = D / n0."""
    w_of = fm.number_density_pair(wt)

    def gradient(offsets, nbr, pos, period, phi, re, factor, out):
        n = offsets.shape[0] - 1
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        re_s = re * SUPPORT
        for i in prange(n):
            xi = pos[i, 0]
            yi = pos[i, 1]
            phii = phi[i]
            gx = 0.0
            gy = 0.0
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                dx, dy, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                q = RADIAL(r, w_of(r, re))
                q = q if inside(r, r2, re_s) else 0.0
                c = (phi[j] - phii) * q
                gx += c * dx
                gy += c * dy
            out[i, 0] = factor * gx
            out[i, 1] = factor * gy
        return out

    return gradient


@factory
def divergence(wt: fm.Weight) -> Any:
    """(D/n0) sum_j (u_j - u_i) . r_ij W_ij / r_ij^2 of a (n, 2) field ``u``:
    ``(offsets, nbr, pos, period, u, re, factor, out)``, factor = D / n0."""
    w_of = fm.number_density_pair(wt)

    def divergence(offsets, nbr, pos, period, u, re, factor, out):
        n = offsets.shape[0] - 1
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        re_s = re * SUPPORT
        for i in prange(n):
            xi = pos[i, 0]
            yi = pos[i, 1]
            ui = u[i, 0]
            vi = u[i, 1]
            s = 0.0
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                dx, dy, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                q = RADIAL(r, w_of(r, re))
                q = q if inside(r, r2, re_s) else 0.0
                s += ((u[j, 0] - ui) * dx + (u[j, 1] - vi) * dy) * q
            out[i] = factor * s
        return out

    return divergence


def positive_weight(wt: fm.Weight) -> Any:
    """``(r2, re) -> W_ij > 0`` for a pair within the list: true well inside the support, and
    W itself is evaluated only where r ~ re (most pairs never need it)."""
    w = wt.w

    @njit(inline="always")
    def positive(r2, re):
        if r2 == 0.0 or r2 > re * re * (1.0 + 1e-9):
            return False
        if r2 < re * re * (1.0 - 1e-9):
            return True
        r = np.sqrt(r2)
        return r <= re and w(r, re) > 0.0

    return positive


@factory
def neighbour_min(wt: fm.Weight) -> Any:
    """p_min,i = min(p_i, p_j over neighbours with W_ij > 0 and mask_j); masked-out i: p_i.
    Arguments ``(offsets, nbr, pos, period, p, mask, re, out)``."""
    positive = positive_weight(wt)

    def neighbour_min(offsets, nbr, pos, period, p, mask, re, out):
        n = offsets.shape[0] - 1
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(n):
            m = p[i]
            if mask[i]:
                xi = pos[i, 0]
                yi = pos[i, 1]
                for k in range(offsets[i], offsets[i + 1]):
                    j = nbr[k]
                    pj = p[j]
                    if not mask[j] or pj >= m:  # most neighbours stop here: no geometry needed
                        continue
                    _, _, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
                    if positive(r2, re):
                        m = pj
            out[i] = m
        return out

    return neighbour_min


@factory
def pressure_gradient(wt: fm.Weight, grad: fm.Gradient) -> Any:
    """A pressure-gradient model of ``p``: prefactor sum_j P_ij r_ij radial(r_ij, W_ij) over
    neighbours with ``mask`` set; out (n, 2).

    Arguments ``(offsets, nbr, pos, period, p, pmin, mask, re, factor, out, rows)``: ``pmin``
    from :func:`neighbour_min` (same mask, weight and re) when the model uses it (else any (n,)
    array), ``factor`` = the model's prefactor(n0); masked-out rows get 0.  ``rows``: a boolean
    array of the rows wanted (the others get 0; a solver needs fluid rows only), or an empty one
    for all.
    """
    w_of = fm.number_density_pair(wt)
    pair = grad.pair
    radial = grad.radial

    def pressure_gradient(
        offsets, nbr, pos, period, p, pmin, mask, re, factor, out, rows
    ):
        n = offsets.shape[0] - 1
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        re_s = re * SUPPORT
        some = rows.shape[0] > 0
        for i in prange(n):
            gx = 0.0
            gy = 0.0
            if mask[i] and (not some or rows[i]):
                xi = pos[i, 0]
                yi = pos[i, 1]
                pi = p[i]
                pmi = pmin[i]
                for k in range(offsets[i], offsets[i + 1]):
                    j = nbr[k]
                    if not mask[j]:
                        continue
                    dx, dy, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
                    r = np.sqrt(r2)
                    q = radial(r, w_of(r, re))
                    q = q if inside(r, r2, re_s) else 0.0
                    c = pair(pi, p[j], pmi, pmin[j]) * q
                    gx += c * dx
                    gy += c * dy
            out[i, 0] = factor * gx
            out[i, 1] = factor * gy
        return out

    return pressure_gradient


# --------------------------------------------------------------------------- Laplacians


@factory
def laplacian_field(wt: fm.Weight, lap: fm.Laplacian) -> Any:
    """The Laplacian of each column of ``phi`` (n, k), k = 1 or 2; out (n, k).

    Arguments ``(offsets, nbr, pos, period, phi, re, pref, s, gfactor, gcorr, out, rowsum,
    rows)``: lap(phi)_i = sum_j c_ij (phi_j - phi_i) [- B_i . grad(phi)_i], c_ij = ``pref`` *
    the model's pair formula (``pref`` = its prefactor(n0, lam); ``s`` the moments S of
    :func:`moments` for a model with a moment, else :data:`NO_MOMENT`).  With ``gcorr`` (the
    xu-jin gradient correction) B_i = sum_j c_ij r_ij and grad is the original gradient
    ``gfactor`` sum phi_ij r_ij W / r^2 at the same ``re`` (gfactor = D / n0).  ``rowsum``: an
    (n,) array that receives sum_j |c_ij| (fused: the stable time step comes with the viscous
    term), or an empty array.  ``rows``: a boolean array of the rows wanted (the others get 0),
    or an empty one for all.
    """
    coef = fm.laplacian_pair(wt, lap)
    w_of = fm.number_density_pair(wt)

    def laplacian_field(
        offsets, nbr, pos, period, phi, re, pref, s, gfactor, gcorr, out, rowsum, rows
    ):
        n = offsets.shape[0] - 1
        two = phi.shape[1] == 2
        want_rows = rowsum.shape[0] > 0
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
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
                dx, dy, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                ins = inside(r, r2, re_s)
                c = pref * coef(r, re, s, i, j)
                c = c if ins else 0.0
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
                    q = RADIAL(r, w_of(r, re))
                    q = q if ins else 0.0
                    g0x += d0 * q * dx
                    g0y += d0 * q * dy
                    if two:
                        g1x += d1 * q * dx
                        g1y += d1 * q * dy
            if gcorr:
                s0 -= bx * (gfactor * g0x) + by * (gfactor * g0y)
                s1 -= bx * (gfactor * g1x) + by * (gfactor * g1y)
            out[i, 0] = s0
            if two:
                out[i, 1] = s1
            if want_rows:
                rowsum[i] = sa
        return out

    return laplacian_field


# ---------------------------------------------------------------- collision, stabilization


@kernel
def collision(
    offsets, nbr, pos, period, vel, kind, distance, restitution, wall_share, out
):
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
                dx, dy, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
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


@factory
def stabilization(wt: fm.Weight) -> Any:
    """Velocity increments of the stabilization (docs/method.md section 5, the pair weight and
    prefactor of :class:`mpsbench.physics.operators.Stabilization`).

    Arguments ``(offsets, nbr, pos, period, vel, kind, inner, with_walls, re, factor, out)``:
    du_i = factor sum_j pair_ij (u_j - u_i) for particles with ``inner`` set (fluid, not free
    surface), 0 elsewhere; ``factor`` = -alpha_s l0 / n0.  ``with_walls``: boundary particles
    are neighbours in the sum (their ``vel`` is the wall velocity); otherwise only fluid
    neighbours count.  out (n, 2).
    """
    term = fm.stabilization_pair(wt)

    def stabilization(
        offsets, nbr, pos, period, vel, kind, inner, with_walls, re, factor, out
    ):
        n = offsets.shape[0] - 1
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
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
                    _, _, r2 = sep(pos, j, xi, yi, px, py, hx, hy)
                    r = np.sqrt(r2)
                    dw = term(r, re)
                    dw = dw if inside(r, r2, re_s) else 0.0
                    s0 += dw * (vel[j, 0] - ui)
                    s1 += dw * (vel[j, 1] - vi)
            out[i, 0] = factor * s0
            out[i, 1] = factor * s1
        return out

    return stabilization


__all__ = [
    "NO_MOMENT",
    "collision",
    "divergence",
    "gradient",
    "laplacian_field",
    "moments",
    "neighbour_min",
    "number_density",
    "pair_sum",
    "pressure_gradient",
    "positive_weight",
    "sep",
    "stabilization",
]
