"""Decaying Taylor-Green vortex on a periodic square: exact velocity, pressure, kinetic energy.

Taylor, G. I. and Green, A. E. (1937), Mechanism of the production of small eddies from large
ones, Proc. R. Soc. Lond. A 158:499-521, doi:10.1098/rspa.1937.0036.  In two dimensions their
single-mode vortex decays without changing shape, an exact solution of the incompressible
Navier-Stokes equations (the convective term is a pure gradient and is balanced by the
pressure; only viscosity changes the amplitude).  (SPHERIC's validation test 6 is a different
case, the flow around a square moving in a box, and is not the source of this one.)

On the periodic square [0, L) x [0, L) [m] with k = 2 pi / L, velocity scale U [m/s],
kinematic viscosity nu = U L / Re [m^2/s] and density rho0 [kg/m^3]:

    u = -U e^{b t} cos(k x) sin(k y)                          [m/s]
    v =  U e^{b t} sin(k x) cos(k y)                          [m/s]
    p = -(rho0 U^2 / 4) e^{2 b t} (cos(2 k x) + cos(2 k y))   [Pa]
    b = -2 k^2 nu = -8 pi^2 nu / L^2                          [1/s]

Check by substitution: u_x + v_y = 0; (u . grad) u = -(k U^2 e^{2bt} / 2) (sin 2kx, sin 2ky)
is cancelled by -grad p / rho0; nu lap u = -2 k^2 nu u = b u = du/dt.  p is the zero-mean
pressure (any constant can be added; a weakly compressible solver adds its background
pressure).  The kinetic energy in the square, per unit depth,

    E(t) = int rho0 (u^2 + v^2) / 2 dA = rho0 U^2 L^2 e^{2 b t} / 4   [J/m],

decays as e^{2 b t}: with L = U = 1, b = -8 pi^2 / Re, e.g. -0.0790 1/s at Re = 1000 and
-0.790 1/s at Re = 100 (E halves by t = 0.44 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

REYNOLDS = (100.0, 1000.0)  # the two cases the benchmark runs


@dataclass(frozen=True)
class TaylorGreen:
    """Taylor-Green vortex with Re = U L / nu on [0, L)^2; SI units (m, s, kg/m^3)."""

    reynolds: float = 100.0
    speed: float = 1.0  # U [m/s]
    side: float = 1.0  # L [m]
    rho0: float = 1000.0  # [kg/m^3]

    def __post_init__(self) -> None:
        for name in ("reynolds", "speed", "side", "rho0"):
            value = getattr(self, name)
            if not value > 0.0:
                raise ValueError(f"TaylorGreen {name} must be positive, got {value!r}")

    @property
    def nu(self) -> float:
        """Kinematic viscosity U L / Re [m^2/s]."""
        return self.speed * self.side / self.reynolds

    @property
    def wavenumber(self) -> float:
        """k = 2 pi / L [1/m]."""
        return 2.0 * math.pi / self.side

    @property
    def decay_rate(self) -> float:
        """b = -2 k^2 nu = -8 pi^2 nu / L^2 [1/s]: velocity ~ e^{b t}, energy ~ e^{2 b t}."""
        return -2.0 * self.wavenumber**2 * self.nu

    def amplitude(self, t: float) -> float:
        """Velocity amplitude U e^{b t} [m/s]."""
        return self.speed * math.exp(self.decay_rate * t)

    def velocity(self, x: ArrayLike, y: ArrayLike, t: float) -> tuple[FloatArray, FloatArray]:
        """(u, v) [m/s] at points (x, y) [m] (broadcast together) and time t [s]."""
        k = self.wavenumber
        kx = k * np.asarray(x, dtype=float)
        ky = k * np.asarray(y, dtype=float)
        a = self.amplitude(t)
        return -a * np.cos(kx) * np.sin(ky), a * np.sin(kx) * np.cos(ky)

    def pressure(self, x: ArrayLike, y: ArrayLike, t: float) -> FloatArray:
        """Zero-mean pressure [Pa] at points (x, y) [m] and time t [s]."""
        k2 = 2.0 * self.wavenumber
        a = self.amplitude(t)
        return -0.25 * self.rho0 * a * a * (
            np.cos(k2 * np.asarray(x, dtype=float)) + np.cos(k2 * np.asarray(y, dtype=float))
        )

    def kinetic_energy(self, t: float) -> float:
        """E(t) = rho0 U^2 L^2 e^{2 b t} / 4 [J/m], the whole square per unit depth."""
        return 0.25 * self.rho0 * self.amplitude(t) ** 2 * self.side**2

    def kinetic_energy_ratio(self, t: float) -> float:
        """E(t) / E(0) = e^{2 b t}."""
        return math.exp(2.0 * self.decay_rate * t)
