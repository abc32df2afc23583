"""The order the numba backend keeps its particles in: along a space-filling curve.

At every neighbour-list rebuild the particles are sorted by the Morton (Z-order) index of a grid
of cells about one interaction radius wide (:func:`morton_order`; a stable sort, so particles of
one cell keep their order), and every per-particle array is permuted with them.  Neighbours then
sit close together in memory: the gathers of the neighbour loops hit cache lines that the rows
before them loaded, however much the flow has stirred the particles (a dam break does, within a
few hundred steps), and a block of consecutive rows is a compact patch of the domain (the
blocks :class:`.fused.Schedule` hands to threads).

The caller's view stays in the problem's order: :class:`Birth` gives each particle an id when it
enters (its index in the problem, then increasing ids for particles an inflow adds) and
:meth:`Birth.external` the permutation that puts the particles back in that order, which is the
reference backend's order too (an open boundary drops particles and appends new ones; both
backends keep the survivors' relative order).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

IntArray = NDArray[np.int64]

_BITS = 16  # per axis: cells beyond 65535 along an axis share the last index (still correct)


def _spread(v: NDArray[np.uint64]) -> NDArray[np.uint64]:
    """The bits of 16-bit integers moved to the even bit positions (for interleaving)."""
    v = v & np.uint64(0xFFFF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF)
    v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F)
    v = (v | (v << np.uint64(2))) & np.uint64(0x33333333)
    return (v | (v << np.uint64(1))) & np.uint64(0x55555555)


def morton_keys(X: NDArray[np.float64], cell: float) -> NDArray[np.uint64]:
    """Z-order index of the cell (of width ``cell``) of each particle; X is (2, n).

    Cells count from the lowest finite coordinate; non-finite coordinates go to cell 0 (the
    order of a state that has blown up does not matter, only that sorting it does not fail).
    """
    n = X.shape[1]
    key = np.zeros(n, np.uint64)
    top = float(2**_BITS - 1)
    with np.errstate(all="ignore"):  # a blown-up state may overflow here: it only sorts
        for ax in range(2):
            c = X[ax]
            finite = np.isfinite(c)
            if not finite.any():
                continue
            lo = float(c[finite].min())
            scaled = np.where(finite, (np.where(finite, c, lo) - lo) / cell, 0.0)
            idx = np.minimum(scaled, top).astype(np.uint64)
            key |= _spread(idx) << np.uint64(ax)
    return key


def morton_order(X: NDArray[np.float64], cell: float) -> IntArray:
    """The permutation that sorts particles along the Z curve of cells ``cell`` wide (stable:
    particles of one cell keep their relative order, so a sorted state stays sorted)."""
    return np.argsort(morton_keys(X, cell), kind="stable").astype(np.int64)


class Birth:
    """Ids in the caller's order: the problem's index of each particle, then increasing ids for
    particles added later (kept in the solver's internal order, permuted along with it)."""

    def __init__(self, n: int) -> None:
        self.ids: IntArray = np.arange(n, dtype=np.int64)
        self.next = n
        self._external: IntArray | None = None

    def permute(self, order: IntArray) -> None:
        self.ids = self.ids[order]
        self._external = None

    def carry(self, keep: NDArray[np.bool_]) -> None:
        """After :func:`mpsbench.physics.boundaries.update_open_boundaries`: ``keep`` over the
        old particles followed by the new rows (appended in the order they were made)."""
        added = len(keep) - len(self.ids)
        grown = np.concatenate([self.ids, self.next + np.arange(added, dtype=np.int64)])
        self.next += added
        self.ids = grown[keep]
        self._external = None

    def external(self) -> IntArray:
        """Internal indices in the caller's order: ``arr[external()]`` is ``arr`` as the
        problem (and the reference backend) orders its particles."""
        if self._external is None:
            self._external = np.argsort(self.ids, kind="stable").astype(np.int64)
        return self._external

    @property
    def identity(self) -> bool:
        return bool(np.array_equal(self.ids, np.arange(len(self.ids))))


__all__ = ["Birth", "morton_keys", "morton_order"]
