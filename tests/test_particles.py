"""Particles container, lattice builders, walls, tank and the periodic Box."""

from __future__ import annotations

import numpy as np
import pytest

from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.operators import lattice_constants, number_density
from mpsbench.physics.particles import (
    UNTAGGED,
    Box,
    Kind,
    Particles,
    block,
    jitter,
    lattice_in_box,
    tank,
    vertical_wall_layers,
    wall_layers,
)
from mpsbench.physics.weights import get_weight


def unique_rows(pos: np.ndarray, l0: float) -> int:
    return len(np.unique(np.round(pos / (0.01 * l0)).astype(np.int64), axis=0))


# --------------------------------------------------------------------------- Box


def test_box_rejects_empty_extent() -> None:
    with pytest.raises(ValueError, match=r"hi\[1\]"):
        Box((0.0, 1.0), (1.0, 1.0))
    with pytest.raises(ValueError, match=r"hi\[0\]"):
        Box((0.0, 0.0), (float("nan"), 1.0))


def test_box_wrap() -> None:
    box = Box((-1.0, 2.0), (1.0, 3.0), (True, False))
    pos = np.array([[1.5, 10.0], [-3.25, 2.5], [1.0, 0.0], [-1.0, 0.0], [0.3, 2.2]])
    out = box.wrap(pos)
    assert out is pos  # in place
    np.testing.assert_allclose(pos[:, 0], [-0.5, 0.75, -1.0, -1.0, 0.3], atol=1e-15)
    np.testing.assert_array_equal(pos[:, 1], [10.0, 2.5, 0.0, 0.0, 2.2])  # y is not periodic


def test_box_wrap_stays_half_open_for_tiny_negative_offsets() -> None:
    box = Box((0.0, 0.0), (1.0, 1.0), (True, True))
    pos = np.array([[-1e-17, -1e-300], [-0.0, 1.0 - 1e-17]])
    box.wrap(pos)
    assert np.all((pos >= 0.0) & (pos < 1.0)), pos


def test_box_minimum_image() -> None:
    box = Box((0.0, 0.0), (2.0, 4.0), (True, True))
    d = np.array([[1.5, -3.0], [-1.2, 1.9], [0.4, 2.1], [5.9, -8.1]])
    box.minimum_image(d)
    np.testing.assert_allclose(d, [[-0.5, 1.0], [0.8, 1.9], [0.4, -1.9], [-0.1, -0.1]], atol=1e-12)
    assert np.all(np.abs(d) <= box.length / 2)
    free = Box((0.0, 0.0), (2.0, 4.0))
    d2 = np.array([[1.5, -3.0]])
    free.minimum_image(d2)
    np.testing.assert_array_equal(d2, [[1.5, -3.0]])


def test_box_outside() -> None:
    box = Box((0.0, 0.0), (1.0, 1.0), (True, False))
    pos = np.array([[5.0, 0.5], [0.5, 1.2], [0.5, -0.05], [0.5, 1.05]])
    np.testing.assert_array_equal(box.outside(pos), [False, True, True, True])
    np.testing.assert_array_equal(box.outside(pos, margin=0.1), [False, True, False, False])
    assert box.any_periodic and not Box((0, 0), (1, 1)).any_periodic
    np.testing.assert_array_equal(box.length, [1.0, 1.0])


# --------------------------------------------------------------------------- Particles


def test_particles_container() -> None:
    p = Particles.from_positions(np.arange(8.0).reshape(4, 2), Kind.WALL)
    assert len(p) == p.n == 4
    assert p.pos.shape == (4, 2) and p.vel.shape == (4, 2) and p.pressure.shape == (4,)
    assert p.kind.dtype == np.int8 and np.all(p.kind == Kind.WALL)
    assert not p.fluid.any() and p.boundary.all() and p.mask(Kind.WALL).all()
    p.fields["phi"] = np.arange(4.0)
    q = p.copy()
    q.pos[0] = 99.0
    q.fields["phi"][0] = 99.0
    assert p.pos[0, 0] == 0.0 and p.fields["phi"][0] == 0.0
    sub = p.subset(np.array([1, 3]))
    np.testing.assert_array_equal(sub.fields["phi"], [1.0, 3.0])
    np.testing.assert_array_equal(sub.pos, [[2.0, 3.0], [6.0, 7.0]])
    kinds = np.array([0, 1, 2, 0], dtype=np.int8)
    r = Particles.from_positions(np.zeros((4, 2)), kinds)
    r.kind[0] = Kind.DUMMY
    assert kinds[0] == 0  # not aliased to the caller's array
    with pytest.raises(ValueError, match="field 'bad' has length 2, expected 4"):
        Particles(p.pos, p.vel, p.kind, p.pressure, {"bad": np.zeros(2)})


def test_concat_fills_missing_fields_with_zeros() -> None:
    a = block(0.0, 0.0, 2, 1, 1.0)
    a.fields["phi"] = np.array([1.0, 2.0])
    b = block(0.0, 5.0, 3, 1, 1.0, Kind.DUMMY)
    c = Particles.concat([a, b])
    assert c.n == 5
    np.testing.assert_array_equal(c.fields["phi"], [1.0, 2.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(c.kind, [0, 0, 2, 2, 2])


def test_concat_leaves_parts_without_a_wall_tag_untagged() -> None:
    # zero is a real tag: a part without the field must not join the walls tagged 0
    walls = block(0.0, 0.0, 2, 1, 1.0, Kind.WALL)
    walls.fields["wall_tag"] = np.zeros(2)
    reservoir = block(0.0, 5.0, 3, 1, 1.0, Kind.INFLOW)
    c = Particles.concat([walls, reservoir])
    np.testing.assert_array_equal(c.fields["wall_tag"], [0.0, 0.0, UNTAGGED, UNTAGGED, UNTAGGED])


# --------------------------------------------------------------------------- builders


def test_block_is_cell_centred() -> None:
    p = block(1.0, 2.0, 3, 2, 0.5)
    assert p.n == 6 and np.all(p.fluid)
    np.testing.assert_allclose(p.pos.min(axis=0), [1.25, 2.25])
    np.testing.assert_allclose(p.pos.max(axis=0), [2.25, 2.75])
    assert unique_rows(p.pos, 0.5) == 6
    assert block(0, 0, 0, 5, 1.0).n == 0
    with pytest.raises(ValueError, match="nx and ny must be >= 0"):
        block(0, 0, -1, 2, 1.0)
    with pytest.raises(ValueError, match="l0 must be > 0"):
        block(0, 0, 1, 2, 0.0)


def test_lattice_in_box() -> None:
    box = Box((0.0, 0.0), (1.0, 0.5), (True, True))
    p = lattice_in_box(box, 0.1)
    assert p.n == 50
    assert np.all(~box.outside(p.pos)) and np.all(p.pos > 0) and np.all(p.pos < box.length)
    with pytest.raises(ValueError, match="not whole multiples of l0=0.3"):
        lattice_in_box(box, 0.3)


def test_wall_layers_rows_and_kinds() -> None:
    w = wall_layers(0.0, 1.0, 0.0, 0.1, n_wall=1, n_dummy=3, side="below", velocity=(2.0, 0.0))
    assert w.n == 40
    ys = np.unique(np.round(w.pos[:, 1], 12))
    np.testing.assert_allclose(ys, [-0.35, -0.25, -0.15, -0.05])
    assert np.all(w.kind[np.isclose(w.pos[:, 1], -0.05)] == Kind.WALL)
    assert np.all(w.kind[w.pos[:, 1] < -0.1] == Kind.DUMMY)
    np.testing.assert_array_equal(w.vel, np.tile([2.0, 0.0], (40, 1)))
    above = wall_layers(0.0, 1.0, 2.0, 0.1, n_wall=2, n_dummy=1, side="above")
    np.testing.assert_allclose(np.unique(np.round(above.pos[:, 1], 12)), [2.05, 2.15, 2.25])
    assert np.count_nonzero(above.kind == Kind.WALL) == 20
    with pytest.raises(ValueError, match="side must be"):
        wall_layers(0.0, 1.0, 0.0, 0.1, side="left")
    with pytest.raises(ValueError, match="side must be"):
        vertical_wall_layers(0.0, 1.0, 0.0, 0.1, side="below")


@pytest.mark.parametrize(("n_wall", "n_dummy"), [(1, 3), (2, 2)])
def test_tank_layout(n_wall: int, n_dummy: int) -> None:
    l0, width, height = 0.1, 1.0, 0.6
    t = tank(width, height, l0, n_wall, n_dummy)
    layers = n_wall + n_dummy
    nx, ny = 10, 6
    assert t.n == (nx + 2 * layers) * layers + 2 * ny * layers
    assert unique_rows(t.pos, l0) == t.n  # no overlaps
    assert not np.any(t.fluid)
    # a wall particle is within n_wall l0 of the fluid region (Chebyshev distance), dummies beyond
    x, y = t.pos[:, 0], t.pos[:, 1]
    depth = np.maximum(np.maximum(-x, x - width), np.maximum(-y, 0.0))
    wall = t.kind == Kind.WALL
    assert np.all(depth[wall] < n_wall * l0) and np.all(depth[~wall] > n_wall * l0)
    assert np.count_nonzero(wall) == n_wall * (nx + 2 * n_wall) + 2 * ny * n_wall


def test_tank_gives_fluid_corners_full_support() -> None:
    """A fluid block in the tank is a perfect lattice near the floor and in the corners."""
    l0, ratio = 0.1, 3.1
    t = tank(1.0, 1.0, l0)
    fluid = block(0.0, 0.0, 10, 8, l0)
    p = Particles.concat([fluid, t])
    re = ratio * l0
    pairs = build_pairs(p.pos, re)
    n = number_density(pairs, get_weight("wf2").w(pairs.r, re))
    n0, _ = lattice_constants("wf2", ratio, l0)
    below_surface = p.fluid & (p.pos[:, 1] < 0.8 - re)
    assert below_surface.sum() == 50
    np.testing.assert_allclose(n[below_surface], n0, rtol=1e-12)


def test_jitter_is_seeded_and_bounded() -> None:
    base = Particles.concat([block(0, 0, 6, 6, 1.0), block(0, -1, 6, 1, 1.0, Kind.WALL)])
    a, b, c = base.copy(), base.copy(), base.copy()
    jitter(a, 0.1, seed=42)
    jitter(b, 0.1, seed=42)
    jitter(c, 0.1, seed=43)
    np.testing.assert_array_equal(a.pos, b.pos)
    assert not np.array_equal(a.pos, c.pos)
    d = a.pos - base.pos
    assert np.all(np.abs(d) <= 0.1) and np.abs(d[a.fluid]).max() > 0.05
    np.testing.assert_array_equal(d[~a.fluid], 0.0)  # walls stay put by default
    e = base.copy()
    jitter(e, 0.2, seed=1, where=np.ones(e.n, bool))
    assert np.all(np.abs(e.pos - base.pos)[~e.fluid].max() > 0)
    f = base.copy()
    jitter(f, 0.0, seed=1)
    np.testing.assert_array_equal(f.pos, base.pos)
    with pytest.raises(ValueError, match="amplitude must be >= 0"):
        jitter(f, -0.1, seed=1)
