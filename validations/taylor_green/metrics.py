"""Taylor-Green: the case's constants and the errors of one particle state (docs/method.md 6 g).

The exact fields are :class:`.reference.TaylorGreen`.  Every error is taken at the particles'
own positions (the flow is periodic and smooth, so no interpolation is needed): the velocity
error against the exact field there, the pressure against the exact zero-mean pressure after
removing the run's mean (a weakly compressible run carries a background pressure the exact
solution does not have), the kinetic energy of the fluid against e^{2 b t}, and two numbers of
particle disorder that are 0 on the initial lattice: the spread and the minimum of the
nearest-neighbour distance in units of l0.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from .reference import TaylorGreen

SIDE = 1.0  # L [m]
SPEED = 1.0  # U [m/s]
RHO = 1000.0  # rho0 [kg/m^3]
C0 = 10.0 * SPEED  # m/s (c0 >= 10 U_max, docs/method.md section 4)
TIME_FRACTIONS = (0.1, 0.2, 0.5, 1.0)  # of end_time: the error times
ENERGY_SAMPLES = 50  # kinetic-energy samples over a run
HEADLINE_N = 40  # particles per side of the headline table
# the configuration of the findings and the refinement set (the dam break's IWC-MPS models)
RECOMMENDED = {"laplacian": "xu-jin", "weight": "wf2", "gradient": "pgm1", "re_ratio": 3.1}


def flow(reynolds: float) -> TaylorGreen:
    return TaylorGreen(reynolds=reynolds, speed=SPEED, side=SIDE, rho0=RHO)


def error_times(end_time: float) -> tuple[float, ...]:
    return tuple(f * end_time for f in TIME_FRACTIONS)


def time_key(fraction: float) -> str:
    """Metric name of the velocity error at ``fraction`` x end_time."""
    return f"velocity_error_{fraction:g}T"


def velocity_error(tg: TaylorGreen, pos: np.ndarray, vel: np.ndarray, t: float) -> float:
    """||u - u_exact|| / ||u_exact|| over the particles (relative L2, at their positions)."""
    u, v = tg.velocity(pos[:, 0], pos[:, 1], t)
    exact = np.column_stack([u, v])
    return float(np.linalg.norm(vel - exact) / np.linalg.norm(exact))


def pressure_error(tg: TaylorGreen, pos: np.ndarray, p: np.ndarray, t: float) -> float:
    """||(p - mean p) - p_exact|| / ||p_exact||: the pressure's shape, background removed."""
    exact = tg.pressure(pos[:, 0], pos[:, 1], t)
    return float(np.linalg.norm(p - p.mean() - exact) / np.linalg.norm(exact))


def energy_ratio(tg: TaylorGreen, vel: np.ndarray, t: float) -> float:
    """Kinetic energy of the particles over the exact E(t) (equal masses, rho0 l0^2 each)."""
    # mean of |u|^2 / 2 over the lattice is U^2 / 4 at t = 0 (the mean of cos^2 sin^2 is 1/4,
    # twice): E / (rho0 L^2) per unit depth
    e = 0.5 * float(np.mean(np.sum(vel**2, axis=1)))
    return e / (tg.kinetic_energy(t) / (tg.rho0 * tg.side**2))


def disorder(pos: np.ndarray, l0: float, side: float = SIDE) -> tuple[float, float]:
    """(std, min) of the nearest-neighbour distance / l0 in the periodic square."""
    tree = cKDTree(np.mod(pos, side), boxsize=side)
    d, _ = tree.query(np.mod(pos, side), k=2)
    nn = d[:, 1] / l0
    return float(np.std(nn)), float(np.min(nn))


def decay_rate_error(t: np.ndarray, ratio: np.ndarray, tg: TaylorGreen) -> float:
    """b_fit / b - 1, b_fit from the least-squares slope of ln(E_num) / 2 against t over the
    samples (E_num = ratio x E_exact); nan with fewer than three positive samples."""
    ok = np.isfinite(ratio) & (ratio > 0)
    if ok.sum() < 3:
        return math.nan
    log_e = np.log(ratio[ok]) + 2.0 * tg.decay_rate * t[ok]
    slope = float(np.polyfit(t[ok], log_e, 1)[0])
    return 0.5 * slope / tg.decay_rate - 1.0
