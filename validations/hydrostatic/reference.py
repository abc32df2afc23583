"""Exact pressure in a column of liquid at rest, for the hydrostatic benchmark case.

A column of height H [m] of an incompressible liquid of density rho0 [kg/m^3] rests on the
floor y = 0 under gravity g [m/s^2] pointing in -y, with a free surface at y = H where the
pressure is zero (gauge pressure; a WC-MPS solver's background pressure is added by the case,
not here).  The momentum balance reduces to dp/dy = -rho0 g, so

    p(y) = rho0 g (H - y)   [Pa],  0 <= y <= H,

the hydrostatic law integrated down from the free surface.  The floor carries p(0) = rho0 g H
and a side wall a force rho0 g H^2 / 2 per unit width [N/m].  g defaults to 9.81 m/s^2, the
value the rest of mpsbench uses.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

G = 9.81  # m/s^2, as in mpsbench.validations.experiments and mpsbench.config
RHO0 = 1000.0  # kg/m^3


def pressure(y: ArrayLike, height: float, rho0: float = RHO0, g: float = G) -> NDArray[np.float64]:
    """Gauge pressure p(y) = rho0 g (H - y) [Pa] at heights y [m] inside the column.

    Heights outside [0, H] raise ValueError: above the surface there is no liquid and below the
    floor no column, and silently extrapolating the line would hide a probe placed wrongly.
    """
    if not height > 0.0:
        raise ValueError(f"column height must be positive, got {height!r} m")
    y_arr = np.asarray(y, dtype=float)
    outside = (y_arr < 0.0) | (y_arr > height)
    if np.any(outside):
        bad = np.atleast_1d(y_arr)[np.atleast_1d(outside)]
        raise ValueError(f"heights outside the column [0, {height:g}] m: {bad[:5].tolist()}")
    return rho0 * g * (height - y_arr)


def floor_pressure(height: float, rho0: float = RHO0, g: float = G) -> float:
    """p(0) = rho0 g H [Pa], the pressure scale of the case."""
    return float(pressure(0.0, height, rho0, g))


def wall_force_per_width(height: float, rho0: float = RHO0, g: float = G) -> float:
    """Integral of p over a vertical wall, rho0 g H^2 / 2 [N/m] per unit width."""
    if not height > 0.0:
        raise ValueError(f"column height must be positive, got {height!r} m")
    return 0.5 * rho0 * g * height**2
