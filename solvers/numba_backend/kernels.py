"""Row functions (one particle's neighbour sum of a model) and the operator kernels built on them.

A *row function* computes one particle's sum over its row of a CSR neighbour list (both
directions of every pair, :mod:`.cells`): ``sum_j term(r_ij, ...)`` for the number density,
a Laplacian's pair coefficients, p_min, a pressure gradient, the collision and the
stabilization increments.  Each is made once per distinct models by a factory
(:func:`row_function`) that closes over the models' compiled formulas (:mod:`.formulas`), so
every registered model, a plugin's too, runs here through its own formulas; nothing in a row
names a model.  The same row functions serve two kinds of kernels:

* the step's fused kernels (:mod:`.fused`): positions and velocities as (2, n) arrays whose rows
  ``x = X[0]``, ``y = X[1]`` are contiguous, each row's sum followed by its per-particle update;
* the operator kernels below, ``number_density(wt)(offsets, nbr, pos, period, re, out)`` and
  the like, on (n, 2) arrays: the compiled operators of :mod:`mpsbench.physics.operators`, used
  by the diffusion set-up and held against the numpy operators by tests/test_numba_kernels.py.

A row function is inlined into the kernel that calls it (numba IR inlining), so it is compiled
with the kernel's floating-point flags (:mod:`._jit`).  ``periodic`` (a factory argument, so a
constant of the compiled code): separations take the minimum image (:mod:`.geometry`, the same
bits as ``Box.minimum_image``); without it the plain difference, which is what a box without
periodic axes gives, and the inner loops vectorise (the minimum image's branches would keep
them scalar).

Conventions: ``offsets, nbr`` a CSR list, ``x, y`` positions, ``i`` the row; ``period, hx, hy``
the box period and half widths (:func:`.geometry.half_width`); weights are zero beyond the
kernel's own ``re`` (``re_s = re * SUPPORT``: the closed support of :func:`.formulas.inside`),
so one list built at ``r_max + skin`` serves every radius.  ``mask`` arguments are boolean
per-particle arrays: a particle whose mask is false neither receives nor contributes; ``kind``
is the int8 :class:`mpsbench.physics.particles.Kind` array (0 = fluid).

Inner loops are branch-free where it pays: every term is computed and then selected with
:func:`.formulas.inside` (0 < r <= re (1 + SUPPORT_RTOL), the reference's own test), which avoids
mispredicted branches on the ragged edge of the support and lets the loop vectorise.  A selected
0.0 adds nothing, so results equal the skipping form.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit, prange

from . import formulas as fm
from ._jit import factory, kernel
from .formulas import FLUID, RADIAL, SUPPORT, inside
from .geometry import half_width, min_image

NO_MOMENT = np.zeros(0)
"""The moment array a Laplacian without a moment is given (never read)."""

_rows: dict[tuple[Any, ...], Any] = {}


def row_function(build: Callable[..., Any]) -> Callable[..., Any]:
    """A memoised factory of an inlined row function: ``build(*models, periodic)`` returns a
    Python function, compiled once per arguments with ``njit(inline="always")``."""

    def get(*args: Any) -> Any:
        key = (build.__name__, *args)
        if key not in _rows:
            _rows[key] = njit(inline="always")(build(*args))
        return _rows[key]

    get.__name__ = build.__name__
    get.__qualname__ = build.__qualname__
    get.__doc__ = build.__doc__
    return get


def separation(periodic: bool) -> Any:
    """``(x, y, j, xi, yi, px, py, hx, hy) -> (dx, dy, r^2)`` from (xi, yi) to particle j."""
    return _minimum_image_sep if periodic else _plain_sep


@njit(inline="always")
def _minimum_image_sep(x, y, j, xi, yi, px, py, hx, hy):
    dx = min_image(x[j] - xi, px, hx)
    dy = min_image(y[j] - yi, py, hy)
    return dx, dy, dx * dx + dy * dy


@njit(inline="always")
def _plain_sep(x, y, j, xi, yi, px, py, hx, hy):
    dx = x[j] - xi
    dy = y[j] - yi
    return dx, dy, dx * dx + dy * dy


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


# --------------------------------------------------------------------------- row functions


@row_function
def pair_sum_row(wt: fm.Weight, formula: Any, periodic: bool) -> Any:
    """sum_j formula(r_ij, W, W', W''): ``(offsets, nbr, x, y, i, px, py, hx, hy, re) -> s``."""
    term = fm.pair_of(wt, formula)
    sep = separation(periodic)

    def pair_sum_row(offsets, nbr, x, y, i, px, py, hx, hy, re):
        re_s = re * SUPPORT
        xi = x[i]
        yi = y[i]
        s = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            _, _, r2 = sep(x, y, nbr[k], xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            v = term(r, re)
            s += v if inside(r, r2, re_s) else 0.0
        return s

    return pair_sum_row


def density_row(wt: fm.Weight, periodic: bool) -> Any:
    """n_i = sum_j W_ij (the row of :func:`pair_sum_row` for W)."""
    return pair_sum_row(wt, fm.W_ONLY, periodic)


@row_function
def laplacian_row(wt: fm.Weight, lap: fm.Laplacian, periodic: bool) -> Any:
    """A Laplacian of a 2-vector field (u, v) at particle i and its row sum of |c_ij|:
    ``(offsets, nbr, x, y, u, v, i, px, py, hx, hy, re, pref, s, gfactor, gcorr) -> (lap_u,
    lap_v, sum |c|)``.

    lap(phi)_i = sum_j c_ij (phi_j - phi_i) [- B_i . grad(phi)_i], c_ij = ``pref`` * the model's
    pair formula (``pref`` = its prefactor(n0, lam); ``s`` the moments S of a model with a
    moment, else :data:`NO_MOMENT`).  With ``gcorr`` (the xu-jin gradient correction) B_i =
    sum_j c_ij r_ij and grad is the original gradient ``gfactor`` sum phi_ij r_ij W / r^2 at the
    same ``re`` (gfactor = D / n0).
    """
    coef = fm.laplacian_pair(wt, lap)
    w_of = fm.number_density_pair(wt)
    sep = separation(periodic)

    def laplacian_row(offsets, nbr, x, y, u, v, i, px, py, hx, hy, re, pref, s, gfactor,
                      gcorr):
        re_s = re * SUPPORT
        xi = x[i]
        yi = y[i]
        ui = u[i]
        vi = v[i]
        s0 = 0.0
        s1 = 0.0
        sa = 0.0
        if not gcorr:
            for k in range(offsets[i], offsets[i + 1]):
                j = nbr[k]
                _, _, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
                r = np.sqrt(r2)
                c = pref * coef(r, re, s, i, j)
                c = c if inside(r, r2, re_s) else 0.0
                s0 += c * (u[j] - ui)
                s1 += c * (v[j] - vi)
                sa += abs(c)
            return s0, s1, sa
        bx = 0.0
        by = 0.0
        g0x = 0.0
        g0y = 0.0
        g1x = 0.0
        g1y = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            ins = inside(r, r2, re_s)
            c = pref * coef(r, re, s, i, j)
            c = c if ins else 0.0
            d0 = u[j] - ui
            d1 = v[j] - vi
            s0 += c * d0
            s1 += c * d1
            sa += abs(c)
            bx += c * dx
            by += c * dy
            q = RADIAL(r, w_of(r, re))
            q = q if ins else 0.0
            g0x += d0 * q * dx
            g0y += d0 * q * dy
            g1x += d1 * q * dx
            g1y += d1 * q * dy
        s0 -= bx * (gfactor * g0x) + by * (gfactor * g0y)
        s1 -= bx * (gfactor * g1x) + by * (gfactor * g1y)
        return s0, s1, sa

    return laplacian_row


@row_function
def pmin_row(wt: fm.Weight, periodic: bool) -> Any:
    """p_min,i = min(p_i, p_j over neighbours with W_ij > 0 and mask_j) (call it for masked-in
    rows): ``(offsets, nbr, x, y, p, mask, i, px, py, hx, hy, re) -> p_min``."""
    positive = positive_weight(wt)
    sep = separation(periodic)

    def pmin_row(offsets, nbr, x, y, p, mask, i, px, py, hx, hy, re):
        m = p[i]
        xi = x[i]
        yi = y[i]
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            pj = p[j]
            if not mask[j] or pj >= m:  # most neighbours stop here: no geometry needed
                continue
            _, _, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            if positive(r2, re):
                m = pj
        return m

    return pmin_row


@row_function
def gradient_row(wt: fm.Weight, grad: fm.Gradient, periodic: bool) -> Any:
    """A pressure-gradient model's sum_j P_ij r_ij radial(r_ij, W_ij) over neighbours with
    ``mask`` set, without the prefactor: ``(offsets, nbr, x, y, p, pmin, mask, i, pmi, px, py,
    hx, hy, re) -> (gx, gy)``; ``pmi`` is p_min of row i (``pmin`` of the neighbours is read
    only when the model's pair formula does)."""
    w_of = fm.number_density_pair(wt)
    pair = grad.pair
    radial = grad.radial
    sep = separation(periodic)

    def gradient_row(offsets, nbr, x, y, p, pmin, mask, i, pmi, px, py, hx, hy, re):
        re_s = re * SUPPORT
        xi = x[i]
        yi = y[i]
        pi = p[i]
        gx = 0.0
        gy = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            q = radial(r, w_of(r, re))
            q = q if inside(r, r2, re_s) & mask[j] else 0.0
            c = pair(pi, p[j], pmi, pmin[j]) * q
            gx += c * dx
            gy += c * dy
        return gx, gy

    return gradient_row


@row_function
def collision_row(periodic: bool) -> Any:
    """Lee et al. (2011) increments of a fluid particle i: ``(offsets, nbr, x, y, u, v, kind, i,
    px, py, hx, hy, distance, restitution, wall_share) -> (ax, ay)``.

    For a neighbour j closer than ``distance`` (alpha_c l0) that approaches i, (u_i - u_j) .
    r_ij > 0 with r_ij = r_j - r_i: du_i = -(1 + e) s_ij [(u_i - u_j) . r_ij / r_ij^2] r_ij,
    s_ij = m_j/(m_i + m_j) = 1/2 for a fluid j and ``wall_share`` for a boundary j (1.0: an
    infinitely heavy wall, the reference backend's choice).  All pairs use the input
    velocities (Jacobi update, order independent).
    """
    sep = separation(periodic)

    def collision_row(offsets, nbr, x, y, u, v, kind, i, px, py, hx, hy, distance,
                      restitution, wall_share):
        reject = distance * distance * (1.0 + 1e-9)  # beyond this r2, r < distance is impossible
        xi = x[i]
        yi = y[i]
        ui = u[i]
        vi = v[i]
        ax = 0.0
        ay = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            if r2 > reject or r2 == 0.0 or not np.sqrt(r2) < distance:
                continue  # nearly every pair: the branch predicts well
            approach = (ui - u[j]) * dx + (vi - v[j]) * dy
            if approach > 0.0:
                share = 0.5 if kind[j] == FLUID else wall_share
                c = share * ((1.0 + restitution) * approach / r2)
                ax -= c * dx
                ay -= c * dy
        return ax, ay

    return collision_row


@row_function
def stabilization_row(wt: fm.Weight, periodic: bool) -> Any:
    """sum_j pair_ij (u_j - u_i) of the stabilization (its pair weight, W') at particle i:
    ``(offsets, nbr, x, y, u, v, kind, i, with_walls, px, py, hx, hy, re) -> (s0, s1)``;
    without ``with_walls`` only fluid neighbours count."""
    term = fm.stabilization_pair(wt)
    sep = separation(periodic)

    def stabilization_row(offsets, nbr, x, y, u, v, kind, i, with_walls, px, py, hx, hy, re):
        re_s = re * SUPPORT
        xi = x[i]
        yi = y[i]
        ui = u[i]
        vi = v[i]
        s0 = 0.0
        s1 = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            _, _, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            dw = term(r, re)
            use = inside(r, r2, re_s) & (with_walls | (kind[j] == FLUID))
            dw = dw if use else 0.0
            s0 += dw * (u[j] - ui)
            s1 += dw * (v[j] - vi)
        return s0, s1

    return stabilization_row


@row_function
def original_gradient_row(wt: fm.Weight, periodic: bool) -> Any:
    """sum_j (phi_j - phi_i) r_ij W_ij / r_ij^2 (Eq. 5 without D/n0) of a scalar:
    ``(offsets, nbr, x, y, phi, i, px, py, hx, hy, re) -> (gx, gy)``."""
    w_of = fm.number_density_pair(wt)
    sep = separation(periodic)

    def original_gradient_row(offsets, nbr, x, y, phi, i, px, py, hx, hy, re):
        re_s = re * SUPPORT
        xi = x[i]
        yi = y[i]
        phii = phi[i]
        gx = 0.0
        gy = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            q = RADIAL(r, w_of(r, re))
            q = q if inside(r, r2, re_s) else 0.0
            c = (phi[j] - phii) * q
            gx += c * dx
            gy += c * dy
        return gx, gy

    return original_gradient_row


@row_function
def divergence_row(wt: fm.Weight, periodic: bool) -> Any:
    """sum_j (u_j - u_i) . r_ij W_ij / r_ij^2 (without D/n0): ``(offsets, nbr, x, y, u, v, i,
    px, py, hx, hy, re) -> s``."""
    w_of = fm.number_density_pair(wt)
    sep = separation(periodic)

    def divergence_row(offsets, nbr, x, y, u, v, i, px, py, hx, hy, re):
        re_s = re * SUPPORT
        xi = x[i]
        yi = y[i]
        ui = u[i]
        vi = v[i]
        s = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            q = RADIAL(r, w_of(r, re))
            q = q if inside(r, r2, re_s) else 0.0
            s += ((u[j] - ui) * dx + (v[j] - vi) * dy) * q
        return s

    return divergence_row


# --------------------------------------------------------------------------- operator kernels
#
# ``(offsets, nbr, pos, period, ...)`` with pos (n, 2); ``out`` arrays are passed in (no
# allocation in the hot path) and also returned.  Every particle's row in parallel (``prange``):
# row i only writes out[i], so the result does not depend on the number of threads.


@factory
def pair_sum(wt: fm.Weight, formula: Any) -> Any:
    """out_i = sum_j formula(r_ij, W, W', W'') over the support of ``re``:
    ``(offsets, nbr, pos, period, re, out)``."""
    row = pair_sum_row(wt, formula, True)

    def pair_sum(offsets, nbr, pos, period, re, out):
        x = pos[:, 0]
        y = pos[:, 1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(offsets.shape[0] - 1):
            out[i] = row(offsets, nbr, x, y, i, px, py, hx, hy, re)
        return out

    return pair_sum


def number_density(wt: fm.Weight) -> Any:
    """n_i = sum_j W_ij: ``(offsets, nbr, pos, period, re, out)``."""
    return pair_sum(wt, fm.W_ONLY)


def moments(wt: fm.Weight, lap: fm.Laplacian) -> Any:
    """S_i = sum_j moment(r_ij, ...) of a Laplacian with a moment (the kernel of
    :func:`pair_sum`)."""
    return pair_sum(wt, lap.moment)


@factory
def gradient(wt: fm.Weight) -> Any:
    """Original gradient (Eq. 5): (D/n0) sum_j (phi_j - phi_i) r_ij W_ij / r_ij^2; out (n, 2).
    Arguments ``(offsets, nbr, pos, period, phi, re, factor, out)``, factor = D / n0."""
    row = original_gradient_row(wt, True)

    def gradient(offsets, nbr, pos, period, phi, re, factor, out):
        x = pos[:, 0]
        y = pos[:, 1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(offsets.shape[0] - 1):
            gx, gy = row(offsets, nbr, x, y, phi, i, px, py, hx, hy, re)
            out[i, 0] = factor * gx
            out[i, 1] = factor * gy
        return out

    return gradient


@factory
def divergence(wt: fm.Weight) -> Any:
    """(D/n0) sum_j (u_j - u_i) . r_ij W_ij / r_ij^2 of a (n, 2) field ``u``:
    ``(offsets, nbr, pos, period, u, re, factor, out)``, factor = D / n0."""
    row = divergence_row(wt, True)

    def divergence(offsets, nbr, pos, period, u, re, factor, out):
        x = pos[:, 0]
        y = pos[:, 1]
        ux = u[:, 0]
        uy = u[:, 1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(offsets.shape[0] - 1):
            out[i] = factor * row(offsets, nbr, x, y, ux, uy, i, px, py, hx, hy, re)
        return out

    return divergence


@factory
def neighbour_min(wt: fm.Weight) -> Any:
    """p_min,i = min(p_i, p_j over neighbours with W_ij > 0 and mask_j); masked-out i: p_i.
    Arguments ``(offsets, nbr, pos, period, p, mask, re, out)``."""
    row = pmin_row(wt, True)

    def neighbour_min(offsets, nbr, pos, period, p, mask, re, out):
        x = pos[:, 0]
        y = pos[:, 1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(offsets.shape[0] - 1):
            out[i] = row(offsets, nbr, x, y, p, mask, i, px, py, hx, hy, re) if mask[i] else p[i]
        return out

    return neighbour_min


@factory
def pressure_gradient(wt: fm.Weight, grad: fm.Gradient) -> Any:
    """A pressure-gradient model of ``p``: prefactor sum_j P_ij r_ij radial(r_ij, W_ij) over
    neighbours with ``mask`` set; out (n, 2).

    Arguments ``(offsets, nbr, pos, period, p, pmin, mask, re, factor, out, rows)``: ``pmin``
    from :func:`neighbour_min` (same mask, weight and re) when the model uses it (else any (n,)
    array), ``factor`` = the model's prefactor(n0); masked-out rows get 0.  ``rows``: a boolean
    array of the rows wanted (the others get 0), or an empty one for all.
    """
    row = gradient_row(wt, grad, True)

    def pressure_gradient(offsets, nbr, pos, period, p, pmin, mask, re, factor, out, rows):
        x = pos[:, 0]
        y = pos[:, 1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        some = rows.shape[0] > 0
        for i in prange(offsets.shape[0] - 1):
            gx = 0.0
            gy = 0.0
            if mask[i] and (not some or rows[i]):
                gx, gy = row(offsets, nbr, x, y, p, pmin, mask, i, pmin[i], px, py, hx, hy, re)
            out[i, 0] = factor * gx
            out[i, 1] = factor * gy
        return out

    return pressure_gradient


@factory
def laplacian_field(wt: fm.Weight, lap: fm.Laplacian) -> Any:
    """The Laplacian of each column of ``phi`` (n, k), k = 1 or 2; out (n, k).

    Arguments ``(offsets, nbr, pos, period, phi, re, pref, s, gfactor, gcorr, out, rowsum,
    rows)`` as :func:`laplacian_row`; ``rowsum``: an (n,) array that receives sum_j |c_ij|, or
    an empty array; ``rows``: a boolean array of the rows wanted (the others get 0), or an
    empty one for all.
    """
    row = laplacian_row(wt, lap, True)

    def laplacian_field(offsets, nbr, pos, period, phi, re, pref, s, gfactor, gcorr, out,
                        rowsum, rows):
        x = pos[:, 0]
        y = pos[:, 1]
        u = phi[:, 0]
        v = phi[:, 1] if phi.shape[1] == 2 else phi[:, 0]
        two = phi.shape[1] == 2
        want_rows = rowsum.shape[0] > 0
        some = rows.shape[0] > 0
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(offsets.shape[0] - 1):
            s0 = 0.0
            s1 = 0.0
            sa = 0.0
            if not some or rows[i]:
                s0, s1, sa = row(offsets, nbr, x, y, u, v, i, px, py, hx, hy, re, pref, s,
                                 gfactor, gcorr)
            out[i, 0] = s0
            if two:
                out[i, 1] = s1
            if want_rows:
                rowsum[i] = sa
        return out

    return laplacian_field


def _collision() -> Any:
    row = collision_row(True)

    def collision(offsets, nbr, pos, period, vel, kind, distance, restitution, wall_share, out):
        """Velocity increments of the Lee et al. (2011) collision model (:func:`collision_row`)
        of fluid particles (non-fluid rows get 0): ``(offsets, nbr, pos, period, vel, kind,
        distance, restitution, wall_share, out)``, out (n, 2)."""
        x = pos[:, 0]
        y = pos[:, 1]
        u = vel[:, 0]
        v = vel[:, 1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(offsets.shape[0] - 1):
            ax = 0.0
            ay = 0.0
            if kind[i] == FLUID:
                ax, ay = row(offsets, nbr, x, y, u, v, kind, i, px, py, hx, hy, distance,
                             restitution, wall_share)
            out[i, 0] = ax
            out[i, 1] = ay
        return out

    return collision


collision = kernel(_collision())


@row_function
def shifting_row(wt: fm.Weight, periodic: bool) -> Any:
    """The two sums of particle shifting at particle i (docs/method.md section 5b):
    ``(offsets, nbr, x, y, u, v, i, px, py, hx, hy, re) -> (sx, sy, gux, guy, gvx, gvy)``,
    s = sum_j W'_ij / r_ij r_ij and grad u = sum_j (u_j - u_i) r_ij W_ij / r_ij^2 without
    their prefactors, every neighbour within re."""
    term, grad = fm.shifting_pairs(wt)
    sep = separation(periodic)

    def shifting_row(offsets, nbr, x, y, u, v, i, px, py, hx, hy, re):
        re_s = re * SUPPORT
        xi = x[i]
        yi = y[i]
        ui = u[i]
        vi = v[i]
        sx = 0.0
        sy = 0.0
        gux = 0.0
        guy = 0.0
        gvx = 0.0
        gvy = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            dx, dy, r2 = sep(x, y, j, xi, yi, px, py, hx, hy)
            r = np.sqrt(r2)
            use = inside(r, r2, re_s)
            c = term(r, re)
            g = grad(r, re)
            c = c if use else 0.0
            g = g if use else 0.0
            sx += c * dx
            sy += c * dy
            du = (u[j] - ui) * g
            dv = (v[j] - vi) * g
            gux += du * dx
            guy += du * dy
            gvx += dv * dx
            gvy += dv * dy
        return sx, sy, gux, guy, gvx, gvy

    return shifting_row


@factory
def stabilization(wt: fm.Weight) -> Any:
    """Velocity increments of the stabilization (docs/method.md section 5): du_i = factor
    sum_j pair_ij (u_j - u_i) for particles with ``inner`` set (fluid, not free surface), 0
    elsewhere; ``factor`` = -alpha_s l0 / n0.  Arguments ``(offsets, nbr, pos, period, vel,
    kind, inner, with_walls, re, factor, out)``, out (n, 2); see :func:`stabilization_row`."""
    row = stabilization_row(wt, True)

    def stabilization(offsets, nbr, pos, period, vel, kind, inner, with_walls, re, factor, out):
        x = pos[:, 0]
        y = pos[:, 1]
        u = vel[:, 0]
        v = vel[:, 1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for i in prange(offsets.shape[0] - 1):
            s0 = 0.0
            s1 = 0.0
            if inner[i]:
                s0, s1 = row(offsets, nbr, x, y, u, v, kind, i, with_walls, px, py, hx, hy, re)
            out[i, 0] = factor * s0
            out[i, 1] = factor * s1
        return out

    return stabilization


__all__ = [
    "NO_MOMENT",
    "collision",
    "collision_row",
    "density_row",
    "divergence",
    "gradient",
    "gradient_row",
    "laplacian_field",
    "laplacian_row",
    "moments",
    "neighbour_min",
    "number_density",
    "pair_sum",
    "pair_sum_row",
    "pmin_row",
    "positive_weight",
    "pressure_gradient",
    "row_function",
    "separation",
    "shifting_row",
    "stabilization",
    "stabilization_row",
]
