"""Pair lists: the cKDTree search against brute force, periodic images, refresh."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mpsbench.physics.neighbours import PairList, brute_force_pairs, build_pairs
from mpsbench.physics.particles import Box

LO = (-0.3, 1.2)
HI = (2.1, 3.0)  # lengths 2.4 and 1.8
BOXES = {
    "free": Box(LO, HI, (False, False)),
    "x-periodic": Box(LO, HI, (True, False)),
    "y-periodic": Box(LO, HI, (False, True)),
    "periodic": Box(LO, HI, (True, True)),
}


def as_set(pl: PairList) -> set[tuple[int, int]]:
    return set(zip(pl.i.tolist(), pl.j.tolist(), strict=True))


def near_cutoff(pos: np.ndarray, box: Box, pairs: set[tuple[int, int]], cutoff: float) -> bool:
    """True when every pair in ``pairs`` is within rounding of the cut-off."""
    for a, b in pairs:
        d = (pos[b] - pos[a])[None, :].copy()
        box.minimum_image(d)
        if abs(float(np.hypot(*d[0])) - cutoff) > 1e-9 * max(cutoff, 1.0):
            return False
    return True


@st.composite
def clouds(draw: st.DrawFn, box_name: str) -> tuple[np.ndarray, Box, float]:
    box = BOXES[box_name]
    n = draw(st.integers(0, 60))
    # coordinates on a 1e-6 grid: coincident particles and pairs at exactly the cut-off stay
    # likely, absurd separations such as 1e-300 (which underflow when squared) do not
    ticks = draw(arrays(np.int64, (n, 2), elements=st.integers(0, 10**6 - 1)))
    pos = np.asarray(box.lo) + ticks * 1e-6 * box.length
    if any(box.periodic):
        # particles may sit outside the box along periodic axes (not wrapped yet)
        shift = draw(arrays(np.int64, (n, 2), elements=st.integers(-2, 2)))
        pos = pos + shift * box.length * np.asarray(box.periodic)
        half = 0.5 * min(box.length[ax] for ax in range(2) if box.periodic[ax])
    else:
        half = 2.0
    cutoff = draw(st.floats(0.01, 0.999 * half))
    return pos, box, cutoff


def check_equivalent(pos: np.ndarray, box: Box, cutoff: float) -> None:
    pl = build_pairs(pos, cutoff, box)
    got, want = as_set(pl), brute_force_pairs(pos, cutoff, box)
    assert near_cutoff(pos, box, got ^ want, cutoff), sorted(got ^ want)[:5]
    # half list: i < j, each pair once, sorted by i
    assert np.all(pl.i < pl.j)
    assert len(got) == len(pl)
    assert np.all(np.diff(pl.i) >= 0)
    # stored separations are the minimum images r_j - r_i
    d = pos[pl.j] - pos[pl.i]
    box.minimum_image(d)
    np.testing.assert_allclose(pl.dx, d, atol=1e-12)
    np.testing.assert_allclose(pl.r, np.hypot(d[:, 0], d[:, 1]), atol=1e-12)
    assert np.all(pl.r <= cutoff * (1 + 1e-9))
    assert pl.n == len(pos) and pl.cutoff == cutoff


@given(clouds("free"))
def test_free_box_matches_brute_force(case: tuple[np.ndarray, Box, float]) -> None:
    check_equivalent(*case)


@given(clouds("x-periodic"))
def test_x_periodic_box_matches_brute_force(case: tuple[np.ndarray, Box, float]) -> None:
    check_equivalent(*case)


@given(clouds("y-periodic"))
def test_y_periodic_box_matches_brute_force(case: tuple[np.ndarray, Box, float]) -> None:
    check_equivalent(*case)


@given(clouds("periodic"))
def test_fully_periodic_box_matches_brute_force(case: tuple[np.ndarray, Box, float]) -> None:
    check_equivalent(*case)


def test_free_box_argument_is_optional() -> None:
    rng = np.random.default_rng(0)
    pos = rng.random((80, 2))
    assert as_set(build_pairs(pos, 0.2)) == as_set(build_pairs(pos, 0.2, BOXES["free"]))
    assert as_set(build_pairs(pos, 0.2)) == brute_force_pairs(pos, 0.2)


def test_periodic_pairs_cross_the_seam() -> None:
    box = Box((0.0, 0.0), (1.0, 1.0), (True, False))
    pos = np.array([[0.05, 0.5], [0.95, 0.5], [0.5, 0.5]])
    pl = build_pairs(pos, 0.2, box)
    assert as_set(pl) == {(0, 1)}
    np.testing.assert_allclose(pl.dx[0], [-0.1, 0.0], atol=1e-15)
    # not across a non-periodic axis
    pos_y = np.array([[0.5, 0.05], [0.5, 0.95]])
    assert len(build_pairs(pos_y, 0.2, box)) == 0


def test_lattice_neighbours_at_exactly_the_cutoff_are_kept() -> None:
    """r_e/l0 = 4 on a lattice with l0 = 0.02: 4 * 0.02 rounds above 0.08 for some pairs."""
    l0 = 0.02
    ix, iy = np.meshgrid(np.arange(15), np.arange(15), indexing="ij")
    pos = np.column_stack([(ix.ravel() + 0.5) * l0 + 0.3, (iy.ravel() + 0.5) * l0 + 0.7])
    pl = build_pairs(pos, 4 * l0)
    centre = 7 * 15 + 7
    count = np.count_nonzero(pl.i == centre) + np.count_nonzero(pl.j == centre)
    assert count == 48  # all lattice points with 0 < r <= 4 l0


@pytest.mark.parametrize("box_name", list(BOXES))
def test_refresh_equals_rebuild(box_name: str) -> None:
    box = BOXES[box_name]
    rng = np.random.default_rng(3)
    pos = np.asarray(box.lo) + rng.random((150, 2)) * box.length
    re, skin = 0.3, 0.1
    pl = build_pairs(pos, re + skin, box)
    moved = pos + rng.uniform(-1, 1, pos.shape) * (0.49 * skin / np.sqrt(2))
    pl.refresh(moved, box)
    fresh = build_pairs(moved, re, box)
    kept = pl.within(re)
    assert as_set(kept) == as_set(fresh)
    order_kept = np.lexsort((kept.j, kept.i))
    order_fresh = np.lexsort((fresh.j, fresh.i))
    np.testing.assert_allclose(kept.dx[order_kept], fresh.dx[order_fresh], atol=1e-14)
    np.testing.assert_allclose(kept.r[order_kept], fresh.r[order_fresh], atol=1e-14)
    # refreshing with the same pairs of a list built at re + skin is a superset of the rebuild
    assert as_set(fresh) <= as_set(pl)


@pytest.mark.parametrize("n", [0, 1])
def test_empty_and_single_particle(n: int) -> None:
    pos = np.zeros((n, 2))
    for box in (None, *BOXES.values()):
        pl = build_pairs(pos, 0.5, box)
        assert len(pl) == 0 and pl.n == n
        assert pl.dx.shape == (0, 2) and pl.r.shape == (0,)
        np.testing.assert_array_equal(pl.sum_sym(np.zeros(0)), np.zeros(n))
        assert brute_force_pairs(pos, 0.5, box) == set()


def test_no_pairs_within_cutoff() -> None:
    pl = build_pairs(np.array([[0.0, 0.0], [5.0, 5.0]]), 1.0)
    assert len(pl) == 0 and pl.i.dtype == np.intp


def test_coincident_particles_are_a_pair() -> None:
    pl = build_pairs(np.array([[0.2, 0.2], [0.2, 0.2]]), 0.1)
    assert as_set(pl) == {(0, 1)} and pl.r[0] == 0.0


@pytest.mark.parametrize("box_name", ["x-periodic", "y-periodic", "periodic"])
def test_cutoff_must_be_below_half_period(box_name: str) -> None:
    box = BOXES[box_name]
    half = 0.5 * min(box.length[ax] for ax in range(2) if box.periodic[ax])
    pos = np.asarray(box.lo) + np.random.default_rng(1).random((10, 2)) * box.length
    with pytest.raises(ValueError, match="half the periodic length"):
        build_pairs(pos, half, box)
    build_pairs(pos, 0.99 * half, box)  # just below is fine


@pytest.mark.parametrize("cutoff", [0.0, -1.0, float("nan")])
def test_cutoff_must_be_positive(cutoff: float) -> None:
    with pytest.raises(ValueError, match="cutoff must be > 0"):
        build_pairs(np.zeros((3, 2)), cutoff)


def test_scatter_helpers() -> None:
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    pl = build_pairs(pos, 3.0)
    assert as_set(pl) == {(0, 1), (0, 2), (1, 2)}
    v = np.array([1.0, 2.0, 4.0])  # pairs (0,1), (0,2), (1,2)
    np.testing.assert_array_equal(pl.sum_sym(v), [3.0, 5.0, 6.0])
    np.testing.assert_array_equal(pl.sum_antisym(v), [3.0, 3.0, -6.0])
    vv = np.column_stack([v, -v])
    np.testing.assert_array_equal(pl.sum_vec_sym(vv), np.column_stack([[3, 5, 6], [-3, -5, -6]]))
    np.testing.assert_array_equal(
        pl.sum_vec_antisym(vv), np.column_stack([[3, 3, -6], [-3, -3, 6]])
    )
    phi = np.array([10.0, 20.0, 40.0])
    np.testing.assert_array_equal(pl.diff(phi), [10.0, 30.0, 20.0])
    ii, jj, dx = pl.directed()
    assert len(ii) == 6
    np.testing.assert_array_equal(dx, pos[jj] - pos[ii])
