"""MPS operators against the lattice oracles of docs/method.md (sections 1-3) and exact
identities."""

from __future__ import annotations

import numpy as np
import pytest

from mpsbench.physics.gradients import GRADIENTS, get_gradient, pgm1, pgm2, pgm3
from mpsbench.physics.laplacians import LAPLACIANS, get_laplacian
from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.operators import (
    divergence,
    gradient,
    gradient_matrix,
    interior_index,
    lattice_constants,
    lattice_pairs,
    number_density,
    particle_constants,
)
from mpsbench.physics.particles import block
from mpsbench.physics.weights import get_weight
from mpsbench.registry import UnknownNameError
from tests.helpers import free_lattice, interior_mask

RATIOS = (2.1, 2.5, 3.1, 3.5, 4.0)

# docs/method.md section 1: (neighbours, WF1 n0, WF1 lambda, WF2 n0, WF2 lambda), l0 = 1.
N0_LAMBDA = {
    2.1: (12, 6.5397, 1.3884, 0.7146, 1.1967),
    2.5: (20, 11.0153, 1.8940, 1.2331, 1.3741),
    3.1: (28, 18.9764, 2.4485, 2.2414, 1.8441),
    3.5: (36, 25.8923, 3.0337, 3.0430, 2.2008),
    4.0: (48, 35.6092, 3.7071, 4.1983, 2.7345),
}
FOUR_DECIMALS = 0.5e-4 + 1e-12

# docs/method.md section 3: ratio of each model to the exact Laplacian on a square lattice.
# (model, "quad" | "mode") -> {(weight, r_e/l0): ratio}
_TABLE = """
wf1 2.1 1.000 0.992 2.126 2.108 1.000 0.993 1.418
wf1 3.1 1.000 0.981 1.857 1.821 1.000 0.988 1.238
wf1 4.0 1.000 0.968 1.761 1.708 1.000 0.982 1.174
wf2 2.1 1.000 0.993 3.463 3.432 1.000 0.995 1.718
wf2 3.1 1.000 0.987 2.588 2.535 1.000 0.991 1.296
wf2 4.0 1.000 0.978 2.358 2.279 1.000 0.987 1.180
"""
_COLUMNS = [
    ("koshizuka-oka", "quad"),
    ("koshizuka-oka", "mode"),
    ("khayyer-gotoh", "quad"),
    ("khayyer-gotoh", "mode"),
    ("xu-jin", "quad"),
    ("xu-jin", "mode"),
    ("xu-jin-analytic", "quad"),
]
LAP_TABLE: dict[tuple[str, str, str, float], float] = {}
for _line in _TABLE.strip().splitlines():
    _wf, _re, *_vals = _line.split()
    for (_model, _test), _v in zip(_COLUMNS, _vals, strict=True):
        LAP_TABLE[(_model, _test, _wf, float(_re))] = float(_v)

# The table is printed to 3 decimals, so an exact lattice sum should be within half a unit
# (5e-4).  Three entries are off by slightly more than that against exact lattice sums (the
# table was computed independently and rounded differently):
#   khayyer-gotoh   wf2 2.1 quad: exact 3.46243, table 3.463
#   xu-jin-analytic wf1 2.1 quad: exact 1.41747, table 1.418
#   xu-jin-analytic wf2 4.0 quad: exact 1.17935, table 1.180
# so every entry is held to one unit in the third decimal (1e-3), which still separates every
# model from every other one (the closest two columns differ by > 1e-2).
TABLE_TOL = 1e-3


def lattice_case(wf: str, ratio: float, l0: float = 1.0, n_side: int = 21):
    pos = free_lattice(n_side, l0)
    re = ratio * l0
    pairs = build_pairs(pos, re)
    n0, lam = lattice_constants(wf, ratio, l0)
    return pos, pairs, get_weight(wf), re, n0, lam


# --------------------------------------------------------------------------- n0 and lambda


@pytest.mark.parametrize("ratio", RATIOS)
@pytest.mark.parametrize("wf", ["wf1", "wf2"])
def test_lattice_constants_match_oracle(wf: str, ratio: float) -> None:
    _, n0_1, lam_1, n0_2, lam_2 = N0_LAMBDA[ratio]
    n0_ref, lam_ref = (n0_1, lam_1) if wf == "wf1" else (n0_2, lam_2)
    n0, lam = lattice_constants(wf, ratio)
    assert abs(n0 - n0_ref) <= FOUR_DECIMALS
    assert abs(lam - lam_ref) <= FOUR_DECIMALS


@pytest.mark.parametrize("ratio", RATIOS)
@pytest.mark.parametrize("wf", ["wf1", "wf2"])
def test_particle_constants_on_built_lattice_match_oracle(wf: str, ratio: float) -> None:
    """n0 from an actual particle arrangement (l0 = 1 cm): n0 is scale free, lambda ~ l0^2."""
    neighbours, n0_1, lam_1, n0_2, lam_2 = N0_LAMBDA[ratio]
    n0_ref, lam_ref = (n0_1, lam_1) if wf == "wf1" else (n0_2, lam_2)
    l0 = 0.01
    p = block(0.0, 0.0, 13, 11, l0)
    re = ratio * l0
    idx = interior_index(p.pos, p.fluid, re, None)
    n0, lam = particle_constants(p.pos, idx, wf, re)
    assert abs(n0 - n0_ref) <= FOUR_DECIMALS
    assert abs(lam / l0**2 - lam_ref) <= FOUR_DECIMALS
    # the chosen particle really has the full lattice neighbourhood
    d = np.hypot(*(p.pos - p.pos[idx]).T)
    assert np.count_nonzero((d > 0) & (d <= re)) == neighbours


def test_number_density_is_n0_everywhere_on_periodic_lattice() -> None:
    pos, box = lattice_pairs(12, 0.5)
    for wf in ("wf1", "wf2"):
        re = 3.1 * 0.5
        pairs = build_pairs(pos, re, box)
        n = number_density(pairs, get_weight(wf).w(pairs.r, re))
        n0, _ = lattice_constants(wf, 3.1, 0.5)
        np.testing.assert_allclose(n, n0, rtol=1e-12)


def test_interior_index_refuses_cloud_without_full_support() -> None:
    p = block(0.0, 0.0, 4, 4, 1.0)
    with pytest.raises(ValueError, match="full support"):
        interior_index(p.pos, p.fluid, 2.1, None)
    with pytest.raises(ValueError, match="no candidate"):
        interior_index(p.pos, np.zeros(p.n, bool), 2.1, None)


def test_particle_constants_without_neighbours_fails() -> None:
    pos = np.array([[0.0, 0.0], [5.0, 5.0]])
    with pytest.raises(ValueError, match="no neighbours"):
        particle_constants(pos, 0, "wf2", 2.1)


# --------------------------------------------------------------------------- Laplacian oracle


@pytest.mark.parametrize(("model", "test", "wf", "ratio"), sorted(LAP_TABLE))
def test_laplacian_lattice_ratio_matches_oracle(
    model: str, test: str, wf: str, ratio: float
) -> None:
    """Ratio model / exact at every interior particle of a 2 cm-spaced lattice."""
    l0 = 0.02
    pos, pairs, weight, re, n0, lam = lattice_case(wf, ratio, l0)
    x, y = pos[:, 0], pos[:, 1]
    lap = get_laplacian(model)
    inner = interior_mask(pos, re)
    if test == "quad":
        phi = (x - 0.3 * l0) ** 2  # exact Laplacian 2
        ratio_model = lap.apply(pairs, phi, weight, re, n0, lam)[inner] / 2.0
    else:
        k = 0.2 / l0  # k l0 = 0.2
        phi = np.sin(k * x + 0.4) * np.sin(k * y + 1.1)  # exact Laplacian -2 k^2 phi
        inner &= np.abs(phi) > 0.1
        ratio_model = lap.apply(pairs, phi, weight, re, n0, lam)[inner] / (-2 * k**2 * phi[inner])
    assert inner.sum() > 20
    expected = LAP_TABLE[(model, test, wf, ratio)]
    assert np.max(np.abs(ratio_model - expected)) <= TABLE_TOL


def test_laplacian_oracle_separates_models() -> None:
    """The test above can fail: LM2 and LM3-analytic are far from exact for x^2."""
    assert LAP_TABLE[("khayyer-gotoh", "quad", "wf1", 2.1)] > 2.0
    pos, pairs, weight, re, n0, lam = lattice_case("wf1", 2.1)
    i = int(np.argmin(np.hypot(*pos.T)))
    phi = pos[:, 0] ** 2
    values = {
        name: get_laplacian(name).apply(pairs, phi, weight, re, n0, lam)[i] / 2.0
        for name in LAPLACIANS.names()
    }
    assert values["khayyer-gotoh"] == pytest.approx(2.1262, abs=1e-4)
    assert values["xu-jin-analytic"] == pytest.approx(1.4175, abs=1e-4)


@pytest.mark.parametrize("correction", [False, True])
@pytest.mark.parametrize(("wf", "ratio"), [("wf1", 2.1), ("wf2", 3.1), ("wf2", 4.0)])
def test_xu_jin_exact_for_quadratics_on_lattice(wf: str, ratio: float, correction: bool) -> None:
    pos, pairs, weight, re, n0, lam = lattice_case(wf, ratio, 0.1)
    x, y = pos[:, 0], pos[:, 1]
    phi = 0.7 + 3 * x - 2 * y + 1.5 * x**2 - 0.8 * x * y + 2.5 * y**2  # exact 2(1.5 + 2.5) = 8
    lap = get_laplacian("xu-jin", gradient_correction=correction)
    assert lap.gradient_correction is correction
    out = lap.apply(pairs, phi, weight, re, n0, lam)
    inner = interior_mask(pos, re)
    np.testing.assert_allclose(out[inner], 8.0, rtol=1e-10)


@pytest.mark.parametrize(("wf", "ratio"), [("wf1", 2.1), ("wf2", 3.1), ("wf2", 4.0)])
def test_xu_jin_gradient_correction_helps_on_jittered_cloud(wf: str, ratio: float) -> None:
    """Off the lattice neither form is exact, but the correction removes the first-order term.

    (For a quadratic the corrected form is exact only where the neighbourhood's second-moment
    tensor is isotropic, i.e. on a symmetric lattice; measured here: ~10x smaller error.)
    """
    p = block(-10.5, -10.5, 21, 21, 1.0)
    from mpsbench.physics.particles import jitter

    jitter(p, 0.1, seed=3)
    pos = p.pos
    x, y = pos[:, 0], pos[:, 1]
    pairs = build_pairs(pos, ratio)
    weight = get_weight(wf)
    n0, lam = lattice_constants(wf, ratio)
    inner = interior_mask(pos, ratio + 0.2)
    for phi, exact in ((3 * x - 2 * y, 0.0), (x**2 + 0.5 * x * y + 2 * y**2 + x, 6.0)):
        plain = get_laplacian("xu-jin").apply(pairs, phi, weight, ratio, n0, lam)[inner]
        corr = get_laplacian("xu-jin", gradient_correction=True).apply(
            pairs, phi, weight, ratio, n0, lam
        )[inner]
        err_plain = np.max(np.abs(plain - exact))
        err_corr = np.max(np.abs(corr - exact))
        assert err_plain > 0.5  # the jitter really breaks the symmetric cancellation
        assert err_corr < 0.25 * err_plain


def test_get_laplacian_options() -> None:
    assert get_laplacian("xu-jin", gradient_correction=False).gradient_correction is False
    # gradient_correction=False is accepted (and ignored) by every model
    for name in LAPLACIANS.names():
        assert get_laplacian(name, gradient_correction=False).gradient_correction is False
    with pytest.raises(ValueError, match="does not accept options"):
        get_laplacian("koshizuka-oka", gradient_correction=True)
    model = get_laplacian("khayyer-gotoh")
    assert get_laplacian(model) is model
    with pytest.raises(UnknownNameError, match="xu-jin-analytic"):
        get_laplacian("xu-jim")


# --------------------------------------------------------------------------- matrix vs apply


@pytest.mark.parametrize(
    ("name", "correction"),
    [(n, False) for n in ("koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic")]
    + [("xu-jin", True)],
)
@pytest.mark.parametrize("wf", ["wf1", "wf2"])
def test_matrix_equals_apply_on_jittered_periodic_cloud(
    name: str, correction: bool, wf: str, jittered_periodic_cloud
) -> None:
    pos, box = jittered_periodic_cloud(n_side=14, l0=0.05, amplitude=0.1)
    re = 3.1 * 0.05
    pairs = build_pairs(pos, re, box)
    weight = get_weight(wf)
    n0, lam = lattice_constants(wf, 3.1, 0.05)
    lap = get_laplacian(name, gradient_correction=correction)
    rng = np.random.default_rng(11)
    phi = rng.normal(size=(len(pos), 3))
    mat = lap.matrix(pairs, weight, re, n0, lam)
    assert mat.shape == (len(pos), len(pos))
    for k in range(3):
        a = lap.apply(pairs, phi[:, k], weight, re, n0, lam)
        np.testing.assert_allclose(mat @ phi[:, k], a, rtol=0, atol=1e-12 * np.abs(a).max())
    # the (n, k) form of apply() agrees with the column-by-column form
    both = lap.apply(pairs, phi, weight, re, n0, lam)
    np.testing.assert_allclose(both, mat @ phi, rtol=0, atol=1e-12 * np.abs(both).max())


def test_gradient_matrix_equals_gradient(jittered_periodic_cloud) -> None:
    pos, box = jittered_periodic_cloud(n_side=12, amplitude=0.15)
    pairs = build_pairs(pos, 2.1, box)
    w = get_weight("wf2").w(pairs.r, 2.1)
    phi = np.random.default_rng(2).normal(size=len(pos))
    g = gradient(pairs, phi, w, 0.7146)
    for ax in range(2):
        gm = gradient_matrix(pairs, w, 0.7146, ax)
        np.testing.assert_allclose(gm @ phi, g[:, ax], rtol=0, atol=1e-12 * np.abs(g).max())


# --------------------------------------------------------------------------- gradient


@pytest.mark.parametrize(("wf", "ratio"), [("wf1", 2.1), ("wf2", 3.1), ("wf1", 4.0)])
def test_gradient_exact_for_linear_field_on_lattice(wf: str, ratio: float) -> None:
    pos, pairs, weight, re, n0, _ = lattice_case(wf, ratio, 0.01)
    phi = 5.0 + 3.0 * pos[:, 0] - 2.0 * pos[:, 1]
    g = gradient(pairs, phi, weight.w(pairs.r, re), n0)
    inner = interior_mask(pos, re)
    np.testing.assert_allclose(g[inner], np.tile([3.0, -2.0], (inner.sum(), 1)), rtol=1e-10)
    # near the edge the one-sided neighbourhood gets it wrong: the check above can fail
    assert np.max(np.abs(g[~inner] - [3.0, -2.0])) > 0.1


@pytest.mark.parametrize(("wf", "ratio"), [("wf1", 2.1), ("wf2", 3.1)])
def test_gradient_of_periodic_mode_matches_lattice_sum(wf: str, ratio: float) -> None:
    """phi = sin(kx + c) on a periodic lattice: grad = R k cos(kx + c) e_x exactly, where
    R = (2 / (n0 k)) sum_lattice sin(k a) a W(r) / r^2 is evaluated here independently."""
    n_side, l0 = 24, 1.0
    pos, box = lattice_pairs(n_side, l0)
    k = 2 * np.pi / (n_side * l0)
    phi = np.sin(k * pos[:, 0] + 0.3)
    weight = get_weight(wf)
    pairs = build_pairs(pos, ratio, box)
    n0, _ = lattice_constants(wf, ratio)
    g = gradient(pairs, phi, weight.w(pairs.r, ratio), n0)
    ia, ib = np.meshgrid(np.arange(-5, 6), np.arange(-5, 6), indexing="ij")
    a, b = ia.ravel().astype(float), ib.ravel().astype(float)
    r = np.hypot(a, b)
    keep = (r > 0) & (r <= ratio)
    a, r = a[keep], r[keep]
    big_r = 2.0 / (n0 * k) * np.sum(np.sin(k * a) * a * weight.w(r, ratio) / r**2)
    assert abs(big_r - 1) < (k * l0) ** 2  # consistent: second-order in k l0
    np.testing.assert_allclose(g[:, 0], big_r * k * np.cos(k * pos[:, 0] + 0.3), atol=1e-13)
    np.testing.assert_allclose(g[:, 1], 0.0, atol=1e-13)


@pytest.mark.parametrize(("wf", "ratio"), [("wf1", 2.1), ("wf2", 3.1), ("wf2", 4.0)])
def test_divergence_of_linear_velocity_on_lattice(wf: str, ratio: float) -> None:
    pos, pairs, weight, re, n0, _ = lattice_case(wf, ratio, 0.5)
    x, y = pos[:, 0], pos[:, 1]
    u = np.column_stack([1.0 + 0.7 * x - 1.3 * y, -2.0 + 2.0 * x - 0.2 * y])  # div = 0.5
    div = divergence(pairs, u, weight.w(pairs.r, re), n0)
    inner = interior_mask(pos, re)
    np.testing.assert_allclose(div[inner], 0.5, rtol=1e-10)
    # a rigid rotation has zero divergence
    rot = np.column_stack([-y, x])
    np.testing.assert_allclose(
        divergence(pairs, rot, weight.w(pairs.r, re), n0)[inner], 0.0, atol=1e-12
    )


# --------------------------------------------------------------------------- pressure gradients


def test_gradient_registry() -> None:
    assert GRADIENTS.names() == ["pgm1", "pgm2", "pgm3"]
    assert get_gradient("pgm2") is pgm2
    assert get_gradient(pgm3) is pgm3


@pytest.mark.parametrize("wf", ["wf1", "wf2"])
def test_pressure_gradient_momentum(wf: str, jittered_periodic_cloud) -> None:
    """PGM2 and PGM3 are antisymmetric pair forces: their sum over particles vanishes."""
    pos, box = jittered_periodic_cloud(n_side=16, amplitude=0.1, seed=5)
    re = 2.1
    pairs = build_pairs(pos, re, box)
    w = get_weight(wf).w(pairs.r, re)
    n0, _ = lattice_constants(wf, re)
    p = 1000.0 + 200.0 * np.random.default_rng(4).random(len(pos))
    for fn in (pgm2, pgm3):
        f = fn(pairs, p, w, n0)
        scale = np.abs(f).sum()
        assert scale > 0
        assert np.all(np.abs(f.sum(axis=0)) <= 1e-13 * scale), fn.name
    f1 = pgm1(pairs, p, w, n0)
    # PGM1's (p_j - pmin_i) is not antisymmetric: it does not conserve momentum
    assert np.max(np.abs(f1.sum(axis=0))) > 1e-3 * np.abs(f1).sum()


@pytest.mark.parametrize("wf", ["wf1", "wf2"])
def test_pressure_gradients_on_linear_pressure_over_lattice(wf: str) -> None:
    """PGM1 and PGM3 return the exact gradient of a linear pressure at interior particles.

    PGM2 as published (Khayyer & Gotoh 2008) returns zero there: on a uniform lattice
    p_j - pmin_j = p_i - pmin_i, so every pair term is the same constant and the sum cancels.
    This pins that property of the formula (see docs/method.md section 2), it is not a wish.
    """
    pos, pairs, weight, re, n0, _ = lattice_case(wf, 2.1)
    p = 100.0 + 3.0 * pos[:, 0] - 2.0 * pos[:, 1]
    w = weight.w(pairs.r, re)
    inner = interior_mask(pos, 2 * re)  # pmin of the neighbours needs their full support too
    for fn in (pgm1, pgm3):
        np.testing.assert_allclose(
            fn(pairs, p, w, n0)[inner], np.tile([3.0, -2.0], (inner.sum(), 1)), rtol=1e-10
        )
    np.testing.assert_allclose(pgm2(pairs, p, w, n0)[inner], 0.0, atol=1e-10)


def test_pressure_gradients_vanish_for_uniform_pressure(jittered_periodic_cloud) -> None:
    pos, box = jittered_periodic_cloud(n_side=12, amplitude=0.1)
    pairs = build_pairs(pos, 2.1, box)
    w = get_weight("wf2").w(pairs.r, 2.1)
    p = np.full(len(pos), 500.0)
    np.testing.assert_allclose(pgm1(pairs, p, w, 0.7146), 0.0, atol=1e-9)
    np.testing.assert_allclose(pgm2(pairs, p, w, 0.7146), 0.0, atol=1e-9)
    # PGM3 (p_i + p_j) keeps a repulsive force on an irregular cloud: not zero
    assert np.abs(pgm3(pairs, p, w, 0.7146)).max() > 1.0
