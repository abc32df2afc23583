"""Neighbour upkeep for the reference backend: a skinned pair list and static wall pairs.

The pair list is built at ``r_max + skin`` and reused until some particle has moved more than
``skin / 2`` since the build (then no pair within ``r_max`` can be missing).  Pairs of a dummy
particle with another boundary particle that move rigidly together (same velocity, not inflow)
never change and never enter the pressure gradient, so their contribution to the number density
is computed once and the pairs are dropped from the list.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mpsbench.physics.neighbours import PairList, build_pairs
from mpsbench.physics.particles import Box, Kind, Particles
from mpsbench.physics.weights import WeightFunction

FloatArray = NDArray[np.float64]


class SkinnedPairs:
    def __init__(self, r_max: float, skin: float, box: Box) -> None:
        self.r_max = r_max
        self.skin = skin
        self.box = box
        self.pairs: PairList | None = None
        self.moved = 0.0  # max displacement since the last build (upper bound)
        self.builds = 0
        self.static_n: FloatArray | None = None
        self.no_dummy: NDArray[np.bool_] = np.zeros(0, dtype=bool)

    def invalidate(self) -> None:
        self.pairs = None

    def note_motion(self, disp: FloatArray) -> None:
        """Record a displacement of every particle (an (N, 2) array) since the last call."""
        if len(disp):
            self.moved += float(np.sqrt(np.max(disp[:, 0] ** 2 + disp[:, 1] ** 2)))

    def stale(self, p: Particles) -> bool:
        """Whether the next :meth:`get` rebuilds the list."""
        return self.pairs is None or 2.0 * self.moved > self.skin or self.pairs.n != p.n

    def get(self, p: Particles, weight: WeightFunction, re: float) -> PairList:
        """The current pair list with fresh ``dx`` and ``r`` (rebuilt when stale)."""
        if self.pairs is None or self.stale(p):
            self._build(p, weight, re)
        else:
            self.pairs.refresh(p.pos, self.box)
        assert self.pairs is not None
        return self.pairs

    def _build(self, p: Particles, weight: WeightFunction, re: float) -> None:
        # the old list goes first: a build holds the skinned list and its filtered copy, and
        # with the old one still alive that was the step's memory peak (issue 20)
        self.pairs = None
        self.no_dummy = np.zeros(0, dtype=bool)
        full = build_pairs(p.pos, self.r_max + self.skin, self.box)
        ki, kj = p.kind[full.i], p.kind[full.j]
        solid_i = (ki != Kind.FLUID) & (ki != Kind.INFLOW)
        boundary = solid_i & (kj != Kind.FLUID) & (kj != Kind.INFLOW)
        # Only pairs with a dummy particle are static: a pair of two wall particles stays in the
        # list, because the pressure gradient needs it (pmin of a wall particle in PGM2 is the
        # minimum over its wall neighbours too).
        boundary &= (ki == Kind.DUMMY) | (kj == Kind.DUMMY)
        # of those (a tenth of the list), the pairs that move rigidly together
        cand = np.flatnonzero(boundary)
        ci, cj = full.i[cand], full.j[cand]
        rigid_at = cand[np.all(p.vel[ci] == p.vel[cj], axis=1)]
        # Static pairs: their weights never change, so add them to n once per build (the same
        # sums, in the same order, as summing every pair with zero weight off the static ones).
        ri, rj = full.i[rigid_at], full.j[rigid_at]
        w = weight.w(full.r[rigid_at], re)
        # bincount with weights sums in float64 (numpy's stubs type it as integer)
        self.static_n = (np.bincount(ri, w, full.n) + np.bincount(rj, w, full.n)).astype(float)
        keep = np.ones(len(full), dtype=bool)
        keep[rigid_at] = False
        del ki, kj, solid_i, boundary, cand, ci, cj, rigid_at, ri, rj, w
        # filter one array at a time, dropping each full one as its copy is made
        i = full.i[keep]
        full.i = i
        j = full.j[keep]
        full.j = j
        dx = full.dx[keep]
        full.dx = dx
        r = full.r[keep]
        self.pairs = PairList(i, j, dx, r, full.n, full.cutoff)
        del full
        kind = p.kind
        self.no_dummy = (kind[self.pairs.i] != Kind.DUMMY) & (kind[self.pairs.j] != Kind.DUMMY)
        self.moved = 0.0
        self.builds += 1
