"""A skinned cell list kept valid as particles move, sub-lists at a smaller radius, and the
conversion of a CSR list to the numpy pair list of :mod:`mpsbench.physics.neighbours`.

A pair at exactly ``r == cutoff`` (to the last bit) may be in or out of a cell list depending on
rounding (:mod:`.cells`).  W is zero there but W' of wf1 is not, so :class:`CellNeighbourList`
builds at ``r_max (1 + SUPPORT_RTOL) + skin`` padded by a relative 1e-12: with any skin, or
none, every pair the kernels' own closed-support test ``r <= re (1 + SUPPORT_RTOL)`` accepts is
in the list.
"""

from __future__ import annotations

import numpy as np
from numba import prange
from numpy.typing import NDArray

from mpsbench.physics.neighbours import PairList
from mpsbench.physics.particles import Box
from mpsbench.physics.weights import SUPPORT_RTOL

from ._jit import kernel, pick
from .cells import CSRNeighbours, IntArray, as_pos, build_csr
from .geometry import box_period, half_width, max_displacement, min_image, pair_geometry

FloatArray = NDArray[np.float64]


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
    pair_geometry(as_pos(pos), i, j, csr.period, dx, r)
    return PairList(i, j, dx, r, csr.n, csr.cutoff)


def build_pairs_cells(pos: FloatArray, cutoff: float, box: Box | None = None) -> PairList:
    """Same result as :func:`mpsbench.physics.neighbours.build_pairs`, from the cell list."""
    pos = as_pos(pos)
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
        pos = as_pos(pos)
        if self.csr is not None and self.csr.n == len(pos) and self._ref is not None:
            if 2.0 * max_displacement(pos, self._ref, self.period) <= self.skin:
                return False
        self.build(pos)
        return True

    def valid_after(self, displacement: float, n: int) -> bool:
        """Whether the list built last still serves ``n`` particles that have moved at most
        ``displacement`` each since (a NaN displacement says no)."""
        return self.csr is not None and self.csr.n == n and 2.0 * displacement <= self.skin

    def compact(self, keep: NDArray[np.bool_]) -> bool:
        """Drop the particles where ``keep`` is false from the list, the sub-list and the
        static marks, renumbering the others, without a rebuild; return False (and do
        nothing) when there is no list or a dropped particle is in a rigid group.

        A list that was valid stays valid: the particles kept have not moved, and the build
        positions they are measured against are kept with them.  Dropping particles only
        removes pairs; the static number density (pairs inside a rigid group) changes only
        when a group member goes, hence the condition."""
        keep = np.ascontiguousarray(keep, np.bool_)
        if self.csr is None or self._ref is None or len(keep) != self.csr.n:
            return False
        if self.group is not None and len(self.group) == len(keep) and (
                self.group[~keep] >= 0).any():
            return False
        index = (np.cumsum(keep) - 1).astype(np.uint32)
        rows = np.flatnonzero(keep).astype(np.int64)
        self.csr = _keep_rows(self.csr, keep, rows, index, self.serial)
        if self.small is not None:
            self.small = _keep_rows(self.small, keep, rows, index, self.serial)
        self._ref = np.ascontiguousarray(self._ref[keep])
        if self.group is not None and len(self.group) == len(keep):
            self.group = np.ascontiguousarray(self.group[keep])
            if self.loose is not None:
                self.loose = np.ascontiguousarray(self.loose[keep])
        return True

    def build(self, pos: FloatArray) -> None:
        """Build the list (and the sub-list) for ``pos`` now."""
        pos = as_pos(pos)
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
    pos = as_pos(pos)
    counts = np.empty(csr.n, np.int64)
    cut2 = float(cutoff) ** 2
    pick(_count_within, serial)(pos, csr.offsets, csr.nbr, csr.period, cut2, counts)
    offsets = np.zeros(csr.n + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    nbr = np.empty(int(offsets[-1]), np.uint32)
    pick(_fill_within, serial)(pos, csr.offsets, csr.nbr, csr.period, cut2, offsets, nbr)
    return CSRNeighbours(offsets, nbr, csr.n, float(cutoff), csr.period, csr.order)


@kernel
def _count_kept(offsets, nbr, keep, rows, counts):
    for t in prange(rows.shape[0]):
        i = rows[t]
        m = 0
        for k in range(offsets[i], offsets[i + 1]):
            m += keep[nbr[k]]
        counts[t] = m


@kernel
def _fill_kept(offsets, nbr, keep, rows, index, new_offsets, out):
    for t in prange(rows.shape[0]):
        i = rows[t]
        s = new_offsets[t]
        for k in range(offsets[i], offsets[i + 1]):
            j = nbr[k]
            if keep[j]:
                out[s] = index[j]
                s += 1


def _keep_rows(csr: CSRNeighbours, keep: NDArray[np.bool_], rows: IntArray,
               index: NDArray[np.uint32], serial: bool) -> CSRNeighbours:
    """``csr`` without the rows and entries of the dropped particles, renumbered by ``index``
    (the kept entries stay in their order)."""
    counts = np.empty(len(rows), np.int64)
    pick(_count_kept, serial)(csr.offsets, csr.nbr, keep, rows, counts)
    offsets = np.zeros(len(rows) + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    nbr = np.empty(int(offsets[-1]), np.uint32)
    pick(_fill_kept, serial)(csr.offsets, csr.nbr, keep, rows, index, offsets, nbr)
    order = index[csr.order[keep[csr.order]]].astype(np.int64)
    return CSRNeighbours(offsets, nbr, len(rows), csr.cutoff, csr.period, order)


__all__ = ["CellNeighbourList", "build_pairs_cells", "csr_to_pairs", "within"]
