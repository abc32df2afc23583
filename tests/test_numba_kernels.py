"""The numba compute layer against the numpy reference operators (mpsbench.physics).

Jittered clouds in free, x-periodic and periodic boxes; both weights; several radii; every
registered Laplacian and pressure gradient, each kernel built by its factory from the model's own
formulas.  One CSR list built at the largest radius plus a skin serves every radius, as in a
solver.  Agreement is held to 1e-10 relative (to the largest value of each result); pair lists
must be identical.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from mpsbench.physics import operators as ops
from mpsbench.physics.gradients import GRADIENTS, get_gradient
from mpsbench.physics.laplacians import LAPLACIANS, get_laplacian
from mpsbench.physics.neighbours import PairList, build_pairs
from mpsbench.physics.particles import Box, Kind
from mpsbench.physics.weights import get_weight

numba = pytest.importorskip("numba")
_backend = pytest.importorskip("mpsbench.solvers.numba_backend")
cells, kernels, formulas = _backend.cells, _backend.kernels, _backend.formulas
geometry, neighbour_list = _backend.geometry, _backend.neighbour_list
ALL_ROWS = np.zeros(0, dtype=np.bool_)
NO_ROWS = np.empty(0)


def compiled_weight(name: str):
    return formulas.weight(get_weight(name))

RTOL = 1e-10
L0 = 0.1
SIDE = 16  # particles per side
RADII = (2.1, 3.1, 4.0)
SKIN = 0.3 * L0
BOXES = {
    "free": (False, False),
    "x-periodic": (True, False),
    "periodic": (True, True),
}


def close(actual: np.ndarray, expected: np.ndarray) -> None:
    scale = float(np.max(np.abs(expected))) if expected.size else 0.0
    np.testing.assert_allclose(actual, expected, rtol=RTOL, atol=RTOL * scale)


def cloud(periodic: tuple[bool, bool], seed: int = 0, jitter: float = 0.1):
    rng = np.random.default_rng(seed)
    ix, iy = np.meshgrid(np.arange(SIDE), np.arange(SIDE), indexing="ij")
    pos = np.column_stack([(ix.ravel() + 0.5) * L0, (iy.ravel() + 0.5) * L0])
    pos += rng.uniform(-jitter * L0, jitter * L0, pos.shape)
    box = Box((0.0, 0.0), (SIDE * L0, SIDE * L0), periodic)
    box.wrap(pos)
    n = len(pos)
    fields = {
        "phi": np.sin(2 * np.pi * pos[:, 0]) * np.cos(3 * np.pi * pos[:, 1])
        + 0.1 * rng.normal(size=n),
        "p": np.abs(rng.normal(size=n)) * 1e3,
        "u": rng.normal(size=(n, 2)),
    }
    return pos, box, fields


@pytest.fixture(scope="module", params=list(BOXES))
def case(request):
    pos, box, fields = cloud(BOXES[request.param])
    csr = cells.build_csr(pos, max(RADII) * L0 + SKIN, box)
    return request.param, pos, box, fields, csr


def args(csr, pos, box):
    return csr.offsets, csr.nbr, pos, geometry.box_period(box)


# --------------------------------------------------------------------------- pair lists


@pytest.mark.parametrize("name", list(BOXES))
@pytest.mark.parametrize("cutoff", [0.21, 0.31, 0.43, 0.7])
@pytest.mark.parametrize("reach", [1, 2, 3])
def test_pair_list_equals_build_pairs(name, cutoff, reach):
    pos, box, _ = cloud(BOXES[name], seed=3)
    ref = build_pairs(pos, cutoff, box)
    got = neighbour_list.csr_to_pairs(cells.build_csr(pos, cutoff, box, reach=reach), pos)
    assert len(got) == len(ref) > 0
    for attr in ("i", "j", "dx", "r"):
        np.testing.assert_array_equal(getattr(got, attr), getattr(ref, attr), err_msg=attr)


def test_pair_list_with_unwrapped_positions():
    pos, box, _ = cloud((True, True), seed=4)
    shifted = pos.copy()
    rng = np.random.default_rng(5)
    shifted += rng.integers(-2, 3, size=pos.shape) * SIDE * L0  # images up to two periods away
    ref = build_pairs(shifted, 0.31, box)
    got = neighbour_list.build_pairs_cells(shifted, 0.31, box)
    for attr in ("i", "j", "dx", "r"):
        np.testing.assert_array_equal(getattr(got, attr), getattr(ref, attr), err_msg=attr)


def test_csr_rows_hold_both_directions(case):
    _, pos, box, _, csr = case
    ref = build_pairs(pos, csr.cutoff, box)
    ii, jj, dx = ref.directed()
    assert len(csr) == len(ii)
    got = csr.rows() * len(pos) + csr.nbr
    np.testing.assert_array_equal(np.sort(got), np.sort(ii * len(pos) + jj))
    csr.fill_geometry(pos)
    order = np.argsort(ii * len(pos) + jj)
    mine = np.argsort(got)
    np.testing.assert_array_equal(csr.dx[mine], dx[order])


def test_small_and_degenerate_inputs():
    assert len(neighbour_list.build_pairs_cells(np.zeros((0, 2)), 1.0)) == 0
    assert len(neighbour_list.build_pairs_cells(np.zeros((1, 2)), 1.0)) == 0
    csr = cells.build_csr(np.zeros((0, 2)), 1.0)
    assert csr.offsets.tolist() == [0] and len(csr) == 0
    # one far-away particle must not blow up the grid or lose pairs
    pos, box, _ = cloud((False, False), seed=6)
    pos = np.vstack([pos, [[1e7, -3e6]]])
    got = neighbour_list.build_pairs_cells(pos, 0.31)
    np.testing.assert_array_equal(got.i, build_pairs(pos, 0.31).i)
    with pytest.raises(ValueError, match="half the periodic length"):
        cells.build_csr(pos[:-1], 0.9, Box((0, 0), (1.6, 1.6), (True, True)))


def test_static_pairs_are_left_out():
    pos, box, _ = cloud((True, False), seed=7)
    static = pos[:, 1] < 0.4
    csr = cells.build_csr(pos, 0.31, box, static=static)
    ref = build_pairs(pos, 0.31, box)
    keep = ~(static[ref.i] & static[ref.j])
    assert len(csr) == 2 * int(keep.sum())


def test_skinned_list_rebuilds_only_when_needed():
    pos, box, fields = cloud((True, True), seed=8)
    re = 3.1 * L0
    nl = neighbour_list.CellNeighbourList(re, SKIN, box)
    assert nl.update(pos) and nl.builds == 1
    rng = np.random.default_rng(9)
    moved = pos + rng.uniform(-0.2, 0.2, pos.shape) * SKIN  # |d| < skin/2
    moved[0] += SIDE * L0  # a particle wrapped through the box is not a move
    assert not nl.update(moved)
    assert nl.csr is not None
    wf, period = get_weight("wf2"), geometry.box_period(box)
    pl = build_pairs(moved, re, box)
    got = kernels.number_density(compiled_weight("wf2"))(
        nl.csr.offsets, nl.csr.nbr, moved, period, re, np.empty(len(pos))
    )
    close(got, ops.number_density(pl, wf.w(pl.r, re)))
    moved[5] += 0.6 * SKIN
    assert nl.update(moved) and nl.builds == 2
    assert nl.update(moved[:-1]) and nl.builds == 3  # particle count changed


def _rows(csr, ids=None):
    """Every row's neighbours as a set of ids (``ids`` maps the list's indices)."""
    ids = np.arange(csr.n) if ids is None else ids
    return [set(ids[csr.nbr[csr.offsets[i]:csr.offsets[i + 1]]].tolist()) for i in range(csr.n)]


@pytest.mark.parametrize("serial", [False, True])
def test_compacting_the_list_equals_building_it_without_the_dropped(serial):
    """``compact`` after particles left: the same rows as a list built from the build positions
    of the particles kept (dropping particles only removes pairs), the sub-list too, renumbered,
    still valid for the same moves; a dropped member of a rigid group refuses it."""
    pos, box, _ = cloud((True, False), seed=3)
    re = 3.1 * L0
    nl = neighbour_list.CellNeighbourList(re, SKIN, box, r_small=2.1 * L0, serial=serial)
    group = np.full(len(pos), -1, np.int64)
    group[:7] = 0  # a rigid group (its pairs are static): dropping one of it needs a rebuild
    nl.set_static(group=group, loose=np.zeros(len(pos), bool))
    nl.build(pos)
    keep = np.random.default_rng(4).uniform(size=len(pos)) > 0.1
    keep[:7] = True
    fresh = neighbour_list.CellNeighbourList(re, SKIN, box, r_small=2.1 * L0)
    fresh.set_static(group=group[keep], loose=np.zeros(int(keep.sum()), bool))
    fresh.build(pos[keep])
    assert nl.compact(keep)
    assert nl.csr is not None and nl.small is not None and fresh.csr is not None
    assert nl.csr.n == int(keep.sum()) and len(nl.csr) == len(fresh.csr)
    assert _rows(nl.csr) == _rows(fresh.csr)
    assert fresh.small is not None and _rows(nl.small) == _rows(fresh.small)
    assert sorted(nl.csr.order.tolist()) == list(range(nl.csr.n))
    assert nl.group is not None and np.array_equal(nl.group, group[keep])
    assert nl.valid_after(0.4 * SKIN, nl.csr.n) and not nl.valid_after(0.6 * SKIN, nl.csr.n)
    assert not nl.update(pos[keep]) and nl.builds == 1
    drop_rigid = np.ones(nl.csr.n, bool)
    drop_rigid[2] = False
    assert not nl.compact(drop_rigid) and nl.csr.n == int(keep.sum())


# --------------------------------------------------------------------------- operators


def test_weights_match_reference():
    """The compiled formulas are the numpy ones: W, W', W'' inside the support."""
    r = np.linspace(0.0, 0.31, 101)[1:]
    re = 0.31
    for name in ("wf1", "wf2"):
        wf, support = get_weight(name), formulas.support(compiled_weight(name))
        got = np.array([support(x, re) for x in r])
        for k, ref in enumerate((wf.w, wf.dw, wf.d2w)):
            close(got[:, k], ref(r, re))


@pytest.mark.parametrize("wname", ["wf1", "wf2"])
@pytest.mark.parametrize("rr", RADII)
def test_density_gradient_divergence(case, wname, rr):
    _, pos, box, f, csr = case
    re, wf, wt = rr * L0, get_weight(wname), compiled_weight(wname)
    n0, _ = ops.lattice_constants(wf, rr, L0)
    pl = build_pairs(pos, re, box)
    w = wf.w(pl.r, re)
    a, n = args(csr, pos, box), len(pos)
    close(kernels.number_density(wt)(*a, re, np.empty(n)), ops.number_density(pl, w))
    close(
        kernels.gradient(wt)(*a, f["phi"], re, ops.DIM / n0, np.empty((n, 2))),
        ops.gradient(pl, f["phi"], w, n0),
    )
    close(
        kernels.divergence(wt)(*a, f["u"], re, ops.DIM / n0, np.empty(n)),
        ops.divergence(pl, f["u"], w, n0),
    )


@pytest.mark.parametrize("gname", GRADIENTS.names())
@pytest.mark.parametrize("wname", ["wf1", "wf2"])
@pytest.mark.parametrize("rr", RADII)
def test_pressure_gradients(case, gname, wname, rr):
    _, pos, box, f, csr = case
    re, wf, wt = rr * L0, get_weight(wname), compiled_weight(wname)
    model = get_gradient(gname)
    grad = formulas.gradient(model)
    n0, _ = ops.lattice_constants(wf, rr, L0)
    a, n, p = args(csr, pos, box), len(pos), f["p"]
    # a mask that leaves particles out (the reference solver drops dummy particles this way)
    mask = np.random.default_rng(11).random(n) > 0.2
    for m in (np.ones(n, bool), mask):
        full = build_pairs(pos, re, box)
        keep = m[full.i] & m[full.j]
        pl = PairList(full.i[keep], full.j[keep], full.dx[keep], full.r[keep], n, re)
        w = wf.w(pl.r, re)
        pmin = kernels.neighbour_min(wt)(*a, p, m, re, np.empty(n))
        close(pmin, ops.neighbour_min(pl, p, w))
        ref = model(pl, p, w, n0)
        ref[~m] = 0.0
        got = kernels.pressure_gradient(wt, grad)(
            *a, p, pmin, m, re, model.prefactor(n0), np.empty((n, 2)), ALL_ROWS
        )
        close(got, ref)


def _laplacians() -> list[tuple[str, bool]]:
    return [(name, False) for name in LAPLACIANS.names()] + [("xu-jin", True)]


def laplacian_kernel(lname, gcorr, wname, rr, csr, pos, box, phi, rowsum=NO_ROWS):
    """The row kernel's Laplacian of ``phi`` (n,) or (n, 2), as a solver calls it."""
    re, wf, wt = rr * L0, get_weight(wname), compiled_weight(wname)
    n0, lam = ops.lattice_constants(wf, rr, L0)
    model = get_laplacian(lname, gradient_correction=gcorr)
    lap = formulas.laplacian(model)
    a, n = args(csr, pos, box), len(pos)
    s = kernels.NO_MOMENT
    if lap.has_moment:
        s = kernels.moments(wt, lap)(*a, re, np.empty(n))
    field = np.ascontiguousarray(phi.reshape(n, -1))
    out = np.empty_like(field)
    kernels.laplacian_field(wt, lap)(
        *a, field, re, model.prefactor(n0, lam), s, ops.DIM / n0, gcorr, out, rowsum, ALL_ROWS
    )
    return out.reshape(phi.shape)


@pytest.mark.parametrize("lname,gcorr", _laplacians())
@pytest.mark.parametrize("wname", ["wf1", "wf2"])
@pytest.mark.parametrize("rr", RADII)
def test_laplacians(case, lname, gcorr, wname, rr):
    _, pos, box, f, csr = case
    re, wf = rr * L0, get_weight(wname)
    n0, lam = ops.lattice_constants(wf, rr, L0)
    model = get_laplacian(lname, gradient_correction=gcorr)
    pl = build_pairs(pos, re, box)
    n = len(pos)
    got = laplacian_kernel(lname, gcorr, wname, rr, csr, pos, box, f["phi"])
    close(got, model.apply(pl, f["phi"], wf, re, n0, lam))
    rows = np.empty(n)
    got = laplacian_kernel(lname, gcorr, wname, rr, csr, pos, box, f["u"], rows)
    close(got, model.apply(pl, f["u"], wf, re, n0, lam))
    c = model.coefficients(pl, wf, re, n0, lam)
    close(rows, pl.sum_sym(np.abs(c)))


# ---------------------------------------------------------------- collision, stabilization


def _kinds(pos):
    kind = np.full(len(pos), Kind.FLUID, np.int8)
    kind[pos[:, 1] < 0.25] = Kind.WALL
    kind[pos[:, 1] < 0.15] = Kind.DUMMY
    return kind


def collision_numpy(pl, vel, kind, distance, e, wall_share):
    """Pair-list form of Lee et al. (2011), as written for the reference backend."""
    fi, fj = kind[pl.i] == Kind.FLUID, kind[pl.j] == Kind.FLUID
    approach = ((vel[pl.i] - vel[pl.j]) * pl.dx).sum(axis=1)
    act = (pl.r < distance) & (fi | fj) & (approach > 0)
    share_i = np.where(fj, 0.5, wall_share)[act]
    share_j = np.where(fi, 0.5, wall_share)[act]
    imp = ((1.0 + e) * approach[act] / pl.r[act] ** 2)[:, None] * pl.dx[act]
    out = np.zeros_like(vel)
    for ax in range(2):
        out[:, ax] -= np.bincount(pl.i[act], share_i * imp[:, ax], len(vel))
        out[:, ax] += np.bincount(pl.j[act], share_j * imp[:, ax], len(vel))
    out[kind != Kind.FLUID] = 0.0
    return out


def stabilization_numpy(pl, vel, kind, inner, with_walls, wf, re, n0, l0, alpha_s):
    use = np.ones(len(pl), bool)
    if not with_walls:
        use = (kind[pl.i] == Kind.FLUID) & (kind[pl.j] == Kind.FLUID)
    dw = np.where(use, wf.dw(pl.r, re), 0.0)
    du = pl.diff(vel)
    out = np.column_stack([pl.sum_antisym(dw * du[:, ax]) for ax in range(2)])
    out *= -alpha_s * l0 / n0
    out[~inner] = 0.0
    return out


@pytest.mark.parametrize("wall_share", [1.0, 0.5])
def test_collision(case, wall_share):
    _, _, box, f, _ = case
    pos, _, _ = cloud(box.periodic, seed=12, jitter=0.3)  # some pairs closer than 0.8 l0
    csr = cells.build_csr(pos, 2.1 * L0, box)
    kind = _kinds(pos)
    vel = f["u"].copy()
    vel[kind != Kind.FLUID] = (0.3, 0.0)
    dist, e = 0.8 * L0, 0.2
    pl = build_pairs(pos, dist, box)
    ref = collision_numpy(pl, vel, kind, dist, e, wall_share)
    assert np.count_nonzero(ref[:, 0]) > 10
    got = kernels.collision(
        *args(csr, pos, box), vel, kind, dist, e, wall_share, np.empty_like(vel)
    )
    close(got, ref)


@pytest.mark.parametrize("with_walls", [True, False])
@pytest.mark.parametrize("wname", ["wf1", "wf2"])
def test_stabilization(case, with_walls, wname):
    _, pos, box, f, csr = case
    re, wf = 2.1 * L0, get_weight(wname)
    factor = ops.STABILIZATION.prefactor(0.01, L0, ops.lattice_constants(wf, 2.1, L0)[0])
    n0, _ = ops.lattice_constants(wf, 2.1, L0)
    kind = _kinds(pos)
    vel = f["u"].copy()
    vel[kind != Kind.FLUID] = (0.3, 0.0)
    inner = (kind == Kind.FLUID) & (pos[:, 1] < 1.3)  # the top rows play the free surface
    pl = build_pairs(pos, re, box)
    ref = stabilization_numpy(pl, vel, kind, inner, with_walls, wf, re, n0, L0, 0.01)
    got = kernels.stabilization(compiled_weight(wname))(
        *args(csr, pos, box), vel, kind, inner, with_walls, re, factor, np.empty_like(vel)
    )
    close(got, ref)


# --------------------------------------------------------------------------- oracle, threads


@pytest.mark.parametrize("wname,rr,n0_expected", [("wf1", 3.1, 18.9764), ("wf2", 2.1, 0.7146)])
def test_lattice_number_density_oracle(wname, rr, n0_expected):
    pos, box = ops.lattice_pairs(12, L0)
    csr = cells.build_csr(pos, rr * L0, box)
    n = kernels.number_density(compiled_weight(wname))(
        *args(csr, pos, box), rr * L0, np.empty(len(pos))
    )
    np.testing.assert_allclose(n, n0_expected, atol=5e-5)


def test_results_do_not_depend_on_thread_count():
    pos, box, f = cloud((True, False), seed=13)
    re, n = 3.1 * L0, len(pos)
    wt = compiled_weight("wf2")
    lap = formulas.laplacian(get_laplacian("xu-jin"))
    grad = formulas.gradient(get_gradient("pgm1"))
    before = numba.get_num_threads()
    results = []
    try:
        for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(threads)
            csr = cells.build_csr(pos, re + SKIN, box)
            a = args(csr, pos, box)
            mask = np.ones(n, bool)
            pmin = kernels.neighbour_min(wt)(*a, f["p"], mask, re, np.empty(n))
            results.append(
                [
                    csr.offsets,
                    csr.nbr,
                    kernels.number_density(compiled_weight("wf1"))(*a, re, np.empty(n)),
                    kernels.laplacian_field(wt, lap)(
                        *a, f["u"], re, 1.0, kernels.NO_MOMENT, 1.0, True, np.empty((n, 2)),
                        np.empty(n), ALL_ROWS,
                    ),
                    kernels.pressure_gradient(wt, grad)(
                        *a, f["p"], pmin, mask, re, 1.0, np.empty((n, 2)), ALL_ROWS
                    ),
                ]
            )
    finally:
        numba.set_num_threads(before)
    for x, y in zip(results[0], results[-1], strict=True):
        np.testing.assert_array_equal(x, y)


def test_import_without_numba_names_the_extra(monkeypatch):
    import importlib
    import sys

    for name in [m for m in sys.modules if m.startswith("mpsbench.solvers.numba_backend")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "numba", None)
    with pytest.raises(
        ImportError, match=r"numba is not installed: pip install 'mpsbench\[fast\]'"
    ):
        importlib.import_module("mpsbench.solvers.numba_backend")


def test_kernel_kind_codes_match_the_particle_kinds() -> None:
    """The kernels compare kinds with plain ints; they must be mpsbench.physics.particles.Kind's."""
    for name in ("FLUID", "WALL", "DUMMY", "INFLOW"):
        assert getattr(formulas, name) == int(getattr(Kind, name)), name


# --------------------------------------------------------------------------- models from outside


PLUGIN_SRC = Path(__file__).resolve().parents[1] / "examples" / "plugin" / "src"


@pytest.fixture
def ko_local(monkeypatch: pytest.MonkeyPatch):
    """The example plugin's ko-local Laplacian, registered for the test."""
    monkeypatch.syspath_prepend(str(PLUGIN_SRC))
    from mpsbench_example.laplacian import LocalKoshizukaOka

    saved = LAPLACIANS._entries.get("ko-local")
    LAPLACIANS.register("ko-local", LocalKoshizukaOka, replace=True, origin="user")
    yield LocalKoshizukaOka
    LAPLACIANS.unregister("ko-local")
    if saved is not None:
        LAPLACIANS._entries["ko-local"] = saved


@pytest.mark.parametrize("wname", ["wf1", "wf2"])
@pytest.mark.parametrize("rr", [2.1, 3.1])
def test_a_plugin_laplacian_with_a_moment_runs_in_the_kernels(case, ko_local, wname, rr):
    """ko-local (c_ij = 2D W_ij / mean(S_i, S_j), S_i = sum_j W r^2): the row kernel, the
    moments and the diffusion entries against the numpy evaluation of the same class."""
    _, pos, box, f, csr = case
    re, wf = rr * L0, get_weight(wname)
    n0, lam = ops.lattice_constants(wf, rr, L0)
    model = get_laplacian("ko-local")
    pl = build_pairs(pos, re, box)
    want = model.apply(pl, f["u"], wf, re, n0, lam)
    n = len(pos)
    rows = np.empty(n)
    close(laplacian_kernel("ko-local", False, wname, rr, csr, pos, box, f["u"], rows), want)
    close(rows, pl.sum_sym(np.abs(model.coefficients(pl, wf, re, n0, lam))))
    # the moments S_i the flow step computes first (kernels.moments)
    wt, lap = compiled_weight(wname), formulas.laplacian(model)
    s = np.empty(n)
    kernels.moments(wt, lap)(*args(csr, pos, box), re, s)
    close(s, pl.sum_sym(wf.w(pl.r, re) * pl.r**2))


def test_a_weight_defined_here_compiles_into_the_kernels():
    """A weighting function that is not a built-in (a plugin's): the kernels use its formulas."""
    from mpsbench.physics.weights import WeightFunction

    class Quartic(WeightFunction):
        name = "test-quartic"

        @staticmethod
        def w_inside(r, re):
            return (1 - r / re) ** 4

        @staticmethod
        def dw_inside(r, re):
            return -4 / re * (1 - r / re) ** 3

        @staticmethod
        def d2w_inside(r, re):
            return 12 / re**2 * (1 - r / re) ** 2

    pos, box, f = cloud((True, True), seed=21)
    re = 3.1 * L0
    csr = cells.build_csr(pos, re, box)
    wf = Quartic()
    pl = build_pairs(pos, re, box)
    got = kernels.number_density(formulas.weight(wf))(*args(csr, pos, box), re,
                                                      np.empty(len(pos)))
    close(got, ops.number_density(pl, wf.w(pl.r, re)))


def test_kernels_of_different_models_have_different_cache_keys():
    """The disk cache keys a kernel by what its code depends on (the models' formulas
    included), not by numba's pickle of the closure, which differs in every process."""
    from mpsbench.solvers.numba_backend._jit import fingerprint

    wf1 = kernels.number_density(compiled_weight("wf1"))
    wf2 = kernels.number_density(compiled_weight("wf2"))
    assert wf1 is kernels.number_density(compiled_weight("wf1"))  # one build per model
    keys = {fingerprint(k.py_func) for k in (wf1, wf2, wf1.serial, wf2.serial)}
    assert len(keys) == 4
    assert fingerprint(wf1.py_func) == fingerprint(wf1.py_func)


_CACHE_PROBE = textwrap.dedent(
    """
    import sys
    import numpy as np
    from mpsbench.physics.weights import get_weight
    from mpsbench.solvers.numba_backend import cells, formulas, geometry, kernels

    pos = np.random.default_rng(0).uniform(0.0, 1.0, (200, 2))
    csr = cells.build_csr(pos, 0.2)
    fn = kernels.number_density(formulas.weight(get_weight("wf2"))).serial
    fn(csr.offsets, csr.nbr, pos, geometry.box_period(None), 0.2, np.empty(200))
    print(sum(fn.stats.cache_hits.values()), sum(fn.stats.cache_misses.values()))
    """
)


def test_model_kernels_load_from_the_disk_cache_in_a_new_process(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    runs = [
        subprocess.run([sys.executable, "-c", _CACHE_PROBE], capture_output=True, text=True,
                       env=env, timeout=300, check=True).stdout.split()
        for _ in range(2)
    ]
    assert runs[0] == ["0", "1"], runs  # compiled and saved
    assert runs[1] == ["1", "0"], runs  # loaded: no compilation in the second process


def test_compile_watch_counts_compilations_not_calls_of_compiled_code():
    """What the solver reports as its JIT time (timings['jit_compile_s'], compile_times)."""
    from mpsbench.solvers.numba_backend._jit import watch_compiles

    @numba.njit
    def plus_one(x):
        return x + 1

    with watch_compiles() as watch:
        assert plus_one(1) == 2
    assert watch.kernels == 1 and watch.seconds > 0.0
    assert list(watch.each) == [plus_one.py_func.__qualname__]
    with watch_compiles() as again:
        assert plus_one(2) == 3
    assert again.kernels == 0 and again.seconds == 0.0


def test_the_compile_time_is_a_counter_and_a_record_column():
    """validate's ETA leaves a record's compile_s out of its case's rate (results/progress.py)."""
    from mpsbench.solvers.numba_backend import NumbaSolver

    from mpsbench.results.records import solver_counters
    from mpsbench.run.runner import run
    from mpsbench.testing import problems

    solver = NumbaSolver(threads=1)
    result = run(solver, problems.dam_break_problem(l0=0.02), max_steps=2)
    assert result.ok, result.reason
    assert result.counters["compile_s"] == solver.timings["jit_compile_s"] >= 0.0
    assert solver_counters([result, result])["compile_s"] == pytest.approx(
        2 * solver.timings["jit_compile_s"], abs=1e-6)
