"""Particles as a structure of arrays, periodic boxes and lattice builders.

Units: SI throughout (m, m/s, Pa).  Kinds: fluid particles move; wall particles form the first
boundary layer (they take part in pressure and in every operator); dummy particles sit behind the
wall to complete the number density.  Wall and dummy particles carry the wall velocity in ``vel``.

Boundary rows built by :func:`wall_layers` also carry ``wall_nx``, ``wall_ny`` (unit normal of
the wall line, pointing into the fluid) and ``wall_dist`` (distance behind the wall line, > 0),
which the ``mirror`` wall-velocity treatment uses to reflect a boundary particle into the fluid.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# What a part without a field gets in :meth:`Particles.concat`: zero, except for ``wall_tag``,
# where zero is a tag like any other (``WallMotion(0, ...)`` would also move the untagged rows,
# e.g. an inflow reservoir joined to tagged walls) and -1 means untagged.
UNTAGGED = -1.0
FIELD_FILL: dict[str, float] = {"wall_tag": UNTAGGED}


class Kind(IntEnum):
    FLUID = 0
    WALL = 1  # first boundary row: pressure from the EOS, in every operator
    DUMMY = 2  # rows behind the wall: complete the number density, carry the wall velocity
    INFLOW = 3  # reservoir rows upstream of an inlet: move at the inflow velocity, then turn fluid


@dataclass(frozen=True)
class Box:
    """An axis-aligned box [lo, hi); ``periodic`` per axis.

    Non-periodic axes only bound the domain (used to detect particles that leave it).
    """

    lo: tuple[float, float]
    hi: tuple[float, float]
    periodic: tuple[bool, bool] = (False, False)

    def __post_init__(self) -> None:
        for ax in range(2):
            if not self.hi[ax] > self.lo[ax]:
                raise ValueError(
                    f"Box: hi[{ax}] = {self.hi[ax]} must be greater than lo[{ax}] = {self.lo[ax]}"
                )

    @property
    def length(self) -> FloatArray:
        return np.asarray(self.hi, float) - np.asarray(self.lo, float)

    @property
    def any_periodic(self) -> bool:
        return any(self.periodic)

    def wrap(self, pos: FloatArray) -> FloatArray:
        """Map positions into the box along periodic axes (in place, returns ``pos``)."""
        for ax in range(2):
            if self.periodic[ax]:
                lo, length = self.lo[ax], self.hi[ax] - self.lo[ax]
                x = np.mod(pos[:, ax] - lo, length)
                # np.mod returns exactly `length` for tiny negative inputs: keep [lo, hi).
                x[x >= length] = 0.0
                pos[:, ax] = lo + x
        return pos

    def minimum_image(self, d: FloatArray) -> FloatArray:
        """Apply the minimum-image convention to separation vectors (in place)."""
        for ax in range(2):
            if self.periodic[ax]:
                length = self.hi[ax] - self.lo[ax]
                d[:, ax] -= length * np.round(d[:, ax] / length)
        return d

    def outside(self, pos: FloatArray, margin: float = 0.0) -> NDArray[np.bool_]:
        """Mask of positions outside the box along non-periodic axes (with a margin)."""
        out = np.zeros(len(pos), dtype=bool)
        for ax in range(2):
            if not self.periodic[ax]:
                out |= (pos[:, ax] < self.lo[ax] - margin) | (pos[:, ax] > self.hi[ax] + margin)
        return out


@dataclass
class Particles:
    """Structure of arrays: ``pos`` and ``vel`` are (N, 2); ``kind`` holds :class:`Kind` values.

    ``fields`` carries named per-particle arrays (a scalar for diffusion, a tag, ...).
    """

    pos: FloatArray
    vel: FloatArray
    kind: NDArray[np.int8]
    pressure: FloatArray
    fields: dict[str, FloatArray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.pos)
        self.pos = np.ascontiguousarray(self.pos, dtype=float).reshape(n, 2)
        self.vel = np.ascontiguousarray(self.vel, dtype=float).reshape(n, 2)
        self.kind = np.ascontiguousarray(self.kind, dtype=np.int8).reshape(n)
        self.pressure = np.ascontiguousarray(self.pressure, dtype=float).reshape(n)
        for name, arr in self.fields.items():
            if len(arr) != n:
                raise ValueError(f"Particles field {name!r} has length {len(arr)}, expected {n}")

    @classmethod
    def from_positions(
        cls, pos: FloatArray, kind: Kind | NDArray[np.int8] = Kind.FLUID
    ) -> Particles:
        pos = np.asarray(pos, dtype=float).reshape(-1, 2)
        n = len(pos)
        if isinstance(kind, Kind):
            kinds = np.full(n, int(kind), np.int8)
        else:  # a copy: the new particles must not share the caller's array
            kinds = np.array(kind, dtype=np.int8).reshape(n)
        return cls(pos.copy(), np.zeros((n, 2)), kinds, np.zeros(n))

    def __len__(self) -> int:
        return len(self.pos)

    @property
    def n(self) -> int:
        return len(self.pos)

    def mask(self, kind: Kind) -> NDArray[np.bool_]:
        return self.kind == int(kind)

    @property
    def fluid(self) -> NDArray[np.bool_]:
        return self.kind == Kind.FLUID

    @property
    def boundary(self) -> NDArray[np.bool_]:
        return self.kind != Kind.FLUID

    def copy(self) -> Particles:
        return Particles(
            self.pos.copy(),
            self.vel.copy(),
            self.kind.copy(),
            self.pressure.copy(),
            {k: v.copy() for k, v in self.fields.items()},
        )

    def subset(self, index: NDArray[np.intp] | NDArray[np.bool_]) -> Particles:
        return Particles(
            self.pos[index],
            self.vel[index],
            self.kind[index],
            self.pressure[index],
            {k: v[index] for k, v in self.fields.items()},
        )

    @staticmethod
    def concat(parts: list[Particles]) -> Particles:
        names = set().union(*(p.fields for p in parts)) if parts else set()
        fields = {
            name: np.concatenate(
                [p.fields.get(name, np.full(p.n, FIELD_FILL.get(name, 0.0))) for p in parts]
            )
            for name in sorted(names)
        }
        return Particles(
            np.concatenate([p.pos for p in parts]),
            np.concatenate([p.vel for p in parts]),
            np.concatenate([p.kind for p in parts]),
            np.concatenate([p.pressure for p in parts]),
            fields,
        )


def block(
    x0: float, y0: float, nx: int, ny: int, l0: float, kind: Kind = Kind.FLUID
) -> Particles:
    """A rectangular block of ``nx`` x ``ny`` particles, cell-centred from corner (x0, y0).

    The first particle sits at (x0 + l0/2, y0 + l0/2), so the block fills [x0, x0 + nx l0).
    """
    if nx < 0 or ny < 0:
        raise ValueError(f"block: nx and ny must be >= 0, got nx={nx}, ny={ny}")
    if not l0 > 0:
        raise ValueError(f"block: l0 must be > 0, got {l0}")
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    pos = np.column_stack([x0 + (ix.ravel() + 0.5) * l0, y0 + (iy.ravel() + 0.5) * l0])
    return Particles.from_positions(pos, kind)


def lattice_in_box(box: Box, l0: float, kind: Kind = Kind.FLUID) -> Particles:
    """Fill a box with a square lattice of spacing ``l0`` (the box must hold a whole number)."""
    counts = box.length / l0
    n = np.rint(counts).astype(int)
    if np.any(np.abs(counts - n) > 1e-9 * np.maximum(n, 1)) or np.any(n < 1):
        raise ValueError(
            f"lattice_in_box: box lengths {tuple(box.length)} are not whole multiples of l0={l0}"
        )
    return block(box.lo[0], box.lo[1], int(n[0]), int(n[1]), l0, kind)


def wall_layers(
    x0: float,
    x1: float,
    y_wall: float,
    l0: float,
    n_wall: int = 1,
    n_dummy: int = 3,
    side: str = "below",
    velocity: tuple[float, float] = (0.0, 0.0),
) -> Particles:
    """Horizontal wall rows spanning [x0, x1): ``n_wall`` wall rows then ``n_dummy`` dummy rows.

    ``y_wall`` is the wall line (the fluid boundary); the first wall row sits l0/2 beyond it on
    ``side`` ("below" or "above"), so a fluid block ending at the wall line keeps spacing l0.
    """
    if side not in ("below", "above"):
        raise ValueError(f"wall_layers: side must be 'below' or 'above', got {side!r}")
    nx = int(round((x1 - x0) / l0))
    sign = -1.0 if side == "below" else 1.0
    rows = []
    for layer in range(n_wall + n_dummy):
        y = y_wall + sign * (layer + 0.5) * l0
        kind = Kind.WALL if layer < n_wall else Kind.DUMMY
        p = Particles.from_positions(
            np.column_stack([x0 + (np.arange(nx) + 0.5) * l0, np.full(nx, y)]), kind
        )
        p.vel[:] = velocity
        _set_wall_geometry(p, (0.0, -sign), (layer + 0.5) * l0)
        rows.append(p)
    return Particles.concat(rows)


def _set_wall_geometry(p: Particles, normal: tuple[float, float], dist: float) -> None:
    p.fields["wall_nx"] = np.full(p.n, normal[0])
    p.fields["wall_ny"] = np.full(p.n, normal[1])
    p.fields["wall_dist"] = np.full(p.n, dist)


def vertical_wall_layers(
    y0: float,
    y1: float,
    x_wall: float,
    l0: float,
    n_wall: int = 1,
    n_dummy: int = 3,
    side: str = "left",
) -> Particles:
    """Vertical wall columns spanning [y0, y1), mirrored version of :func:`wall_layers`."""
    if side not in ("left", "right"):
        raise ValueError(f"vertical_wall_layers: side must be 'left' or 'right', got {side!r}")
    ny = int(round((y1 - y0) / l0))
    sign = -1.0 if side == "left" else 1.0
    cols = []
    for layer in range(n_wall + n_dummy):
        x = x_wall + sign * (layer + 0.5) * l0
        kind = Kind.WALL if layer < n_wall else Kind.DUMMY
        col = Particles.from_positions(
            np.column_stack([np.full(ny, x), y0 + (np.arange(ny) + 0.5) * l0]), kind
        )
        _set_wall_geometry(col, (-sign, 0.0), (layer + 0.5) * l0)
        cols.append(col)
    return Particles.concat(cols)


def tank(
    width: float,
    height: float,
    l0: float,
    n_wall: int = 1,
    n_dummy: int = 3,
) -> Particles:
    """Boundary particles of an open-top tank [0, width] x [0, height]: floor and two side walls.

    Corners are filled so that every wall particle near a corner has a complete support.
    """
    layers = n_wall + n_dummy
    ext = layers * l0
    floor = wall_layers(-ext, width + ext, 0.0, l0, n_wall, n_dummy, "below")
    # Corner blocks below the floor line belong to the floor rows (already included by the
    # extension); side walls start at the floor line.
    left = vertical_wall_layers(0.0, height, 0.0, l0, n_wall, n_dummy, "left")
    right = vertical_wall_layers(0.0, height, width, l0, n_wall, n_dummy, "right")
    # Corner floor particles outside [0, width] are wall or dummy by their distance to the fluid.
    parts = Particles.concat([floor, left, right])
    _reclassify_corners(parts, width, l0, n_wall)
    return parts


def _reclassify_corners(p: Particles, width: float, l0: float, n_wall: int) -> None:
    """Floor particles beyond the side walls: wall if within the wall layers of both walls."""
    x, y = p.pos[:, 0], p.pos[:, 1]
    depth_x = np.maximum(-x, x - width)  # > 0 beyond a side wall
    depth_y = -y
    corner = (depth_x > 0) & (depth_y > 0)
    is_wall = corner & (depth_x < n_wall * l0) & (depth_y < n_wall * l0)
    p.kind[corner] = Kind.DUMMY
    p.kind[is_wall] = Kind.WALL


def jitter(
    p: Particles, amplitude: float, seed: int, where: NDArray[np.bool_] | None = None
) -> None:
    """Displace particles by a seeded uniform random offset in [-amplitude, amplitude]^2."""
    if amplitude < 0:
        raise ValueError(f"jitter: amplitude must be >= 0, got {amplitude}")
    rng = np.random.default_rng(seed)
    mask = p.fluid if where is None else where
    p.pos[mask] += rng.uniform(-amplitude, amplitude, size=(int(mask.sum()), 2))
