"""Couette: the series solution and the errors of a velocity profile (docs/method.md 6b).

Morris et al. (1997) parameters: gap L = 1e-3 m, nu = 1e-6 m^2/s, rho0 = 1000 kg/m^3; the plate
at y = 0 is fixed, the plate at y = L moves at U = 1.25e-5 m/s in x from t = 0.
Exact: u(y, t) = U y/L + sum_n (2U/(n pi)) (-1)^n sin(n pi y/L) exp(-n^2 pi^2 nu t / L^2).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

L = 1.0e-3  # m, gap between the plates
NU = 1.0e-6  # m^2/s
RHO = 1000.0  # kg/m^3
U = 1.25e-5  # m/s, speed of the upper plate
C0 = 10.0 * U  # m/s (without drift)
SMOKE_DRIFT = 4.0e-3  # m/s: 4.5e-4 m (the L/20 strip width, 9 l0) in 0.1125 s
TIMES = (0.0225, 0.045, 0.1125)  # s, Morris et al.'s profile times
END_TIME = TIMES[-1]
STEADY_RUN_TIME = 0.3  # s
MOVING_TAG = 1


def sound_speed(params: dict[str, Any]) -> float:
    """c0 = 10 x the largest speed, U + drift (docs/method.md: c0 >= 10 U_max)."""
    return 10.0 * (U + float(params.get("drift", 0.0)))


def time_key(t: float) -> str:
    return f"l2_error_t{t:g}"


def series(y: np.ndarray | float, t: float, u_wall: float = U, gap: float = L,
           nu: float = NU) -> np.ndarray:
    """Exact start-up Couette velocity u(y, t) [m/s] (terms while exp(...) > 1e-17)."""
    y = np.asarray(y, dtype=float)
    if t <= 0:
        return np.where(y >= gap, u_wall, 0.0)
    rate = math.pi**2 * nu * t / gap**2
    n_max = min(100_000, max(1, math.ceil(math.sqrt(40.0 / rate))))
    n = np.arange(1, n_max + 1)
    exponent = -(n**2) * rate
    decay = np.where(exponent > -700.0, np.exp(np.maximum(exponent, -700.0)), 0.0)
    coef = (2.0 * u_wall / (n * math.pi)) * (-1.0) ** n * decay
    return u_wall * y / gap + np.sin(np.multiply.outer(y, n) * math.pi / gap) @ coef


def profile_metrics(rows: np.ndarray, u: np.ndarray, re: float) -> dict[str, float]:
    """Errors of the profiles ``u`` (one row per time of TIMES) at the fluid rows ``rows``."""
    out: dict[str, float] = {}
    for k, t in enumerate(TIMES):
        exact = series(rows, t)
        out[time_key(t)] = float(np.linalg.norm(u[k] - exact) / np.linalg.norm(exact))
    exact = series(rows, END_TIME)
    err = u[-1] - exact
    near = np.minimum(rows, L - rows) <= re * (1 + 1e-9)
    norm = float(np.linalg.norm(exact))
    total = float(np.sum(err**2))
    out.update(
        l2_error=out[time_key(END_TIME)],
        linf_error=float(np.max(np.abs(err))) / U,
        l2_error_near_wall=float(np.sqrt(np.sum(err[near] ** 2))) / norm,
        l2_error_interior=float(np.sqrt(np.sum(err[~near] ** 2))) / norm,
        wall_error_share=float(np.sum(err[near] ** 2)) / total if total > 0 else 0.0,
        wall_row_share=float(near.mean()),
        max_error_y=float(rows[np.argmax(np.abs(err))] / L),
    )
    return out
