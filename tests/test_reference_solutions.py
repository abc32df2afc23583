"""Reference solutions of the hydrostatic, Poiseuille, Taylor-Green and cavity cases.

Each reference is held against values computed independently of its formula: hand arithmetic,
quadrature, a finite-difference solution of the same PDE, finite-difference residuals of the
Navier-Stokes equations, and the Ghia tables as verified against four public copies
(validations/data/README.md).
"""

from __future__ import annotations

import fnmatch
import math
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.linalg
from mpsbench.validations.cavity import reference as cavity
from mpsbench.validations.experiments import DataFileError
from mpsbench.validations.hydrostatic import reference as hydro
from mpsbench.validations.poiseuille import reference as poiseuille
from mpsbench.validations.taylor_green.reference import TaylorGreen

# ---------------------------------------------------------------- hydrostatic


def test_hydrostatic_values_by_hand() -> None:
    # 1000 kg/m^3 * 9.81 m/s^2 * 0.6 m = 5886 Pa at the floor, half of it half-way up
    p = hydro.pressure([0.0, 0.3, 0.6], height=0.6)
    assert p == pytest.approx([5886.0, 2943.0, 0.0], abs=1e-9)
    assert hydro.floor_pressure(0.3, rho0=997.0) == pytest.approx(2934.2, abs=0.1)  # Lobovsky


def test_hydrostatic_balances_gravity_and_integrates_to_the_wall_force() -> None:
    height, rho0, g = 0.8, 1025.0, 9.81
    y = np.linspace(0.0, height, 801)
    p = hydro.pressure(y, height, rho0, g)
    assert np.gradient(p, y) == pytest.approx(np.full_like(y, -rho0 * g), rel=1e-12)
    force = float(np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(y)))  # trapezoid, exact for a line
    assert force == pytest.approx(hydro.wall_force_per_width(height, rho0, g), rel=1e-12)
    assert force == pytest.approx(0.5 * 1025.0 * 9.81 * 0.64, rel=1e-12)


@pytest.mark.parametrize("y", [-1e-6, 0.6 + 1e-6])
def test_hydrostatic_refuses_heights_outside_the_column(y: float) -> None:
    with pytest.raises(ValueError, match="outside the column"):
        hydro.pressure(y, height=0.6)


# ---------------------------------------------------------------- Poiseuille

MORRIS = poiseuille.Poiseuille()  # L = 1e-3 m, nu = 1e-6 m^2/s, F = 2e-4 m/s^2


def test_poiseuille_steady_state_is_the_parabola() -> None:
    # F L^2 / (8 nu) = 2e-4 * 1e-6 / 8e-6 = 2.5e-5 m/s; at L/4: F (L/4)(3L/4) / (2 nu) = 1.875e-5
    assert MORRIS.u_max == pytest.approx(2.5e-5, rel=1e-15)
    y = np.array([0.0, 2.5e-4, 5.0e-4, 7.5e-4, 1.0e-3])
    hand = np.array([0.0, 1.875e-5, 2.5e-5, 1.875e-5, 0.0])
    assert MORRIS.steady(y) == pytest.approx(hand, rel=1e-14, abs=1e-25)
    # t -> infinity: 50 s is ~500 diffusion times L^2 / (pi^2 nu); no term is left
    assert MORRIS.terms_needed(50.0) == 0
    assert MORRIS.velocity(y, 50.0) == pytest.approx(hand, rel=1e-14, abs=1e-25)
    # 5 s: the slowest mode is exp(-49) ~ 5e-22 of u_max, far below the default bound
    assert MORRIS.velocity(y, 5.0) == pytest.approx(hand, rel=1e-12, abs=1e-20)


def test_poiseuille_starts_from_rest() -> None:
    y = np.linspace(0.0, MORRIS.gap, 11)
    assert np.all(MORRIS.velocity(y, 0.0) == 0.0)
    # The series itself at t = 0 (every mode undecayed) sums to the parabola: u = 0 within B.
    n = MORRIS.terms_needed(0.0, rtol=1e-8)
    assert np.max(np.abs(MORRIS.velocity(y, 0.0, n_terms=n))) <= MORRIS.truncation_bound(0.0, n)
    # Just after the start the walls are not yet felt in the middle: u = F t.
    t = 1e-9
    assert MORRIS.velocity(5e-4, t) == pytest.approx(MORRIS.force * t, rel=1e-6)


def test_poiseuille_interior_accelerates_freely_before_the_walls_are_felt() -> None:
    # At t = 1e-4 s the diffusion length sqrt(nu t) = 1e-5 m is 1/25 of the distance to the
    # nearer wall: the deficit below F t is ~erfc(12.5) ~ 1e-69, so u = F t = 2e-8 m/s exactly.
    t = 1e-4
    assert MORRIS.velocity([2.5e-4, 5e-4, 7.5e-4], t) == pytest.approx(
        np.full(3, 2e-8), rel=1e-9
    )


def _poiseuille_finite_differences(cells: int, t: float) -> tuple[np.ndarray, np.ndarray]:
    """u_t = nu u_yy + F, u = 0 at both plates and at t = 0: central differences on `cells`
    uniform cells, integrated exactly in time, u(t) = A^-1 (exp(A t) - I) F."""
    h = MORRIS.gap / cells
    n = cells - 1
    a = (MORRIS.nu / h**2) * (
        np.diag(np.full(n, -2.0)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1)
    )
    u = np.linalg.solve(a, (scipy.linalg.expm(a * t) - np.eye(n)) @ np.full(n, MORRIS.force))
    return h * np.arange(1, cells), u


@pytest.mark.parametrize("t", [0.0225, 0.1125])  # s, profile times of validations/couette.py
def test_poiseuille_series_is_the_limit_of_a_finite_difference_solution(t: float) -> None:
    y_probe = np.array([0.25e-3, 0.5e-3])
    errors, values = [], []
    for cells in (64, 128):
        y, u = _poiseuille_finite_differences(cells, t)
        at = np.searchsorted(y, y_probe - 1e-12)
        assert y[at] == pytest.approx(y_probe, rel=1e-12)
        values.append(u[at])
        errors.append(u[at] - MORRIS.velocity(y_probe, t))
    # second order in h towards the series: the error falls by 4 when h halves ...
    ratio = errors[0] / errors[1]
    assert ratio == pytest.approx(np.full(2, 4.0), rel=0.01)
    # ... and the Richardson extrapolation of the two grids meets the series to 1e-8 u_max
    # (found 1e-9 to 6e-9; the 128-cell errors are 5e-6 to 2e-5 u_max, the series bound 1e-10).
    richardson = (4.0 * values[1] - values[0]) / 3.0
    assert np.max(np.abs(richardson - MORRIS.velocity(y_probe, t))) <= 1e-8 * MORRIS.u_max
    assert 0.1 * MORRIS.u_max < MORRIS.velocity(5e-4, t) < 0.9 * MORRIS.u_max  # mid-transient


@pytest.mark.parametrize("t", [1e-4, 0.0225, 0.1125])
def test_poiseuille_truncation_bound_holds(t: float) -> None:
    y = np.linspace(0.0, MORRIS.gap, 41)
    reference = MORRIS.velocity(y, t, n_terms=MORRIS.terms_needed(t, rtol=1e-14) + 50)
    for n in (0, 1, 2, 5, 10, 20):
        err = np.max(np.abs(MORRIS.velocity(y, t, n_terms=n) - reference))
        assert err <= MORRIS.truncation_bound(t, n) + 1e-14 * MORRIS.u_max
    # the rule picks the fewest terms meeting the tolerance
    n = MORRIS.terms_needed(t)
    assert MORRIS.truncation_bound(t, n) <= 1e-10 * MORRIS.u_max
    assert n == 0 or MORRIS.truncation_bound(t, n - 1) > 1e-10 * MORRIS.u_max
    assert np.max(np.abs(MORRIS.velocity(y, t) - reference)) <= 1e-10 * MORRIS.u_max


def test_poiseuille_needs_fewer_terms_later() -> None:
    times = [0.0, 1e-9, 1e-6, 1e-4, 1e-2, 0.0225, 0.1, 1.0, 3.0]
    counts = [MORRIS.terms_needed(t) for t in times]
    assert counts == sorted(counts, reverse=True)
    assert counts[-1] == 0 and MORRIS.terms_needed(0.0225) == 4


def test_poiseuille_refuses_bad_input() -> None:
    with pytest.raises(ValueError, match="outside the gap"):
        MORRIS.velocity([0.0, 1.1e-3], 0.1)
    with pytest.raises(ValueError, match="time must be >= 0"):
        MORRIS.velocity(5e-4, -1.0)
    with pytest.raises(ValueError, match="rtol"):
        MORRIS.terms_needed(0.1, rtol=1e-16)
    with pytest.raises(ValueError, match="nu must be positive"):
        poiseuille.Poiseuille(nu=0.0)


# ---------------------------------------------------------------- Taylor-Green

Field = Callable[[np.ndarray, np.ndarray, float], np.ndarray]


def _d(f: Callable[[float], np.ndarray], h: float) -> np.ndarray:
    """Fourth-order central first derivative of f at 0."""
    return (8.0 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12.0 * h)


def _d2(f: Callable[[float], np.ndarray], h: float) -> np.ndarray:
    """Fourth-order central second derivative of f at 0."""
    return (16.0 * (f(h) + f(-h)) - (f(2 * h) + f(-2 * h)) - 30.0 * f(0.0)) / (12.0 * h * h)


def _along(f: Field, x: np.ndarray, y: np.ndarray, t: float,
           axis: str) -> Callable[[float], np.ndarray]:
    """s -> f at (x, y, t) shifted by s along axis "x", "y" or "t"."""
    if axis == "x":
        return lambda s: f(x + s, y, t)
    if axis == "y":
        return lambda s: f(x, y + s, t)
    return lambda s: f(x, y, t + s)


def _navier_stokes_residuals(u: Field, v: Field, p: Field, rho0: float, nu: float,
                             x: np.ndarray, y: np.ndarray, t: float
                             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Continuity and x/y momentum residuals by finite differences of the fields, and the
    size of the viscous term; nothing of the closed form is used but point values."""
    h, dt = 1e-3, 1e-3
    div = _d(_along(u, x, y, t, "x"), h) + _d(_along(v, x, y, t, "y"), h)
    uu, vv = u(x, y, t), v(x, y, t)
    residuals, viscous = [], []
    for f, axis in ((u, "x"), (v, "y")):
        f_t = _d(_along(f, x, y, t, "t"), dt)
        f_x = _d(_along(f, x, y, t, "x"), h)
        f_y = _d(_along(f, x, y, t, "y"), h)
        lap = _d2(_along(f, x, y, t, "x"), h) + _d2(_along(f, x, y, t, "y"), h)
        grad_p = _d(_along(p, x, y, t, axis), h)
        residuals.append(f_t + uu * f_x + vv * f_y + grad_p / rho0 - nu * lap)
        viscous.append(nu * lap)
    return div, residuals[0], residuals[1], np.maximum(np.abs(viscous[0]), np.abs(viscous[1]))


def _tg_fields(tg: TaylorGreen) -> tuple[Field, Field, Field]:
    return (lambda x, y, t: tg.velocity(x, y, t)[0], lambda x, y, t: tg.velocity(x, y, t)[1],
            tg.pressure)


@pytest.mark.parametrize("re", [100.0, 1000.0])
def test_taylor_green_satisfies_navier_stokes(re: float) -> None:
    tg = TaylorGreen(reynolds=re)
    rng = np.random.default_rng(6)
    x, y = rng.uniform(0.0, 1.0, (2, 200))
    u, v, p = _tg_fields(tg)
    for t in (0.0, 0.3, 1.0):
        div, rx, ry, viscous = _navier_stokes_residuals(u, v, p, tg.rho0, tg.nu, x, y, t)
        # scale of the smallest balanced term: nu |lap u| <= 8 pi^2 nu U e^{bt}, 0.08 at
        # Re = 1000 against ~6 for convection; the residual must be far below it
        scale = 8.0 * math.pi**2 * tg.nu * tg.amplitude(t)
        assert np.max(viscous) == pytest.approx(scale, rel=0.05)
        assert np.max(np.abs(div)) <= 1e-9 * 2 * math.pi * tg.amplitude(t)
        assert np.max(np.abs(rx)) <= 1e-5 * scale
        assert np.max(np.abs(ry)) <= 1e-5 * scale


@pytest.mark.parametrize("re", [100.0, 1000.0])
def test_taylor_green_residual_check_catches_wrong_fields(re: float) -> None:
    """The residual test above can fail: a flipped pressure or a wrong decay rate leave residuals
    some 1e5 times its tolerance (1e-5 of the viscous scale)."""
    tg = TaylorGreen(reynolds=re)
    x, y = np.random.default_rng(7).uniform(0.0, 1.0, (2, 200))
    u, v, p = _tg_fields(tg)
    scale = 8.0 * math.pi**2 * tg.nu * tg.amplitude(0.3)
    wrong_p: Field = lambda x, y, t: -p(x, y, t)  # noqa: E731
    _, rx, _, _ = _navier_stokes_residuals(u, v, wrong_p, tg.rho0, tg.nu, x, y, 0.3)
    assert np.max(np.abs(rx)) > scale
    slow_u: Field = lambda x, y, t: u(x, y, t / 2)  # noqa: E731 (decays at b / 2)
    slow_v: Field = lambda x, y, t: v(x, y, t / 2)  # noqa: E731
    slow_p: Field = lambda x, y, t: p(x, y, t / 2)  # noqa: E731
    _, rx, _, _ = _navier_stokes_residuals(slow_u, slow_v, slow_p, tg.rho0, tg.nu, x, y, 0.3)
    assert np.max(np.abs(rx)) > 0.3 * scale


@pytest.mark.parametrize("re", [100.0, 1000.0])
def test_taylor_green_kinetic_energy_decays_as_exp_2bt(re: float) -> None:
    tg = TaylorGreen(reynolds=re, rho0=998.0)
    n = 64  # midpoint rule: exact for these trigonometric polynomials on the periodic square
    s = (np.arange(n) + 0.5) / n
    x, y = np.meshgrid(s, s, indexing="ij")
    b = -8.0 * math.pi**2 / re  # L = U = 1: nu = 1 / Re
    e0 = 998.0 / 4.0  # rho0 U^2 L^2 / 4
    for t in (0.0, 0.25, 1.0, 4.0):
        u, v = tg.velocity(x, y, t)
        integral = float(np.sum(0.5 * 998.0 * (u * u + v * v))) / n**2
        assert integral == pytest.approx(e0 * math.exp(2.0 * b * t), rel=1e-12)
        assert tg.kinetic_energy(t) == pytest.approx(integral, rel=1e-12)
        assert tg.kinetic_energy_ratio(t) == pytest.approx(math.exp(2.0 * b * t), rel=1e-12)
    # Re = 100: E halves by t = ln 2 / (16 pi^2 / 100) = 0.43894 s
    if re == 100.0:
        assert tg.kinetic_energy_ratio(0.43894058) == pytest.approx(0.5, rel=1e-7)


def test_taylor_green_parameters_by_hand() -> None:
    tg = TaylorGreen(reynolds=1000.0, speed=2.0, side=0.5)
    assert tg.nu == pytest.approx(1e-3)
    assert tg.decay_rate == pytest.approx(-8.0 * math.pi**2 * 1e-3 / 0.25)
    # periodic, mean-free pressure, and u = -U at (0, L/4) at t = 0
    u, v = tg.velocity([0.0, 0.5], [0.125, 0.625], 0.0)
    assert u == pytest.approx([-2.0, -2.0]) and v == pytest.approx([0.0, 0.0], abs=1e-15)
    s = (np.arange(32) + 0.5) / 64
    xx, yy = np.meshgrid(s, s)
    assert abs(float(np.mean(tg.pressure(xx, yy, 0.1)))) < 1e-12
    with pytest.raises(ValueError, match="reynolds must be positive"):
        TaylorGreen(reynolds=0.0)


# ---------------------------------------------------------------- lid-driven cavity (Ghia 1982)

# The values as verified against four public copies (validations/data/README.md), typed here
# again so a change to the shipped files shows; table order, from the lid / right wall down.
# Point numbers n on the 129 x 129 grid (the tables' first column, as copy A lists them):
# the coordinate is (n - 1) / 128.
GHIA_U_POINT = [129, 126, 125, 124, 123, 110, 95, 80, 65, 59, 37, 23, 14, 10, 9, 8, 1]
GHIA_Y = [1.0000, 0.9766, 0.9688, 0.9609, 0.9531, 0.8516, 0.7344, 0.6172, 0.5000, 0.4531,
          0.2813, 0.1719, 0.1016, 0.0703, 0.0625, 0.0547, 0.0000]
GHIA_U = {
    100: [1.00000, 0.84123, 0.78871, 0.73722, 0.68717, 0.23151, 0.00332, -0.13641, -0.20581,
          -0.21090, -0.15662, -0.10150, -0.06434, -0.04775, -0.04192, -0.03717, 0.00000],
    1000: [1.00000, 0.65928, 0.57492, 0.51117, 0.46604, 0.33304, 0.18719, 0.05702, -0.06080,
           -0.10648, -0.27805, -0.38289, -0.29730, -0.22220, -0.20196, -0.18109, 0.00000],
}
GHIA_V_POINT = [129, 125, 124, 123, 122, 117, 111, 104, 65, 31, 30, 21, 13, 11, 10, 9, 1]
GHIA_X = [1.0000, 0.9688, 0.9609, 0.9531, 0.9453, 0.9063, 0.8594, 0.8047, 0.5000, 0.2344,
          0.2266, 0.1563, 0.0938, 0.0781, 0.0703, 0.0625, 0.0000]
GHIA_V = {
    100: [0.00000, -0.05906, -0.07391, -0.08864, -0.10313, -0.16914, -0.22445, -0.24533,
          0.05454, 0.17527, 0.17507, 0.16077, 0.12317, 0.10890, 0.10091, 0.09233, 0.00000],
    1000: [0.00000, -0.21388, -0.27669, -0.33714, -0.39188, -0.51550, -0.42665, -0.31966,
           0.02526, 0.32235, 0.33075, 0.37095, 0.32627, 0.30353, 0.29012, 0.27485, 0.00000],
}
ROOT = Path(__file__).resolve().parents[1]


def test_ghia_loader_returns_the_verified_values() -> None:
    u = cavity.u_vertical_centreline()
    v = cavity.v_horizontal_centreline()
    assert (u.coordinate_name, v.coordinate_name) == ("y", "x")
    assert u.reynolds == v.reynolds == (100, 1000)
    assert u.coordinate.tolist() == GHIA_Y and v.coordinate.tolist() == GHIA_X
    for re in (100, 1000):
        assert u[re].tolist() == GHIA_U[re]
        assert v[re].tolist() == GHIA_V[re]
    assert "Ghia" in u.source and "48(3):387-411" in v.source
    y, u100 = u.ascending(100)
    assert np.all(np.diff(y) > 0) and u100[0] == 0.0 and u100[-1] == 1.0
    with pytest.raises(KeyError, match="no Re = 400 column"):
        u[400]


def test_ghia_coordinates_are_the_129_grid_nodes() -> None:
    for coords, points in ((GHIA_Y, GHIA_U_POINT), (GHIA_X, GHIA_V_POINT)):
        nodes = (np.array(points) - 1) / 128.0
        assert np.max(np.abs(np.array(coords) - nodes)) <= 5e-5 + 1e-12  # printed to 4 decimals


@pytest.mark.parametrize("component", ["u", "v"])
def test_ghia_profiles_carry_no_net_flux(component: cavity.Component) -> None:
    """Mass conservation in the closed cavity: nothing crosses a centreline on balance.  The
    trapezoid rule over the 17 points leaves at most 0.0073; a sign error at 8 to 12 of the 17
    points of a column would push it above 0.01 (validations/data/README.md)."""
    profile = cavity.load_ghia(component)
    for re in profile.reynolds:
        s, f = profile.ascending(re)
        flux = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(s)))
        assert abs(flux) < 0.01, (component, re, flux)


def test_ghia_files_are_package_data() -> None:
    with open(ROOT / "pyproject.toml", "rb") as fh:
        globs = tomllib.load(fh)["tool"]["setuptools"]["package-data"]["mpsbench.validations.data"]
    for name, _ in cavity.FILES.values():
        rel = f"{name}.csv"
        assert (ROOT / "validations" / "data" / rel).is_file()
        assert any(fnmatch.fnmatch(rel, g) for g in globs), (rel, globs)


def _shipped_lines(component: cavity.Component) -> list[str]:
    name, _ = cavity.FILES[component]
    return (ROOT / "validations" / "data" / f"{name}.csv").read_text(encoding="utf-8").splitlines()


def _broken(tmp_path: Path, lines: list[str], name: str = "broken.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _first_data(lines: list[str]) -> int:
    """Index of the first data row (the line after the column header)."""
    return next(i for i, line in enumerate(lines) if not line.startswith("#")) + 1


def test_ghia_loader_accepts_an_intact_copy(tmp_path: Path) -> None:
    profile = cavity.load_ghia("v", _broken(tmp_path, _shipped_lines("v"), "copy.csv"))
    assert profile[1000].tolist() == GHIA_V[1000]


def test_ghia_loader_rejects_a_file_that_is_not_utf8(tmp_path: Path) -> None:
    lines = _shipped_lines("u")
    path = tmp_path / "latin1.csv"
    text = "\n".join(lines).replace("Shin, C. T.", "Shin, C. T. (Universit\u00e4t)") + "\n"
    path.write_bytes(text.encode("latin-1"))
    with pytest.raises(DataFileError, match=r"latin1\.csv: not UTF-8 text \(byte 0xe4 on line 1\)"):
        cavity.load_ghia("u", path)


def test_ghia_loader_rejects_a_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + "\n".join(_shipped_lines("u")).encode("utf-8"))
    with pytest.raises(DataFileError, match="bom.csv: starts with a UTF-8 byte-order mark"):
        cavity.load_ghia("u", path)


def test_ghia_loader_rejects_a_missing_column(tmp_path: Path) -> None:
    lines = _shipped_lines("v")
    start = _first_data(lines) - 1  # the column header
    cut = [",".join(line.split(",")[:2]) if i >= start else line for i, line in enumerate(lines)]
    cut = [line.replace(", Re1000=1", "") for line in cut]
    with pytest.raises(DataFileError, match="broken.csv: missing column 'Re1000'"):
        cavity.load_ghia("v", _broken(tmp_path, cut))


def test_ghia_loader_rejects_a_truncated_row(tmp_path: Path) -> None:
    lines = _shipped_lines("u")
    lines[-1] = lines[-1][: lines[-1].rindex(",")]  # the file ends mid-row: "0.0000,0.00000"
    with pytest.raises(DataFileError, match="broken.csv: data row 18 has 2 values, expected 3"):
        cavity.load_ghia("u", _broken(tmp_path, lines))


def test_ghia_loader_rejects_a_file_cut_between_rows(tmp_path: Path) -> None:
    lines = _shipped_lines("u")[:-3]
    with pytest.raises(DataFileError, match="broken.csv: 14 data rows, expected 17"):
        cavity.load_ghia("u", _broken(tmp_path, lines))


@pytest.mark.parametrize(
    ("component", "row", "new", "message"),
    [
        ("u", 3, "0.9788,0.78871,0.57492", r"monotone \(data rows 4 and 5: 0.9688 then 0.9788\)"),
        ("v", 0, "1.0100,0.00000,0.00000", "coordinate 'x' outside \\[0, 1\\]"),
        ("u", 0, "1.0000,0.99000,1.00000", "Re100: u = 0.99 at the lid y = 1"),
        ("v", 16, "0.0000,0.00000,0.00100", "Re1000: v = 0.001 at the left wall x = 0"),
        ("u", 16, "0.0010,0.00000,0.00000", "runs from 1 to 0.001"),
        ("u", 5, "0.8516,0.23151,nan", "data row 7, column 'Re1000': 'nan' is not a finite"),
    ],
)
def test_ghia_loader_rejects_wrong_values(tmp_path: Path, component: cavity.Component, row: int,
                                          new: str, message: str) -> None:
    lines = _shipped_lines(component)
    lines[_first_data(lines) + row] = new
    with pytest.raises(DataFileError, match=message) as info:
        cavity.load_ghia(component, _broken(tmp_path, lines))
    assert "broken.csv" in str(info.value)
    assert isinstance(info.value, ValueError)


def test_ghia_loader_rejects_a_missing_file(tmp_path: Path) -> None:
    with pytest.raises(DataFileError, match="does not exist"):
        cavity.load_ghia("u", tmp_path / "absent.csv")
    with pytest.raises(ValueError, match="component must be 'u' or 'v'"):
        not_a_component: Any = "w"
        cavity.load_ghia(not_a_component)
