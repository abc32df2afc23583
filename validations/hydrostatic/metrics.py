"""Hydrostatic tank: what a run's samples are reduced to (docs/method.md 6 e).

Every function here works on plain arrays (the case's probe samples), so the tests can feed
them constructed data.  Heights are in m, pressures in Pa, speeds in m/s.

Pressure.  The layer averages p_k(t) (fluid particles in bins of height l0, centres y_k) are
averaged over the settled window [t_w, T]; the exact profile is rho0 g (H - y), H the
height of the initial column (its cell edge, a row above the top particle's centre).  The
layers within ``SURFACE_LAYERS`` l0 of the surface are left out of the line fit: MPS sets the
pressure of free-surface particles to 0 (the Dirichlet condition) where the exact value is
rho0 g l0 / 2 at the top row, so those layers measure the surface condition, not the column.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from numpy.typing import NDArray

from .reference import G, pressure

FloatArray = NDArray[np.float64]

# The recommended configuration, the one the gates hold (here so that the case and its
# analysis both import it without importing each other).
RECOMMENDED = {"laplacian": "xu-jin", "weight": "wf2", "gradient": "pgm1", "re_ratio": 2.1,
               "stabilization": True}
SURFACE_LAYERS = 3  # layers below the surface left out of the pressure line fit
SETTLE_FRACTION = 0.01  # settled: RMS speed below this fraction of sqrt(2 g H)


def speed_scale(height: float, g: float = G) -> float:
    """sqrt(2 g H) [m/s]: the speed of a particle falling the column's height."""
    return math.sqrt(2.0 * g * height)


def window_mean(t: FloatArray, values: FloatArray, start: float) -> FloatArray:
    """Mean over the samples with t >= start (axis 0), ignoring NaN (empty layers)."""
    sel = np.asarray(t) >= start - 1e-12
    if not sel.any():
        return np.full(np.shape(values)[1:], math.nan)
    with warnings.catch_warnings():  # an all-NaN (empty) layer stays NaN, without a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.asarray(np.nanmean(np.asarray(values, float)[sel], axis=0))


def pressure_metrics(centres: FloatArray, p_mean: FloatArray, height: float, l0: float,
                     rho0: float, g: float = G) -> dict[str, float]:
    """Errors of the time-averaged layer pressures ``p_mean`` at layer centres ``centres``.

    ``floor_pressure_error``: p_fit(0) / (rho0 g H) - 1, p_fit the least-squares line through
    the layers below H - SURFACE_LAYERS l0; ``pressure_gradient_error``: -slope / (rho0 g) - 1;
    ``pressure_profile_error``: RMS over every layer inside the column of
    (p_k - rho0 g (H - y_k)) / (rho0 g H).
    """
    scale = rho0 * g * height
    y = np.asarray(centres, float)
    p = np.asarray(p_mean, float)
    inside = (y > 0.0) & (y < height) & np.isfinite(p)
    out = {"floor_pressure_error": math.nan, "pressure_gradient_error": math.nan,
           "pressure_profile_error": math.nan}
    if inside.any():
        exact = pressure(y[inside], height, rho0, g)
        out["pressure_profile_error"] = float(np.sqrt(np.mean((p[inside] - exact) ** 2)) / scale)
    fit = inside & (y < height - SURFACE_LAYERS * l0)
    if np.count_nonzero(fit) >= 2:
        slope, intercept = np.polyfit(y[fit], p[fit], 1)
        out["floor_pressure_error"] = float(intercept / scale - 1.0)
        out["pressure_gradient_error"] = float(-slope / (rho0 * g) - 1.0)
    return out


def settling_time(t: FloatArray, rms: FloatArray, threshold: float) -> float:
    """First sample time from which the RMS speed stays below ``threshold`` to the end
    (NaN when it never does, or is above it at the last sample)."""
    t = np.asarray(t, float)
    rms = np.asarray(rms, float)
    if len(t) == 0 or not rms[-1] < threshold:
        return math.nan
    above = np.nonzero(~(rms < threshold))[0]
    return float(t[above[-1] + 1]) if above.size else float(t[0])


def surface_height(y_fluid: FloatArray, n_top: int, l0: float) -> float:
    """Mean height of the ``n_top`` highest fluid particles plus l0/2 (their half cell) [m]:
    the free surface of a column ``n_top`` particles wide."""
    y = np.sort(np.asarray(y_fluid, float))
    if y.size == 0:
        return math.nan
    return float(np.mean(y[-max(1, n_top):]) + 0.5 * l0)


def lost_particles(pos: FloatArray, width: float) -> int:
    """Fluid particles through a wall: centre beyond a wall line (x < 0, x > width or y < 0;
    the fluid rows start half a spacing inside those lines, the wall rows half a spacing
    outside)."""
    pos = np.asarray(pos, float).reshape(-1, 2)
    out = (pos[:, 0] < 0.0) | (pos[:, 0] > width) | (pos[:, 1] < 0.0)
    return int(np.count_nonzero(out))
