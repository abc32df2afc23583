"""Cell-linked neighbour lists compiled with numba: CSR rows, full or half.

Cells are at least ``cutoff / reach`` wide (``reach`` = 2 by default), so every neighbour of a
particle lies within ``reach`` cells of its own along each axis.  On a periodic axis the grid
covers the period (a stencil that would visit a cell twice is de-duplicated, one that wraps is
split in two); on a free axis it covers the bounding box of the positions (capped at a few cells
per particle: coarser cells stay correct, only slower, if one particle flies far away).
Particles are binned with a stable counting sort; the cells of one stencil row are contiguous in
that order and are scanned as one span.  Separations are those of :mod:`.geometry`.

The CSR list holds both directions of every pair: row ``i`` is
``nbr[offsets[i]:offsets[i + 1]]`` (uint32: unsigned indices spare numba's negative-index
wraparound test on every gather), so per-particle loops run in parallel without write
conflicts; a half list (``half=True``) keeps each pair once.  It stores no geometry by default:
the compute kernels recompute ``dx`` and ``r`` from the positions on the fly, which reads 4
bytes per entry instead of 28 and lets one list built at ``r_max + skin`` serve many steps
(:class:`.neighbour_list.CellNeighbourList`).  :meth:`CSRNeighbours.fill_geometry` fills ``dx``
and ``r`` per entry when they are wanted.

A pair at exactly ``r == cutoff`` (to the last bit) may be in or out of the list depending on
rounding, as in scipy's cKDTree, which decides it in a shifted frame (the skinned list pads its
cut-off for that: :mod:`.neighbour_list`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from mpsbench.physics.particles import Box

from ._jit import compiled, kernel, pick
from .geometry import box_lo, box_period, csr_geometry, half_width, min_image

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# cells are made this much wider than the cut-off so rounding in the binning cannot lose a pair
_SAFETY = 1.0 + 1e-9
_CELLS_PER_PARTICLE = 4


# --------------------------------------------------------------------------- compiled pieces


def _grid(pos: FloatArray, cutoff: float, period: FloatArray, lo: FloatArray, max_cells: int,
          reach: int) -> tuple[FloatArray, FloatArray, IntArray]:
    """Cell grid: origin (2,), cell size (2,), cells per axis (2,); cells >= cutoff / reach.

    Plain Python and numpy: a few operations per axis, once per build (a compiled version cost
    0.3-0.7 s of a cold start, more than all the builds of a run).  NaN coordinates are ignored,
    as the binning ignores them; an infinite extent starts at 2^53 cells and coarsens.
    """
    origin = [0.0, 0.0]
    size = [0.0, 0.0]
    ncell = [1, 1]
    extent = [0.0, 0.0]
    width = cutoff / reach * _SAFETY
    for ax in range(2):
        if period[ax] > 0.0:
            m = max(int(period[ax] / width), 1)
            origin[ax] = float(lo[ax])
            ncell[ax] = m
            size[ax] = float(period[ax]) / m
        else:
            x = pos[:, ax]
            # fmin/fmax skip NaN; all NaN (or no particle) leaves NaN: no finite coordinate
            xmin = float(np.fmin.reduce(x, initial=np.nan))
            xmax = float(np.fmax.reduce(x, initial=np.nan))
            if not xmax >= xmin:
                xmin = xmax = 0.0
            origin[ax] = xmin
            extent[ax] = xmax - xmin
            size[ax] = width
            ncell[ax] = _cells_along(extent[ax], width)
    while ncell[0] * ncell[1] > max_cells:
        ax = 0 if ncell[0] >= ncell[1] else 1
        if ncell[ax] == 1:
            break
        if period[ax] > 0.0:
            ncell[ax] = ncell[ax] // 2
            size[ax] = float(period[ax]) / ncell[ax]
        else:
            size[ax] *= 2.0
            ncell[ax] = _cells_along(extent[ax], size[ax])
    return np.array(origin), np.array(size), np.array(ncell, np.int64)


def _cells_along(extent: float, width: float) -> int:
    """Cells of ``width`` that cover ``extent`` (2^53 for an infinite or NaN one)."""
    cells = extent / width
    return int(cells) + 1 if cells < 2.0**53 else 2**53


@njit(inline="always")
def _coord(x, origin, size, m, periodic):
    f = np.floor((x - origin) / size)
    if periodic:
        if not abs(f) < 1e15:  # NaN or absurd: any cell is correct for the distance test
            return 0
        return int(f) % m
    if not f >= 0.0:
        return 0
    if f >= m:
        return m - 1
    return int(f)


@njit(inline="always")
def _bin(pos, origin, size, ncell, period, cell):
    """Cell id of every particle; ids run along x fastest (``cy * nx + cx``)."""
    n = pos.shape[0]
    px = period[0] > 0.0
    py = period[1] > 0.0
    for i in range(n):
        cx = _coord(pos[i, 0], origin[0], size[0], ncell[0], px)
        cy = _coord(pos[i, 1], origin[1], size[1], ncell[1], py)
        cell[i] = cy * ncell[0] + cx


@njit(inline="always")
def _counting_sort(cell, ncells, start, order):
    """Stable counting sort of particles by cell: ``order`` lists particles cell by cell."""
    n = cell.shape[0]
    start[:] = 0
    for i in range(n):
        start[cell[i] + 1] += 1
    for c in range(ncells):
        start[c + 1] += start[c]
    ptr = start[:-1].copy()
    for i in range(n):
        c = cell[i]
        order[ptr[c]] = i
        ptr[c] += 1


@njit(inline="always")
def _spans(c, m, periodic, reach):
    """Cells c-reach..c+reach along one axis as up to two contiguous spans [a0, b0], [a1, b1].

    Each cell appears once (a periodic axis with at most 2 reach + 1 cells takes the whole
    axis; a stencil that wraps is split in two).  An empty second span has a1 > b1.
    """
    lo = c - reach
    hi = c + reach
    if periodic:
        if m <= 2 * reach + 1:
            return 0, m - 1, 1, 0
        if lo < 0:
            return 0, hi, m + lo, m - 1
        if hi > m - 1:
            return lo, m - 1, 0, hi - m
        return lo, hi, 1, 0
    return max(lo, 0), min(hi, m - 1), 1, 0


@njit(inline="always")
def _bounds(start, cell, ncell, period, reach, order, bound):
    """bound[k]: particles in the stencil cells of particle ``order[k]`` (a row-length bound)."""
    n = order.shape[0]
    nx = ncell[0]
    ny = ncell[1]
    px = period[0] > 0.0
    py = period[1] > 0.0
    for k in range(n):
        c = cell[order[k]]
        cy = c // nx
        cx = c - cy * nx
        xa0, xb0, xa1, xb1 = _spans(cx, nx, px, reach)
        ya0, yb0, ya1, yb1 = _spans(cy, ny, py, reach)
        m = 0
        for ys in range(2):
            ylo = ya0 if ys == 0 else ya1
            yhi = yb0 if ys == 0 else yb1
            for ay in range(ylo, yhi + 1):
                row = ay * nx
                m += start[row + xb0 + 1] - start[row + xa0]
                if xa1 <= xb1:
                    m += start[row + xb1 + 1] - start[row + xa1]
        bound[k] = m


@njit(inline="always")
def _gather_rows(pos, order, out):
    for k in range(order.shape[0]):
        out[k, 0] = pos[order[k], 0]
        out[k, 1] = pos[order[k], 1]


@compiled
def _bin_sort(pos, origin, size, ncell, period, reach, cell, start, order, spos, bound):
    """Bin the particles, sort them by cell, gather their positions in that order and bound
    each row's length: the serial steps of a build before the distance pass, one compiled
    function (each compiled function costs about 0.1 s of a cold start, whatever its size)."""
    _bin(pos, origin, size, ncell, period, cell)
    _counting_sort(cell, start.shape[0] - 1, start, order)
    _gather_rows(pos, order, spos)
    _bounds(start, cell, ncell, period, reach, order, bound)


@kernel
def _scan(
    spos, order, start, cell, ncell, period, reach, cut2, group, loose, half, bstart, buf, counts
):
    """Write the neighbours of every particle into its slice of ``buf`` (one distance pass).

    Particle ``order[k]`` owns ``buf[bstart[k]:bstart[k + 1]]``, long enough for every
    candidate in its stencil, so the write is branch-free (always store, advance when inside).
    Loops run in cell order, so neighbouring cells are hot in cache; the cells of one stencil
    row are contiguous in that order and are scanned as one span.  Static pairs are skipped:
    both ends in the same rigid ``group`` (>= 0), not both ``loose`` (see :func:`build_csr`).
    With ``half`` each pair is kept once, in the row of the end that comes first in cell
    order (candidates before particle ``order[k]`` in that order are not even looked at).
    """
    hx = half_width(period[0])
    hy = half_width(period[1])
    n = spos.shape[0]
    nx = ncell[0]
    ny = ncell[1]
    px = period[0] > 0.0
    py = period[1] > 0.0
    for k in prange(n):
        i = order[k]
        xi = spos[k, 0]
        yi = spos[k, 1]
        gi = group[i]
        li = loose[i]
        c = cell[i]
        cy = c // nx
        cx = c - cy * nx
        xa0, xb0, xa1, xb1 = _spans(cx, nx, px, reach)
        ya0, yb0, ya1, yb1 = _spans(cy, ny, py, reach)
        t0 = bstart[k]
        t = t0
        for ys in range(2):
            ylo = ya0 if ys == 0 else ya1
            yhi = yb0 if ys == 0 else yb1
            for ay in range(ylo, yhi + 1):
                row = ay * nx
                for xs in range(2):
                    xlo = xa0 if xs == 0 else xa1
                    xhi = xb0 if xs == 0 else xb1
                    if xlo > xhi:
                        continue
                    q0 = start[row + xlo]
                    if half and q0 <= k:
                        q0 = k + 1  # each pair once: at the end that comes first in cell order
                    for q in range(q0, start[row + xhi + 1]):
                        dx = min_image(spos[q, 0] - xi, period[0], hx)
                        dy = min_image(spos[q, 1] - yi, period[1], hy)
                        j = order[q]
                        inside = (dx * dx + dy * dy <= cut2) & (q != k)
                        if gi >= 0:
                            inside = inside & ((group[j] != gi) | (li & loose[j]))
                        buf[t] = j
                        t += inside
        counts[i] = t - t0


@kernel
def _compact(order, bstart, buf, offsets, nbr):
    """Copy each particle's neighbours from its ``buf`` slice to its CSR row.  An element loop,
    not a slice copy: numba compiled the slice assignment in 2.9-3.5 s of the cold start against
    0.2 s for the loop, which runs 1.08x the slice copy's time (40k rows of 30, measured
    2026-12-07; a rebuild is ~6 % of a step)."""
    for k in prange(order.shape[0]):
        i = order[k]
        a = offsets[i]
        m = offsets[i + 1] - a
        b = bstart[k]
        for q in range(m):
            nbr[a + q] = buf[b + q]


@compiled
def _sort_rows(offsets, nbr):
    for i in range(offsets.shape[0] - 1):
        a = offsets[i]
        b = offsets[i + 1]
        if b - a > 1:
            nbr[a:b] = np.sort(nbr[a:b])


# --------------------------------------------------------------------------- Python API


@dataclass
class CSRNeighbours:
    """Per-particle neighbour rows (both directions of every pair).

    ``offsets`` (n + 1,) int64, ``nbr`` (M,) uint32 (do not mix it with signed integers in
    numba arithmetic: int64 op uint64 gives float64); ``order`` is the cell order of the particles
    at build time (a good permutation for spatial locality).  ``dx`` (M, 2) and ``r`` (M,) are
    filled by :meth:`fill_geometry` only.
    """

    offsets: IntArray
    nbr: NDArray[np.uint32]
    n: int
    cutoff: float
    period: FloatArray
    order: IntArray
    dx: FloatArray | None = None
    r: FloatArray | None = None

    def __len__(self) -> int:
        return len(self.nbr)

    @property
    def counts(self) -> IntArray:
        return np.diff(self.offsets)

    def rows(self) -> IntArray:
        """Row index of every entry (for tests and numpy post-processing)."""
        return np.repeat(np.arange(self.n, dtype=np.int64), self.counts)

    def fill_geometry(self, pos: FloatArray) -> None:
        """Compute ``dx`` and ``r`` of every entry from ``pos`` (allocating them once)."""
        m = len(self.nbr)
        if self.dx is None or len(self.dx) != m:
            self.dx = np.empty((m, 2))
            self.r = np.empty(m)
        csr_geometry(as_pos(pos), self.offsets, self.nbr, self.period, self.dx, self.r)


def as_pos(pos: FloatArray) -> FloatArray:
    return np.ascontiguousarray(pos, dtype=np.float64).reshape(-1, 2)


def build_csr(
    pos: FloatArray,
    cutoff: float,
    box: Box | None = None,
    *,
    static: NDArray[np.bool_] | None = None,
    sort_rows: bool = False,
    geometry: bool = False,
    reach: int = 2,
    group: IntArray | None = None,
    loose: NDArray[np.bool_] | None = None,
    half: bool = False,
    serial: bool = False,
) -> CSRNeighbours:
    """All neighbours within ``cutoff`` of every particle, as CSR rows.

    ``static``: pairs whose two ends are both flagged are left out (rigid boundary-boundary
    pairs whose contribution a solver precomputes).  The general form: ``group`` (int64, -1 for
    none) puts particles in rigid groups and a pair inside one group is left out unless both
    ends are ``loose`` (the solvers' rule: a dummy particle's pairs with boundary particles
    moving with it are static, a pair of two wall particles is not).  ``static`` is the
    shorthand group 0 with nothing loose.  ``half``: each pair once, in the row of whichever
    end comes first in cell order (for the kernels of :mod:`.pairs`; half the distance tests).
    ``serial``: the one-thread builds of the kernels (:mod:`._jit`).  ``sort_rows`` orders
    each row by
    neighbour index (deterministic layout for comparisons; costs a sort per row).
    ``geometry`` also fills ``dx`` and ``r``.  ``reach``: cells are ``cutoff / reach`` wide and
    the stencil spans +-reach cells (2: 25 cells of cutoff/2 scan ~30% fewer candidates than
    9 cells of cutoff).
    """
    if reach not in (1, 2, 3):
        raise ValueError(f"build_csr: reach must be 1, 2 or 3, got {reach}")
    pos = as_pos(pos)
    n = len(pos)
    if not cutoff > 0:
        raise ValueError(f"build_csr: cutoff must be > 0, got {cutoff}")
    period = box_period(box)
    for ax in range(2):
        if period[ax] > 0 and cutoff >= period[ax] / 2:
            raise ValueError(
                f"build_csr: cutoff {cutoff} must be < half the periodic length {period[ax]}"
            )
    grp, lse = _static_rule(n, static, group, loose)
    origin, size, ncell = _grid(
        pos, float(cutoff), period, box_lo(box), _CELLS_PER_PARTICLE * n + 64, reach
    )
    ncells = int(ncell[0] * ncell[1])
    cell = np.empty(n, np.int64)
    start = np.empty(ncells + 1, np.int64)
    order = np.empty(n, np.int64)
    spos = np.empty((n, 2))
    bstart = np.zeros(n + 1, np.int64)
    _bin_sort(pos, origin, size, ncell, period, reach, cell, start, order, spos, bstart[1:])
    np.cumsum(bstart[1:], out=bstart[1:])
    buf = np.empty(int(bstart[-1]), np.uint32)
    counts = np.empty(n, np.int64)
    pick(_scan, serial)(
        spos, order, start, cell, ncell, period, reach, float(cutoff) ** 2, grp, lse, bool(half),
        bstart, buf, counts,
    )
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    nbr = np.empty(int(offsets[-1]), np.uint32)
    pick(_compact, serial)(order, bstart, buf, offsets, nbr)
    if sort_rows:
        _sort_rows(offsets, nbr)
    out = CSRNeighbours(offsets, nbr, n, float(cutoff), period, order)
    if geometry:
        out.fill_geometry(pos)
    return out


def _static_rule(
    n: int,
    static: NDArray[np.bool_] | None,
    group: IntArray | None,
    loose: NDArray[np.bool_] | None,
) -> tuple[IntArray, NDArray[np.bool_]]:
    """(group, loose) arrays for :func:`_scan` from either form of the static-pair rule."""
    if static is not None and group is not None:
        raise ValueError("build_csr: give static or group, not both")
    if group is None:
        st = np.zeros(n, np.bool_) if static is None else np.asarray(static, np.bool_)
        if len(st) != n:
            raise ValueError(f"build_csr: static has length {len(st)}, expected {n}")
        grp = np.where(st, 0, -1).astype(np.int64)
    else:
        grp = np.ascontiguousarray(group, np.int64)
        if len(grp) != n:
            raise ValueError(f"build_csr: group has length {len(grp)}, expected {n}")
    lse = np.zeros(n, np.bool_) if loose is None else np.ascontiguousarray(loose, np.bool_)
    if len(lse) != n:
        raise ValueError(f"build_csr: loose has length {len(lse)}, expected {n}")
    return grp, lse


__all__ = ["CSRNeighbours", "as_pos", "build_csr"]
