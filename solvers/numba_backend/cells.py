"""Cell-linked neighbour lists compiled with numba: a CSR list and a half pair list.

Geometry of a box is passed to the compiled code as one (2,) float64 array ``period``: the period
L of each periodic axis and 0.0 on free axes (:func:`box_period`).  Separations follow
:meth:`mpsbench.physics.particles.Box.minimum_image` bit for bit: ``dx = r_j - r_i``, then on a
periodic
axis ``dx - L * rint(dx / L)``.

Cells are at least ``cutoff / reach`` wide (``reach`` = 2 by default), so every neighbour of a
particle lies within ``reach`` cells of its own along each axis.  On a periodic axis the grid
covers the period (a stencil that would visit a cell twice is de-duplicated, one that wraps is
split in two); on a free axis it covers the bounding box of the positions (capped at a few cells
per particle: coarser cells stay correct, only slower, if one particle flies far away).
Particles are binned with a stable counting sort; the cells of one stencil row are contiguous in
that order and are scanned as one span.

The CSR list holds both directions of every pair: row ``i`` is
``nbr[offsets[i]:offsets[i + 1]]`` (uint32: unsigned indices spare numba's negative-index
wraparound test on every gather), so per-particle loops run in parallel without write
conflicts.  It stores no geometry by default: the compute kernels recompute ``dx`` and ``r`` from
the positions on the fly, which reads 4 bytes per entry instead of 28 and lets one list built at
``r_max + skin`` serve many steps (:class:`CellNeighbourList`).  :func:`csr_geometry` fills
``dx`` and ``r`` per entry when they are wanted.

A pair at exactly ``r == cutoff`` (to the last bit) may be in or out of the list depending on
rounding, as in scipy's cKDTree, which decides it in a shifted frame.  W is zero there but W' of
wf1 is not, so :class:`CellNeighbourList` builds at ``r_max (1 + SUPPORT_RTOL) + skin`` padded
by a relative 1e-12: with any skin, or none, every pair the kernels' own closed-support test
``r <= re (1 + SUPPORT_RTOL)`` accepts is in the list.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from mpsbench.physics.neighbours import PairList
from mpsbench.physics.particles import Box
from mpsbench.physics.weights import SUPPORT_RTOL

from ._jit import kernel, pick

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# cells are made this much wider than the cut-off so rounding in the binning cannot lose a pair
_SAFETY = 1.0 + 1e-9
_CELLS_PER_PARTICLE = 4


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


# --------------------------------------------------------------------------- compiled helpers


@njit(cache=True, inline="always")
def half_width(period):
    """Half the period of an axis, +inf on a free axis (period 0): the argument of min_image."""
    return 0.5 * period if period > 0.0 else np.inf


@njit(cache=True, inline="always")
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


@njit(cache=True)
def _grid(pos, cutoff, period, lo, max_cells, reach):
    """Cell grid: origin (2,), cell size (2,), cells per axis (2,); cells >= cutoff / reach."""
    n = pos.shape[0]
    origin = np.empty(2)
    size = np.empty(2)
    ncell = np.empty(2, np.int64)
    extent = np.zeros(2)
    width = cutoff / reach * _SAFETY
    for ax in range(2):
        if period[ax] > 0.0:
            m = int(period[ax] / width)
            if m < 1:
                m = 1
            origin[ax] = lo[ax]
            ncell[ax] = m
            size[ax] = period[ax] / m
        else:
            xmin = np.inf
            xmax = -np.inf
            for i in range(n):
                x = pos[i, ax]
                if x < xmin:
                    xmin = x
                if x > xmax:
                    xmax = x
            if not xmax >= xmin:  # no finite coordinate
                xmin = 0.0
                xmax = 0.0
            origin[ax] = xmin
            extent[ax] = xmax - xmin
            size[ax] = width
            ncell[ax] = int(extent[ax] / width) + 1
    while ncell[0] * ncell[1] > max_cells:
        ax = 0 if ncell[0] >= ncell[1] else 1
        if ncell[ax] == 1:
            break
        if period[ax] > 0.0:
            ncell[ax] = ncell[ax] // 2
            size[ax] = period[ax] / ncell[ax]
        else:
            size[ax] *= 2.0
            ncell[ax] = int(extent[ax] / size[ax]) + 1
    return origin, size, ncell


@njit(cache=True, inline="always")
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


@njit(cache=True)
def _bin(pos, origin, size, ncell, period, cell):
    """Cell id of every particle; ids run along x fastest (``cy * nx + cx``)."""
    n = pos.shape[0]
    px = period[0] > 0.0
    py = period[1] > 0.0
    for i in range(n):
        cx = _coord(pos[i, 0], origin[0], size[0], ncell[0], px)
        cy = _coord(pos[i, 1], origin[1], size[1], ncell[1], py)
        cell[i] = cy * ncell[0] + cx


@njit(cache=True)
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


@njit(cache=True, inline="always")
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


@njit(cache=True)
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
    """Copy each particle's neighbours from its ``buf`` slice to its CSR row (slice copies:
    an element loop is ~7x slower here)."""
    for k in prange(order.shape[0]):
        i = order[k]
        a = offsets[i]
        m = offsets[i + 1] - a
        b = bstart[k]
        nbr[a : a + m] = buf[b : b + m]


@njit(cache=True)
def _sort_rows(offsets, nbr):
    for i in range(offsets.shape[0] - 1):
        a = offsets[i]
        b = offsets[i + 1]
        if b - a > 1:
            nbr[a:b] = np.sort(nbr[a:b])


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
def _gather_rows(pos, order, out):
    for k in range(order.shape[0]):
        out[k, 0] = pos[order[k], 0]
        out[k, 1] = pos[order[k], 1]


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
        csr_geometry(_as_pos(pos), self.offsets, self.nbr, self.period, self.dx, self.r)


def _as_pos(pos: FloatArray) -> FloatArray:
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
    pos = _as_pos(pos)
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
    _bin(pos, origin, size, ncell, period, cell)
    start = np.empty(ncells + 1, np.int64)
    order = np.empty(n, np.int64)
    _counting_sort(cell, ncells, start, order)
    spos = np.empty((n, 2))
    _gather_rows(pos, order, spos)
    bstart = np.zeros(n + 1, np.int64)
    _bounds(start, cell, ncell, period, reach, order, bstart[1:])
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


def csr_to_pairs(csr: CSRNeighbours, pos: FloatArray) -> PairList:
    """The half pair list (i < j, sorted by i then j) of a CSR list, with ``dx`` and ``r``."""
    rows = csr.rows()
    nbr = csr.nbr.astype(np.int64)
    keep = nbr > rows
    i, j = rows[keep], nbr[keep]
    order = np.lexsort((j, i))
    i = np.ascontiguousarray(i[order], dtype=np.intp)
    j = np.ascontiguousarray(j[order], dtype=np.intp)
    dx = np.empty((len(i), 2))
    r = np.empty(len(i))
    pair_geometry(_as_pos(pos), i, j, csr.period, dx, r)
    return PairList(i, j, dx, r, csr.n, csr.cutoff)


def build_pairs_cells(pos: FloatArray, cutoff: float, box: Box | None = None) -> PairList:
    """Same result as :func:`mpsbench.physics.neighbours.build_pairs`, from the cell list."""
    pos = _as_pos(pos)
    if len(pos) < 2:
        if not cutoff > 0:
            raise ValueError(f"build_pairs_cells: cutoff must be > 0, got {cutoff}")
        empty = np.zeros(0, dtype=np.intp)
        return PairList(empty, empty.copy(), np.zeros((0, 2)), np.zeros(0), len(pos), cutoff)
    return csr_to_pairs(build_csr(pos, cutoff, box), pos)


class CellNeighbourList:
    """A CSR list built at ``r_max + skin`` and kept while no particle moved more than skin/2.

    Call :meth:`update` with the current positions before each use; it rebuilds only when a
    particle has moved more than ``skin / 2`` since the last build (then no pair within
    ``r_max`` can be missing), when the particle count changed, or after :meth:`invalidate`.
    Kernels evaluate weights as zero beyond their own r_e, so the extra pairs are harmless.

    ``r_small`` (optional, < r_max): also keep :attr:`small`, the entries of the list within
    ``r_small + skin`` at build time; it stays valid for ``r_small`` by the same argument, and
    kernels at the smaller radius (number density, pressure gradient, stabilization at
    r_e = 2.1 l0 next to a Laplacian at 3.1 l0) scan half as many entries.  ``half``: half
    lists (each pair once, see :func:`build_csr`).  ``serial``: one-thread kernel builds.
    """

    def __init__(
        self,
        r_max: float,
        skin: float,
        box: Box | None = None,
        sort_rows: bool = False,
        r_small: float | None = None,
        half: bool = False,
        serial: bool = False,
    ) -> None:
        if not r_max > 0 or not skin >= 0:
            raise ValueError(f"CellNeighbourList: need r_max > 0, skin >= 0; got {r_max}, {skin}")
        if r_small is not None and not 0 < r_small <= r_max:
            raise ValueError(f"CellNeighbourList: need 0 < r_small <= r_max, got {r_small}")
        self.r_max = float(r_max)
        self.skin = float(skin)
        self.r_small = None if r_small is None else float(r_small)
        self.half = bool(half)
        self.serial = bool(serial)
        self.box = box
        self.period = box_period(box)
        self.sort_rows = sort_rows
        self.csr: CSRNeighbours | None = None
        self.small: CSRNeighbours | None = None
        self.group: IntArray | None = None
        self.loose: NDArray[np.bool_] | None = None
        self._ref: FloatArray | None = None
        self.builds = 0

    @staticmethod
    def padded(r: float, skin: float) -> float:
        """Cut-off for radius ``r``: the closed support r (1 + SUPPORT_RTOL) + skin, padded."""
        return (r * (1.0 + SUPPORT_RTOL) + skin) * (1.0 + 1e-12)

    @property
    def cutoff(self) -> float:
        """The list's cut-off: r_max + skin, padded so no pair the kernels count is lost."""
        return self.padded(self.r_max, self.skin)

    def invalidate(self) -> None:
        self.csr = None
        self.small = None

    def set_static(
        self,
        static: NDArray[np.bool_] | None = None,
        *,
        group: IntArray | None = None,
        loose: NDArray[np.bool_] | None = None,
    ) -> None:
        """Which pairs are left out (see :func:`build_csr`); takes effect at the next build."""
        if static is not None:
            group = np.where(np.asarray(static, np.bool_), 0, -1).astype(np.int64)
            loose = None
        self.group = None if group is None else np.ascontiguousarray(group, np.int64)
        self.loose = None if loose is None else np.ascontiguousarray(loose, np.bool_)
        self.invalidate()

    def update(self, pos: FloatArray) -> bool:
        """Make the list valid for ``pos``; return True when it was rebuilt."""
        pos = _as_pos(pos)
        if self.csr is not None and self.csr.n == len(pos) and self._ref is not None:
            if 2.0 * max_displacement(pos, self._ref, self.period) <= self.skin:
                return False
        group = self.group if self.group is not None and len(self.group) == len(pos) else None
        loose = self.loose if group is not None else None
        self.csr = build_csr(
            pos, self.cutoff, self.box, sort_rows=self.sort_rows, group=group, loose=loose,
            half=self.half, serial=self.serial,
        )
        if self.r_small is not None:
            self.small = within(
                self.csr, pos, self.padded(self.r_small, self.skin), serial=self.serial
            )
        self._ref = pos.copy()
        self.builds += 1
        return True


@kernel
def _count_within(pos, offsets, nbr, period, cut2, counts):
    hx = half_width(period[0])
    hy = half_width(period[1])
    for i in prange(offsets.shape[0] - 1):
        xi = pos[i, 0]
        yi = pos[i, 1]
        m = 0
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            d0 = min_image(pos[j, 0] - xi, period[0], hx)
            d1 = min_image(pos[j, 1] - yi, period[1], hy)
            m += d0 * d0 + d1 * d1 <= cut2
        counts[i] = m


@kernel
def _fill_within(pos, offsets, nbr, period, cut2, new_offsets, out):
    hx = half_width(period[0])
    hy = half_width(period[1])
    for i in prange(offsets.shape[0] - 1):
        xi = pos[i, 0]
        yi = pos[i, 1]
        t = new_offsets[i]
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            d0 = min_image(pos[j, 0] - xi, period[0], hx)
            d1 = min_image(pos[j, 1] - yi, period[1], hy)
            if d0 * d0 + d1 * d1 <= cut2:
                out[t] = j
                t += 1


def within(
    csr: CSRNeighbours, pos: FloatArray, cutoff: float, serial: bool = False
) -> CSRNeighbours:
    """The sub-list of ``csr`` within ``cutoff`` at ``pos`` (same row order, CSR again)."""
    pos = _as_pos(pos)
    counts = np.empty(csr.n, np.int64)
    cut2 = float(cutoff) ** 2
    pick(_count_within, serial)(pos, csr.offsets, csr.nbr, csr.period, cut2, counts)
    offsets = np.zeros(csr.n + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    nbr = np.empty(int(offsets[-1]), np.uint32)
    pick(_fill_within, serial)(pos, csr.offsets, csr.nbr, csr.period, cut2, offsets, nbr)
    return CSRNeighbours(offsets, nbr, csr.n, float(cutoff), csr.period, csr.order)


__all__ = [
    "CSRNeighbours",
    "CellNeighbourList",
    "box_lo",
    "box_period",
    "build_csr",
    "build_pairs_cells",
    "csr_geometry",
    "csr_to_pairs",
    "max_displacement",
    "half_width",
    "min_image",
    "pair_geometry",
    "within",
]
