"""Reference solutions of the hydrostatic, Poiseuille, Taylor-Green and cavity cases.

Each reference is held against values computed independently of its formula: hand arithmetic,
quadrature, a finite-difference solution of the same PDE, finite-difference residuals of the
Navier-Stokes equations, and the Ghia tables as verified against four public copies
(validations/data/README.md).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpsbench.validations.hydrostatic import reference as hydro

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
