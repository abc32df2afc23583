"""Lid-driven cavity: the case's constants and the errors of centreline profiles against Ghia,
Ghia & Shin (1982) (docs/method.md 6 h).  The tables load, checked, from :mod:`.reference`.

A profile is sampled at the interior points of Ghia's tables (15 per centreline: the wall
points carry the boundary values and are left out) as the Shepard average of the fluid
particles within ``SAMPLE_RADIUS`` x l0 (:func:`mpsbench.run.probes.kernel_average`), and
averaged over the samples of the last ``WINDOW`` of the run: a weakly compressible particle
flow carries acoustic and disorder noise that a single snapshot would add to the error.
"""

from __future__ import annotations

import math

import numpy as np

from .reference import load_ghia

SIDE = 1.0  # L [m]
LID_SPEED = 1.0  # U [m/s]
RHO = 1000.0  # rho0 [kg/m^3]
C0 = 10.0 * LID_SPEED  # m/s (c0 >= 10 U_max, docs/method.md section 4)
SAMPLE_RADIUS = 2.0  # of l0: the Shepard kernel's support
WINDOW = 0.2  # the last fifth of the run is averaged
SAMPLES = 100  # profile samples over a run (the window holds a fifth of them)
RECOMMENDED = {"laplacian": "xu-jin", "weight": "wf2", "gradient": "pgm1", "re_ratio": 3.1}
HEADLINE_N = 40


def ghia_points(reynolds: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{"u": (y, u) on x = 0.5, "v": (x, v) on y = 0.5}, Ghia's interior points (ascending)."""
    out = {}
    for comp in ("u", "v"):
        s, val = load_ghia(comp).ascending(reynolds)
        inner = (s > 0.0) & (s < SIDE)
        out[comp] = (s[inner], val[inner])
    return out


def sample_points(reynolds: int) -> np.ndarray:
    """The points the probe samples: the u-table points on x = 0.5, then the v-table points
    on y = 0.5 (m)."""
    g = ghia_points(reynolds)
    y, x = g["u"][0], g["v"][0]
    return np.vstack([np.column_stack([np.full(len(y), 0.5 * SIDE), y]),
                      np.column_stack([x, np.full(len(x), 0.5 * SIDE)])])


def split(samples: np.ndarray, reynolds: int) -> tuple[np.ndarray, np.ndarray]:
    """(u at the u points, v at the v points) from one row of the probe."""
    n_u = len(ghia_points(reynolds)["u"][0])
    return samples[..., :n_u], samples[..., n_u:]


def profile_errors(u: np.ndarray, v: np.ndarray, reynolds: int) -> dict[str, float]:
    """RMS errors / U of the u and v centreline profiles against Ghia, their combination and
    the largest deviation; NaN when a point had no particle."""
    g = ghia_points(reynolds)
    eu, ev = u - g["u"][1], v - g["v"][1]
    if not (np.all(np.isfinite(eu)) and np.all(np.isfinite(ev))):
        return {"u_rms_error": math.nan, "v_rms_error": math.nan, "rms_error": math.nan,
                "max_error": math.nan}
    both = np.concatenate([eu, ev])
    return {
        "u_rms_error": float(np.sqrt(np.mean(eu**2))) / LID_SPEED,
        "v_rms_error": float(np.sqrt(np.mean(ev**2))) / LID_SPEED,
        "rms_error": float(np.sqrt(np.mean(both**2))) / LID_SPEED,
        "max_error": float(np.max(np.abs(both))) / LID_SPEED,
    }


def window_mean(t: np.ndarray, samples: np.ndarray, end: float) -> np.ndarray:
    """Mean of the sample rows with t >= (1 - WINDOW) end."""
    late = t >= (1.0 - WINDOW) * end - 1e-12
    return np.asarray(samples[late].mean(axis=0))


def unsteadiness(t: np.ndarray, samples: np.ndarray, end: float) -> float:
    """RMS difference / U between the window's profile and the one over the window before it:
    how far the flow still is from steady (or how noisy it is)."""
    late = t >= (1.0 - WINDOW) * end - 1e-12
    before = (t >= (1.0 - 2.0 * WINDOW) * end - 1e-12) & ~late
    if not before.any() or not late.any():
        return math.nan
    d = samples[late].mean(axis=0) - samples[before].mean(axis=0)
    return float(np.sqrt(np.nanmean(d**2))) / LID_SPEED
