"""Inflow, outflow and the ``mirror`` wall-velocity treatment for the reference backend."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from mpsbench.config import Inflow, Region
from mpsbench.kernels import WeightFunction
from mpsbench.particles import Box, Kind, Particles

FloatArray = NDArray[np.float64]


class InflowBoundary:
    """Reservoir rows of INFLOW particles upstream of the inlet segment.

    Reservoir particles advect at the inflow velocity; once past the inlet line they become
    fluid.  A fresh row is added upstream whenever the rows have advanced by one spacing.
    """

    def __init__(self, spec: Inflow, l0: float) -> None:
        self.spec = spec
        self.l0 = l0
        a, b = np.asarray(spec.start, float), np.asarray(spec.end, float)
        self.a = a
        length = float(np.hypot(*(b - a)))
        self.n_across = max(1, int(round(length / l0)))
        self.tangent = (b - a) / length
        v = np.asarray(spec.velocity, float)
        self.speed = float(np.hypot(*v))
        self.direction = v / self.speed
        if abs(float(self.direction @ self.tangent)) > 1e-9:
            raise ValueError("Inflow.velocity must be normal to the inlet segment start->end")
        self.advanced = 0.0

    def row(self, offset: float) -> Particles:
        """One row of INFLOW particles at ``offset`` upstream of the inlet line."""
        s = (np.arange(self.n_across) + 0.5) * self.l0
        pos = self.a + s[:, None] * self.tangent - offset * self.direction
        p = Particles.from_positions(pos, Kind.INFLOW)
        p.vel[:] = self.speed * self.direction
        return p

    def initial(self) -> Particles:
        return Particles.concat(
            [self.row((k + 0.5) * self.l0) for k in range(self.spec.layers)]
        )

    def update(self, p: Particles, dt: float) -> tuple[Particles, bool]:
        """Turn crossed reservoir particles into fluid and add rows as needed.

        Returns the (possibly new) particle set and whether the particle count changed.
        """
        inflow = p.kind == Kind.INFLOW
        depth = (p.pos - self.a) @ self.direction  # > 0 downstream of the inlet line
        crossed = inflow & (depth >= 0.0)
        p.kind[crossed] = Kind.FLUID
        self.advanced += self.speed * dt
        if self.advanced < self.l0:
            return p, False
        rows = []
        while self.advanced >= self.l0:
            self.advanced -= self.l0
            # the newest row starts one spacing behind the last one, minus what it has moved
            rows.append(self.row(self.spec.layers * self.l0 - self.advanced - 0.5 * self.l0))
        new = Particles.concat([p, *rows]) if rows else p
        return _align_fields(new, p), True


def _align_fields(new: Particles, old: Particles) -> Particles:
    for name in old.fields:
        if name not in new.fields:
            new.fields[name] = np.zeros(new.n)
    return new


def remove_outflow(p: Particles, regions: tuple[Region, ...]) -> tuple[Particles, int]:
    """Drop fluid particles inside any outflow region; returns the new set and the count removed."""
    if not regions:
        return p, 0
    gone = np.zeros(p.n, dtype=bool)
    for reg in regions:
        inside = np.all((p.pos >= reg.lo) & (p.pos <= reg.hi), axis=1)
        gone |= inside & (p.kind == Kind.FLUID)
    if not gone.any():
        return p, 0
    return p.subset(~gone), int(gone.sum())


def mirror_velocity(p: Particles, weight: WeightFunction, re: float, box: Box) -> FloatArray:
    """Boundary velocities extrapolated so the wall velocity holds on the wall line.

    Each boundary particle is reflected across its wall line (``wall_nx/ny``, ``wall_dist``);
    the fluid velocity there is a Shepard (kernel-weighted) average, and the boundary particle
    gets u_b = 2 u_wall - u_fluid(mirror point): linear extrapolation through the wall.
    Boundary particles without wall geometry keep their prescribed velocity.
    """
    vel = p.vel.copy()
    wall_vel = p.vel  # a boundary particle's vel is its prescribed wall velocity
    bnd = np.nonzero((p.kind == Kind.WALL) | (p.kind == Kind.DUMMY))[0]
    if "wall_dist" not in p.fields or len(bnd) == 0:
        return vel
    fluid = np.nonzero(p.kind == Kind.FLUID)[0]
    if len(fluid) == 0:
        return vel
    normal = np.column_stack([p.fields["wall_nx"][bnd], p.fields["wall_ny"][bnd]])
    has = np.hypot(normal[:, 0], normal[:, 1]) > 0
    bnd, normal = bnd[has], normal[has]
    mirror = p.pos[bnd] + 2.0 * p.fields["wall_dist"][bnd, None] * normal
    fpos, mpos, boxsize = _common_frame(p.pos[fluid], mirror, re, box)
    ftree = cKDTree(fpos, boxsize=boxsize)
    sdm = ftree.sparse_distance_matrix(cKDTree(mpos, boxsize=boxsize), re, output_type="coo_matrix")
    w = weight.w(np.maximum(sdm.data, 1e-12 * re), re)
    den = np.bincount(sdm.col, w, len(bnd))
    ok = den > 0
    for ax in range(2):
        num = np.bincount(sdm.col, w * p.vel[fluid[sdm.row], ax], len(bnd))
        u_mirror = np.where(ok, num / np.where(ok, den, 1.0), wall_vel[bnd, ax])
        vel[bnd, ax] = 2.0 * wall_vel[bnd, ax] - u_mirror
    return vel


def _common_frame(
    a: FloatArray, b: FloatArray, cutoff: float, box: Box
) -> tuple[FloatArray, FloatArray, FloatArray | None]:
    """Map two point sets into one cKDTree frame (periodic axes wrapped)."""
    if not box.any_periodic:
        return a, b, None
    a, b = a.copy(), b.copy()
    size = np.empty(2)
    for ax in range(2):
        if box.periodic[ax]:
            length = box.hi[ax] - box.lo[ax]
            for pts in (a, b):
                pts[:, ax] = np.mod(pts[:, ax] - box.lo[ax], length)
                pts[:, ax][pts[:, ax] >= length] = 0.0
            size[ax] = length
        else:
            lo = min(a[:, ax].min(), b[:, ax].min())
            hi = max(a[:, ax].max(), b[:, ax].max())
            a[:, ax] -= lo
            b[:, ax] -= lo
            size[ax] = hi - lo + 2.0 * cutoff + 1.0
    return a, b, size
