"""Inflow, outflow and the ``mirror`` wall-velocity treatment for the reference backend."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from mpsbench.physics.config import Inflow, Region
from mpsbench.physics.particles import Box, Kind, Particles
from mpsbench.physics.powers import whole_power
from mpsbench.physics.weights import WeightFunction

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


def outflow_mask(p: Particles, regions: tuple[Region, ...]) -> NDArray[np.bool_]:
    """Mask of the fluid particles inside any outflow region."""
    gone = np.zeros(p.n, dtype=bool)
    for reg in regions:
        inside = np.all((p.pos >= reg.lo) & (p.pos <= reg.hi), axis=1)
        gone |= inside & (p.kind == Kind.FLUID)
    return gone


def update_open_boundaries(
    p: Particles, inflow: InflowBoundary | None, outflows: tuple[Region, ...], dt: float
) -> tuple[Particles, NDArray[np.bool_] | None]:
    """Advance the inflow reservoir by ``dt`` and drop the fluid inside the outflow regions.

    Returns the new particle set and ``keep``: over the old particles followed by the rows the
    inflow appended, which of them remain (None when the set did not change).  A solver moves
    its per-particle arrays along with :func:`carry`.  Both backends use this, so they add and
    remove the same particles in the same order.
    """
    grew = False
    if inflow is not None:
        p, grew = inflow.update(p, dt)  # new rows are appended at the end
    gone = outflow_mask(p, outflows)
    if gone.any():
        p = p.subset(~gone)
    return p, (~gone if grew or gone.any() else None)


def carry(arr: NDArray[Any], keep: NDArray[np.bool_]) -> NDArray[Any]:
    """A per-particle array after :func:`update_open_boundaries`: survivors keep their values
    (so diagnostics stay valid between steps), new reservoir rows get 0 / False."""
    grown = np.zeros(len(keep), dtype=arr.dtype)
    grown[: len(arr)] = arr
    return grown[keep]


def mirror_points(p: Particles) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray]:
    """Boundary particles with wall geometry, the fluid particles, and the boundary particles'
    mirror points: their reflections across the wall line (``pos + 2 wall_dist n``).

    Empty index arrays when there is no wall geometry, no such boundary particle or no fluid.
    """
    none = np.zeros(0, np.intp)
    bnd = np.nonzero((p.kind == Kind.WALL) | (p.kind == Kind.DUMMY))[0]
    fluid = np.nonzero(p.kind == Kind.FLUID)[0]
    if "wall_dist" not in p.fields or len(bnd) == 0 or len(fluid) == 0:
        return none, none, np.zeros((0, 2))
    normal = np.column_stack([p.fields["wall_nx"][bnd], p.fields["wall_ny"][bnd]])
    has = np.hypot(normal[:, 0], normal[:, 1]) > 0
    bnd, normal = bnd[has], normal[has]
    return bnd, fluid, p.pos[bnd] + 2.0 * p.fields["wall_dist"][bnd, None] * normal


def extrapolate_through_wall(wall_vel: FloatArray, u_mirror: FloatArray) -> FloatArray:
    """u_b = 2 u_wall - u_mirror (linear through the wall line); where the fit found no fluid
    (NaN) the boundary particle keeps its prescribed velocity."""
    return 2.0 * wall_vel - np.where(np.isnan(u_mirror), wall_vel, u_mirror)


def mirror_velocity(p: Particles, weight: WeightFunction, re: float, box: Box) -> FloatArray:
    """Boundary velocities extrapolated so the wall velocity holds on the wall line.

    Each boundary particle is reflected across its wall line (``wall_nx/ny``, ``wall_dist``);
    the fluid velocity u_f at the mirror point is interpolated from the fluid particles within
    ``re`` by a kernel-weighted linear least-squares fit (moving least squares, exact for a
    linear field), and the boundary particle gets u_b = 2 u_wall - u_f: linear extrapolation
    through the wall.  A plain Shepard average is only zeroth-order: near a wall its support is
    one-sided and it returns the fluid velocity about r_e/2 inside the fluid, which puts the
    no-slip point O(r_e) away from the wall line.  Where the fit is ill-posed (fewer than three
    neighbours, all in a line) the Shepard average is used; without any fluid neighbour the
    prescribed velocity is kept.  Boundary particles without wall geometry keep theirs too.
    """
    vel = p.vel.copy()
    bnd, fluid, mirror = mirror_points(p)
    if len(bnd) == 0:
        return vel
    fpos, mpos, boxsize = _common_frame(p.pos[fluid], mirror, re, box)
    ftree = cKDTree(fpos, boxsize=boxsize)
    sdm = ftree.sparse_distance_matrix(cKDTree(mpos, boxsize=boxsize), re, output_type="coo_matrix")
    u_mirror = _linear_fit(
        p.pos[fluid[sdm.row]] - mirror[sdm.col], sdm.col, sdm.data, p.vel[fluid[sdm.row]],
        len(bnd), weight, re, box,
    )
    # a boundary particle's vel is its prescribed wall velocity
    vel[bnd] = extrapolate_through_wall(p.vel[bnd], u_mirror)
    return vel


def _linear_fit(
    d: FloatArray, col: NDArray[np.intp], r: FloatArray, values: FloatArray, n: int,
    weight: WeightFunction, re: float, box: Box,
) -> FloatArray:
    """Value at n points of the weighted linear fit a + g.d to ``values`` (NaN: no data).

    ``d`` (M, 2) are the offsets of the data points from their target point ``col``, ``r``
    their lengths.  The weight is floored at r = 0.05 re so that a singular weight (WF1) at a
    data point on the target point stays finite; any positive weight keeps the fit exact for
    linear fields.
    """
    if box.any_periodic:
        box.minimum_image(d)
    s = d / re  # offsets in units of re keep the moment matrix well scaled
    w = weight.w(np.maximum(r, 0.05 * re), re)
    basis = np.column_stack([np.ones(len(w)), s[:, 0], s[:, 1]])
    moment = np.zeros((n, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            moment[:, a, b] = np.bincount(col, w * basis[:, a] * basis[:, b], n)
            moment[:, b, a] = moment[:, a, b]
    count = np.bincount(col, None, n)
    den = moment[:, 0, 0]
    out = np.full((n, 2), np.nan)
    has = den > 0
    rhs = np.zeros((n, 3, 2))
    for a in range(3):
        for ax in range(2):
            rhs[:, a, ax] = np.bincount(col, w * basis[:, a] * values[:, ax], n)
    out[has] = rhs[has, 0, :] / den[has, None]  # Shepard average (zeroth order)
    # the linear fit where the moment matrix is well conditioned
    det = np.linalg.det(moment)
    scale = whole_power(np.where(has, den, 1.0), 3)
    good = has & (count >= 3) & (np.abs(det) > 1e-8 * scale)
    if good.any():
        coef = np.linalg.solve(moment[good], rhs[good])
        out[good] = coef[:, 0, :]
    return out


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
