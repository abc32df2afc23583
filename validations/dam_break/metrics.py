"""Dam break: nondimensionalisation and metric functions (pure functions on arrays, no solver).

Martin & Moyce (1952), column of width ``a`` and height ``n^2 a``:

* surge front  Z = z / a,          T = t sqrt(2 g / a)  (the n^2 = 2 form of T = n t sqrt(g / a));
* column height H* = h / (n^2 a) = h / H,  tau = t sqrt(g / a).

Lobovsky et al. (2014), column height H:  p* = p / (rho g H),  t* = t sqrt(g / H).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import uniform_filter1d

FloatArray = NDArray[np.float64]
G = 9.81  # m/s^2


# ---------------------------------------------------------------- nondimensionalisation


def surge_T(t: ArrayLike, a: float, g: float = G) -> FloatArray:
    """T = t sqrt(2 g / a) for time t [s] and column width a [m]."""
    return np.asarray(t, float) * math.sqrt(2.0 * g / a)


def surge_Z(z: ArrayLike, a: float) -> FloatArray:
    """Z = z / a for the front distance z [m] from the back wall."""
    return np.asarray(z, float) / a


def height_tau(t: ArrayLike, a: float, g: float = G) -> FloatArray:
    """tau = t sqrt(g / a) [t in s, a in m]."""
    return np.asarray(t, float) * math.sqrt(g / a)


def height_star(h: ArrayLike, column_height: float) -> FloatArray:
    """H* = h / (n^2 a) = h / H with H the initial column height [m]."""
    return np.asarray(h, float) / column_height


def pressure_star(p: ArrayLike, rho: float, height: float, g: float = G) -> FloatArray:
    """p* = p / (rho g H) for p in Pa."""
    return np.asarray(p, float) / (rho * g * height)


def time_star(t: ArrayLike, height: float, g: float = G) -> FloatArray:
    """t* = t sqrt(g / H)."""
    return np.asarray(t, float) * math.sqrt(g / height)


# ---------------------------------------------------------------- curve comparisons


def curve_errors(
    x_sim: ArrayLike,
    y_sim: ArrayLike,
    x_exp: ArrayLike,
    y_exp: ArrayLike,
    x_max: float = math.inf,
) -> dict[str, float]:
    """Simulation interpolated at the experimental abscissae (x_exp <= x_max, inside the run).

    Returns ``rms`` and ``max`` of |y_sim - y_exp|, the signed ``mean`` of (y_sim - y_exp) and
    ``n`` the number of points compared (NaN errors when no point can be compared).
    """
    xs, ys = np.asarray(x_sim, float), np.asarray(y_sim, float)
    xe, ye = np.asarray(x_exp, float), np.asarray(y_exp, float)
    ok = np.isfinite(xs) & np.isfinite(ys)
    xs, ys = xs[ok], ys[ok]
    if len(xs) < 2:
        return {"rms": math.nan, "max": math.nan, "mean": math.nan, "n": 0}
    order = np.argsort(xs)
    xs, ys = xs[order], ys[order]
    use = (xe <= x_max) & (xe >= xs[0]) & (xe <= xs[-1])
    if not use.any():
        return {"rms": math.nan, "max": math.nan, "mean": math.nan, "n": 0}
    diff = np.interp(xe[use], xs, ys) - ye[use]
    return {
        "rms": float(np.sqrt(np.mean(diff**2))),
        "max": float(np.max(np.abs(diff))),
        "mean": float(np.mean(diff)),
        "n": int(use.sum()),
    }


def first_crossing(x: ArrayLike, y: ArrayLike, level: float) -> float:
    """The first x at which y reaches ``level`` (linear interpolation); NaN if it never does."""
    xs, ys = np.asarray(x, float), np.asarray(y, float)
    hit = np.nonzero(ys >= level)[0]
    if len(hit) == 0:
        return math.nan
    k = int(hit[0])
    if k == 0:
        return float(xs[0])
    y0, y1 = ys[k - 1], ys[k]
    frac = (level - y0) / (y1 - y0) if y1 != y0 else 1.0
    return float(xs[k - 1] + frac * (xs[k] - xs[k - 1]))


# ---------------------------------------------------------------- wall pressure sensors


def impact_start(t: ArrayLike, signals: ArrayLike, threshold: float) -> float:
    """First time any sensor (columns of ``signals``) exceeds ``threshold``; NaN if none does."""
    ts = np.asarray(t, float)
    s = np.atleast_2d(np.asarray(signals, float))
    if s.shape[0] != len(ts):
        s = s.T
    wet = np.nonzero(np.any(s > threshold, axis=1))[0]
    return float(ts[wet[0]]) if len(wet) else math.nan


def window_peak(t: ArrayLike, p: ArrayLike, t0: float, t1: float) -> tuple[float, float]:
    """The largest value of ``p`` for t0 <= t <= t1 and its time; (NaN, NaN) if none."""
    ts, ps = np.asarray(t, float), np.asarray(p, float)
    m = (ts >= t0) & (ts <= t1) & np.isfinite(ps)
    if not m.any():
        return math.nan, math.nan
    k = int(np.argmax(np.where(m, ps, -np.inf)))
    return float(ps[k]), float(ts[k])


def in_band(value: float, lo: float, hi: float) -> bool | None:
    """True if lo <= value <= hi; None when the value is missing."""
    if value is None or not math.isfinite(value):
        return None
    return bool(lo <= value <= hi)


def moving_average(p: ArrayLike, width: int) -> FloatArray:
    """Centred moving average over ``width`` samples (made odd)."""
    width = max(1, int(width) | 1)
    return uniform_filter1d(np.asarray(p, float), size=width, mode="nearest")


def signal_noise(t: ArrayLike, p: ArrayLike, window: float, t0: float = -math.inf) -> float:
    """High-frequency content of a sampled signal: RMS of (p - centred moving average).

    ``window`` is the averaging width in the units of ``t``; samples are assumed evenly spaced.
    Only samples with t >= t0 that are at least half a window from either end enter the RMS,
    so a smooth (even linear) signal measures ~0.  NaN if too few samples remain.
    """
    ts, ps = np.asarray(t, float), np.asarray(p, float)
    if len(ts) < 3:
        return math.nan
    dt = float(np.median(np.diff(ts)))
    width = max(3, int(round(window / dt)) | 1)
    half = width // 2
    resid = ps - moving_average(ps, width)
    idx = np.arange(len(ts))
    keep = (ts >= t0) & (idx >= half) & (idx < len(ts) - half)
    if keep.sum() < 3:
        return math.nan
    return float(np.sqrt(np.mean(resid[keep] ** 2)))


def contiguous_extent(values: ArrayLike, start: float, gap: float) -> float:
    """The far end of the run of ``values`` that starts at ``start`` with no gap wider than ``gap``.

    Used for the surge front (x of fluid particles, from the back wall) and the column height
    (y of fluid particles near the back wall, from the floor): a droplet or a clump that has
    detached by more than ``gap`` does not count.  Returns ``start`` when no value lies within
    ``gap`` of it, NaN for no values.
    """
    v = np.sort(np.asarray(values, float))
    if len(v) == 0:
        return math.nan
    v = v[v >= start - gap]
    if len(v) == 0 or v[0] > start + gap:
        return float(start)
    jumps = np.nonzero(np.diff(v) > gap)[0]
    return float(v[jumps[0]] if len(jumps) else v[-1])
