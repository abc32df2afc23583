"""Poiseuille: Morris et al.'s (1997) parameters and the errors of a velocity profile
(docs/method.md 6 f).  The exact solution is :class:`.reference.Poiseuille`."""

from __future__ import annotations

import numpy as np

from .reference import MORRIS_F, MORRIS_L, MORRIS_NU, Poiseuille

L = MORRIS_L  # m, gap between the plates
NU = MORRIS_NU  # m^2/s
F = MORRIS_F  # m/s^2, body force per unit mass along +x
RHO = 1000.0  # kg/m^3
FLOW = Poiseuille(L, NU, F)
U_MAX = FLOW.u_max  # 2.5e-5 m/s
C0 = 10.0 * U_MAX  # m/s (c0 >= 10 U_max, docs/method.md section 4)
TIMES = (0.0225, 0.045, 0.1125)  # s, Morris et al.'s profile times (as for Couette)
END_TIME = TIMES[-1]
STEADY_RUN_TIME = 0.3  # s, three diffusion times L^2 / (pi^2 nu)


def time_key(t: float) -> str:
    return f"l2_error_t{t:g}"


def profile_metrics(rows: np.ndarray, u: np.ndarray) -> dict[str, float]:
    """Errors of the profiles ``u`` (one row per time of TIMES) at the fluid rows ``rows``:
    relative L2 per time, max |e| / u_max and the centreline error at END_TIME."""
    out: dict[str, float] = {}
    for k, t in enumerate(TIMES):
        exact = FLOW.velocity(rows, t)
        out[time_key(t)] = float(np.linalg.norm(u[k] - exact) / np.linalg.norm(exact))
    exact = FLOW.velocity(rows, END_TIME)
    err = u[-1] - exact
    mid = int(np.argmin(np.abs(rows - 0.5 * L)))
    out.update(
        l2_error=out[time_key(END_TIME)],
        linf_error=float(np.max(np.abs(err))) / U_MAX,
        centreline_error=float(u[-1][mid] / exact[mid] - 1.0),
    )
    return out


def steady_error(rows: np.ndarray, u: np.ndarray) -> float:
    """Relative L2 distance of a profile from the steady parabola."""
    exact = FLOW.steady(rows)
    return float(np.linalg.norm(u - exact) / np.linalg.norm(exact))
