"""The WC-MPS step as fused row passes: each neighbour sum with the per-particle updates that
follow it.

A step of :class:`mpsbench.run.scheme.SchemeSolver` has one pass over the neighbour lists per
sum that needs the previous one complete everywhere (the pressure needs every number density,
the gradient every pressure, the stabilization every corrected velocity); what only needs a
particle's own sum is done at the end of its row, in the same kernel:

=======================  ==============================================================
:func:`predict`          Laplacian of u (+ its row sum of |c_ij|), u* = u + dt (nu lap + g),
                         r* = r + dt u*, the displacement since the list was built
:func:`density_pressure` number density at r*, equation of state, free surface
:func:`correct`          [p_min], pressure gradient, du = -dt/rho0 grad p, u += du (without
                         collision; p_min in the same row when the model reads p_min of
                         particle i only, as PGM1 does)
:func:`collide`          collision increments at u + du, du += them, u += du
:func:`move`             stabilization at r*, r += dt du, u += the stabilization, the
                         displacement and max |u| (the next time step's)
:func:`shift`            (with particle shifting) the shift at the moved positions,
                         u += (grad u) . dr, r += dr, the displacement and max |u|
=======================  ==============================================================

Every row is computed by its own particle ("owner computes", rows of a full list): no two
threads write the same element, no per-thread accumulator is zeroed or added up, and a row
that is not needed (a boundary row of the Laplacian or the gradient) costs nothing.  A pass
whose rows read what it updates (positions, velocities) writes the new values into a second
buffer (``X2``, ``V2``) that the caller swaps in.

Rows are visited in blocks (:class:`Schedule`): ``prange`` hands each thread a contiguous
range of block numbers, and block numbers are bit-reversed, so each thread gets blocks from
all over the (space-filling-curve sorted) particles and the fluid rows, the expensive ones, are
shared evenly.  Maxima (row sums, displacement, speed) are taken per block into ``partial``
and combined by the caller: the results do not depend on the number of threads.

Positions and velocities are (2, n) arrays (``X[0]`` is x): contiguous coordinates make the
gathers of the inner loops vector loads (1.2-1.7x on the pair loops, measured).  Kernels are
made per compiled models and per ``periodic`` (:mod:`.kernels`), lazily: a run compiles only
the passes its physics uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit, prange

from . import formulas as fm
from ._jit import factory
from .formulas import FLUID
from .geometry import half_width
from .kernels import (
    collision_row,
    density_row,
    gradient_row,
    laplacian_row,
    pmin_row,
    row_function,
    separation,
    shifting_row,
    stabilization_row,
)
from .steps import integer_gamma, state_of


@njit(inline="always")
def nan_max(m, v):
    """max(m, v) where a NaN ``v`` wins (a block maximum must show a NaN row)."""
    return v if v > m or v != v else m


@row_function
def store_row(periodic: bool) -> Any:
    """Row i's new position and velocity into ``X2``, ``V2``, returning its squared
    displacement from ``Xref`` (minimum image): ``(X2, V2, Xref, i, xn, yn, ui, vi, px, py,
    hx, hy) -> d2``; the tail of every pass that moves particles."""
    sep = separation(periodic)

    def store_row(X2, V2, Xref, i, xn, yn, ui, vi, px, py, hx, hy):
        X2[0, i] = xn
        X2[1, i] = yn
        V2[0, i] = ui
        V2[1, i] = vi
        _, _, d2 = sep(Xref[0], Xref[1], i, xn, yn, px, py, hx, hy)
        return d2

    return store_row


PMIN_NONE = 0  # the gradient model does not read p_min
PMIN_ROW = 1  # it reads p_min of particle i only: computed in the gradient's own row
PMIN_TABLE = 2  # it reads p_min of the neighbours too: a pass of its own first (pmin_all)

ROWS_PER_BLOCK = 192


@dataclass(frozen=True)
class Schedule:
    """Row blocks for ``n`` particles: ``order[t]`` is the t-th block handed out (bit-reversed
    numbering), rows ``bounds[b]:bounds[b + 1]`` make block b.  The block count depends on n
    only (a power of two, about :data:`ROWS_PER_BLOCK` rows each), never on the threads."""

    n: int
    order: np.ndarray
    bounds: np.ndarray

    @classmethod
    def of(cls, n: int) -> Schedule:
        bits = 0
        while (1 << bits) * ROWS_PER_BLOCK < n and bits < 12:
            bits += 1
        nb = 1 << bits
        order = np.zeros(nb, np.int64)
        for t in range(nb):
            order[t] = int(format(t, f"0{bits}b")[::-1], 2) if bits else 0
        bounds = (np.arange(nb + 1, dtype=np.int64) * n) // nb
        return cls(n, order, bounds)

    @property
    def blocks(self) -> int:
        return len(self.order)


def combine_max(partial: np.ndarray) -> np.ndarray:
    """Column maxima of a (blocks, k) ``partial`` (NaN wins, as in the reference's max)."""
    return np.asarray(partial.max(axis=0)) if len(partial) else np.zeros(partial.shape[1])


# --------------------------------------------------------------------------- 1-2: predictor


@factory
def predict(wt: fm.Weight, lap: fm.Laplacian, periodic: bool) -> Any:
    """Viscosity and gravity on fluid, every particle moved (the scheme's steps 1-2).

    Arguments ``(offsets, nbr, X, V, U, period, re, pref, s, gfactor, gcorr, viscous, nu, gx,
    gy, dt, kind, Xref, X2, V2, order, bounds, partial)``: ``U`` the velocities the Laplacian
    reads (``V``, or with mirrored walls the boundary rows replaced), the Laplacian's
    arguments as :func:`.kernels.laplacian_row`; fluid rows: u* = u + dt (nu lap(u) + g),
    other rows keep u; r* = r + dt u* into ``X2``, ``V2``.  ``partial[b]``: (max over the
    block's fluid rows of sum_j |c_ij|, max |r* - Xref|^2 under the minimum image).  With
    ``viscous`` false no neighbour is visited and the row sums are 0.
    """
    row = laplacian_row(wt, lap, periodic)
    store = store_row(periodic)

    def predict(offsets, nbr, X, V, U, period, re, pref, s, gfactor, gcorr, viscous, nu, gx, gy,
                dt, kind, Xref, X2, V2, order, bounds, partial):
        x = X[0]
        y = X[1]
        u = U[0]
        v = U[1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for t in prange(order.shape[0]):
            b = order[t]
            rows = 0.0
            disp = 0.0
            for i in range(bounds[b], bounds[b + 1]):
                ui = V[0, i]
                vi = V[1, i]
                if kind[i] == FLUID:
                    ax = 0.0
                    ay = 0.0
                    if viscous:
                        l0, l1, sa = row(offsets, nbr, x, y, u, v, i, px, py, hx, hy, re, pref, s,
                                         gfactor, gcorr)
                        ax = nu * l0
                        ay = nu * l1
                        rows = nan_max(rows, sa)
                    ui += dt * (ax + gx)
                    vi += dt * (ay + gy)
                d2 = store(X2, V2, Xref, i, x[i] + dt * ui, y[i] + dt * vi, ui, vi, px, py,
                           hx, hy)
                disp = nan_max(disp, d2)
            partial[b, 0] = rows
            partial[b, 1] = disp

    return predict


# --------------------------------------------------------------------------- 3: number density


@factory
def density_pressure(wt: fm.Weight, periodic: bool) -> Any:
    """Number density, equation of state and free surface (the scheme's step 3), every row.

    Arguments ``(offsets, nbr, X, period, re, static_n, kind, n0, tait, prefactor, gamma, clip,
    beta, with_eos, n_out, p_out, surface, inner, order, bounds)``: n_i = sum_j W_ij +
    static_n_i; with ``with_eos`` the pressure, surface and inner flags as
    :func:`.steps.state_of` (without: only ``n_out``).
    """
    row = density_row(wt, periodic)

    def density_pressure(offsets, nbr, X, period, re, static_n, kind, n0, tait, prefactor, gamma,
                         clip, beta, with_eos, n_out, p_out, surface, inner, order, bounds):
        x = X[0]
        y = X[1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        threshold = beta * n0
        igamma = integer_gamma(gamma)
        for t in prange(order.shape[0]):
            b = order[t]
            for i in range(bounds[b], bounds[b + 1]):
                ni = row(offsets, nbr, x, y, i, px, py, hx, hy, re) + static_n[i]
                if with_eos:
                    state_of(i, ni, kind, n0, tait, prefactor, gamma, igamma, clip, threshold,
                             n_out, p_out, surface, inner)
                else:
                    n_out[i] = ni

    return density_pressure


# --------------------------------------------------------------------------- 4: corrector


@factory
def pmin_all(wt: fm.Weight, periodic: bool) -> Any:
    """p_min of every row whose ``mask`` is set (others: p_i), for a gradient model that reads
    the neighbours' p_min: ``(offsets, nbr, X, period, p, mask, re, out, order, bounds)``."""
    row = pmin_row(wt, periodic)

    def pmin_all(offsets, nbr, X, period, p, mask, re, out, order, bounds):
        x = X[0]
        y = X[1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for t in prange(order.shape[0]):
            b = order[t]
            for i in range(bounds[b], bounds[b + 1]):
                out[i] = row(offsets, nbr, x, y, p, mask, i, px, py, hx, hy, re) if mask[i] \
                    else p[i]

    return pmin_all


@factory
def correct(wt: fm.Weight, grad: fm.Gradient, periodic: bool, pmin_mode: int) -> Any:
    """The pressure increment of fluid particles (the scheme's step 4) and, without a collision
    pass, the velocity update.

    Arguments ``(offsets, nbr, X, period, p, pmin, no_dummy, re, factor0, factor, kind, V, DU,
    W, collision, order, bounds)``: fluid rows du = factor (factor0 sum_j P_ij r_ij radial)
    (factor0 the model's prefactor, factor = -dt / rho0: the reference's order of the
    products) over neighbours with ``no_dummy`` set, other rows du = 0, into ``DU``; then
    u += du in ``V``, or with ``collision`` the velocity the collision pass reads, u + du, into
    ``W`` (``V`` is then left alone).  ``pmin``: the table of :func:`pmin_all` (``pmin_mode``
    PMIN_TABLE), or any (n,) array; with PMIN_ROW p_min of row i is found first in the same
    row.
    """
    grow = gradient_row(wt, grad, periodic)
    mrow = pmin_row(wt, periodic)

    def correct(offsets, nbr, X, period, p, pmin, no_dummy, re, factor0, factor, kind, V, DU, W,
                collision, order, bounds):
        x = X[0]
        y = X[1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for t in prange(order.shape[0]):
            b = order[t]
            for i in range(bounds[b], bounds[b + 1]):
                du0 = 0.0
                du1 = 0.0
                if kind[i] == FLUID:
                    if pmin_mode == PMIN_ROW:
                        pmi = mrow(offsets, nbr, x, y, p, no_dummy, i, px, py, hx, hy, re)
                    elif pmin_mode == PMIN_TABLE:
                        pmi = pmin[i]
                    else:
                        pmi = p[i]
                    g0, g1 = grow(offsets, nbr, x, y, p, pmin, no_dummy, i, pmi, px, py, hx, hy,
                                  re)
                    du0 = factor * (factor0 * g0)
                    du1 = factor * (factor0 * g1)
                DU[0, i] = du0
                DU[1, i] = du1
                if collision:
                    W[0, i] = V[0, i] + du0
                    W[1, i] = V[1, i] + du1
                else:
                    V[0, i] += du0
                    V[1, i] += du1

    return correct


# --------------------------------------------------------------------------- 5: collision


@factory
def collide(periodic: bool) -> Any:
    """Collision increments (the scheme's step 5) of fluid particles at ``W`` = u + du, added
    to du, then u += du: ``(offsets, nbr, X, period, W, kind, distance, restitution,
    wall_share, V, DU, order, bounds)`` (see :func:`.kernels.collision_row`)."""
    row = collision_row(periodic)

    def collide(offsets, nbr, X, period, W, kind, distance, restitution, wall_share, V, DU,
                order, bounds):
        x = X[0]
        y = X[1]
        w0 = W[0]
        w1 = W[1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for t in prange(order.shape[0]):
            b = order[t]
            for i in range(bounds[b], bounds[b + 1]):
                if kind[i] == FLUID:
                    ax, ay = row(offsets, nbr, x, y, w0, w1, kind, i, px, py, hx, hy, distance,
                                 restitution, wall_share)
                    DU[0, i] += ax
                    DU[1, i] += ay
                V[0, i] += DU[0, i]
                V[1, i] += DU[1, i]

    return collide


# --------------------------------------------------------------------------- 6: move


@factory
def move(wt: fm.Weight, periodic: bool) -> Any:
    """Stabilization and the move (the scheme's step 6): r += dt du for every particle; with
    ``stabilized`` u += factor sum_j W'_ij (u_j - u_i) at r* for inner rows (fluid, not free
    surface; boundary neighbours count with ``with_walls``).

    Arguments ``(offsets, nbr, X, V, DU, period, kind, inner, with_walls, re, factor,
    stabilized, dt, Xref, X2, V2, order, bounds, partial)``: new positions and velocities into
    ``X2``, ``V2``; ``partial[b]`` = (max |r - Xref|^2 under the minimum image, max |u|^2) over
    the block's rows.
    """
    row = stabilization_row(wt, periodic)
    store = store_row(periodic)

    def move(offsets, nbr, X, V, DU, period, kind, inner, with_walls, re, factor, stabilized,
             dt, Xref, X2, V2, order, bounds, partial):
        x = X[0]
        y = X[1]
        u = V[0]
        v = V[1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for t in prange(order.shape[0]):
            b = order[t]
            disp = 0.0
            speed = 0.0
            for i in range(bounds[b], bounds[b + 1]):
                ui = u[i]
                vi = v[i]
                if stabilized and inner[i]:
                    s0, s1 = row(offsets, nbr, x, y, u, v, kind, i, with_walls, px, py, hx, hy,
                                 re)
                    ui += factor * s0
                    vi += factor * s1
                d2 = store(X2, V2, Xref, i, x[i] + dt * DU[0, i], y[i] + dt * DU[1, i], ui, vi,
                           px, py, hx, hy)
                disp = nan_max(disp, d2)
                speed = nan_max(speed, ui * ui + vi * vi)
            partial[b, 0] = disp
            partial[b, 1] = speed

    return move


# --------------------------------------------------------------------------- 6b: shifting


@factory
def shift(wt: fm.Weight, periodic: bool) -> Any:
    """Particle shifting (the scheme's step 6b, docs/method.md section 5b) for inner fluid
    rows (fluid, ``surface`` false): dr = factor sum_j W'_ij / r_ij r_ij, capped at ``cap``;
    u += gfactor (grad u) . dr; r += dr; every other row is copied.

    Arguments ``(offsets, nbr, X, V, period, kind, surface, re, factor, gfactor, cap, Xref,
    X2, V2, order, bounds, partial)``: new positions and velocities into ``X2``, ``V2``;
    ``partial`` as :func:`move`'s.
    """
    row = shifting_row(wt, periodic)
    store = store_row(periodic)

    def shift(offsets, nbr, X, V, period, kind, surface, re, factor, gfactor, cap, Xref, X2,
              V2, order, bounds, partial):
        x = X[0]
        y = X[1]
        u = V[0]
        v = V[1]
        px = period[0]
        py = period[1]
        hx = half_width(px)
        hy = half_width(py)
        for t in prange(order.shape[0]):
            b = order[t]
            disp = 0.0
            speed = 0.0
            for i in range(bounds[b], bounds[b + 1]):
                xn = x[i]
                yn = y[i]
                ui = u[i]
                vi = v[i]
                if kind[i] == FLUID and not surface[i]:
                    sx, sy, gux, guy, gvx, gvy = row(offsets, nbr, x, y, u, v, i, px, py, hx,
                                                     hy, re)
                    ddx = factor * sx
                    ddy = factor * sy
                    norm = np.sqrt(ddx * ddx + ddy * ddy)
                    if norm > cap:
                        ddx *= cap / norm
                        ddy *= cap / norm
                    ui += gfactor * (gux * ddx + guy * ddy)
                    vi += gfactor * (gvx * ddx + gvy * ddy)
                    xn += ddx
                    yn += ddy
                disp = nan_max(disp, store(X2, V2, Xref, i, xn, yn, ui, vi, px, py, hx, hy))
                speed = nan_max(speed, ui * ui + vi * vi)
            partial[b, 0] = disp
            partial[b, 1] = speed

    return shift


__all__ = [
    "PMIN_NONE",
    "PMIN_ROW",
    "PMIN_TABLE",
    "Schedule",
    "collide",
    "combine_max",
    "correct",
    "density_pressure",
    "move",
    "pmin_all",
    "predict",
    "shift",
]
