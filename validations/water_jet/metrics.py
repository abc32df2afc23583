"""Reference solution and metrics of the impinging-jet case (docs/method.md 6c).

* :func:`free_streamline_cp`: the plate pressure coefficient of the steady free-streamline
  (potential-flow) solution of a plane jet of width b hitting an infinite plate normally.
  Parametric form, with s = wall speed / U in [0, 1):
  x/b = (2/pi) [artanh(s) + arctan(s)],  Cp = p / (rho U^2 / 2) = 1 - s^2.
  It is evaluated by Newton's method in tau = artanh(s) (x/b = (2/pi)[tau + arctan(tanh tau)],
  Cp = sech^2 tau), which converges monotonically from tau = pi |x/b| / 4 because the map is
  increasing and concave.  Its momentum balance: integral of Cp d(x/b) over the plate = 2,
  i.e. integral of p dx = rho U^2 b.
* :func:`pressure_deviation`: p_i minus the kernel mean of its neighbours' pressure (the spatial
  pressure-noise measure).
* :func:`frame_measures`: the per-snapshot noise, number-density drift and penetration numbers.

Pressures in Pa, lengths in m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.particles import Kind
from mpsbench.physics.powers import whole_power
from mpsbench.physics.weights import get_weight

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

# docs/method.md 6c: Cp at x/b = 0, 0.2, ..., 2.0 (used by the tests as an independent oracle)
TABLE_XB = np.round(np.arange(11) * 0.2, 10)
TABLE_CP = np.array([1.000, 0.975, 0.902, 0.782, 0.628, 0.461, 0.309, 0.192, 0.112, 0.063, 0.035])

NOISE_RADIUS = 2.1  # kernel-mean radius of the noise measure, in l0
_TAU_MAX = 300.0  # sech^2(300) ~ 1e-260: Cp is zero to double precision beyond


def free_streamline_x(s: ArrayLike) -> FloatArray:
    """x/b of the point where the wall speed is s U (0 <= s < 1)."""
    s = np.asarray(s, float)
    return (2.0 / np.pi) * (np.arctanh(s) + np.arctan(s))


def free_streamline_cp(x_over_b: ArrayLike, tol: float = 1e-14) -> FloatArray:
    """Plate Cp(x/b) of the free-streamline solution (symmetric in x)."""
    x = np.abs(np.asarray(x_over_b, float))
    tau = 0.25 * np.pi * x  # a lower bound of the root: Newton then increases monotonically
    for _ in range(60):
        th = np.tanh(tau)
        f = (2.0 / np.pi) * (tau + np.arctan(th)) - x
        df = (2.0 / np.pi) * (1.0 + (1.0 - th**2) / (1.0 + th**2))
        step = f / df
        tau = np.minimum(tau - step, _TAU_MAX)
        if np.all(np.abs(step) <= tol * np.maximum(1.0, tau)):
            break
    e = np.exp(-2.0 * tau)  # sech^2 tau = 4 e / (1 + e)^2, no overflow for large tau
    return 4.0 * e / (1.0 + e) ** 2


def number_density(pos: FloatArray, weight: str, re: float) -> FloatArray:
    """n_i = sum_j W(r_ij) over every particle (all kinds), as the solvers compute it."""
    pairs = build_pairs(pos, re)
    w = get_weight(weight).w(pairs.r, re)
    return pairs.sum_sym(w)


def pressure_deviation(
    pos: FloatArray, pressure: FloatArray, carries: BoolArray, radius: float
) -> tuple[FloatArray, BoolArray]:
    """p_i minus the Shepard mean of p_j over neighbours j != i within ``radius``.

    Only particles in ``carries`` (fluid, wall and inflow particles: those with a pressure)
    enter the mean.  Weight (1 - r/R)^3, the same for every model, so the measure does not
    change with the weighting function under test.  Returns the deviation and a mask of
    particles that had at least one neighbour (the deviation is 0 elsewhere).
    """
    pairs = build_pairs(pos, radius)
    w = whole_power(1.0 - np.minimum(pairs.r / radius, 1.0), 3)
    wi = w * carries[pairs.j]  # weight of j in the mean of i
    wj = w * carries[pairs.i]  # weight of i in the mean of j
    n = len(pos)
    num = np.bincount(pairs.i, wi * pressure[pairs.j], n) + np.bincount(
        pairs.j, wj * pressure[pairs.i], n
    )
    den = np.bincount(pairs.i, wi, n) + np.bincount(pairs.j, wj, n)
    ok = den > 0
    dev = np.zeros(n)
    dev[ok] = pressure[ok] - num[ok] / den[ok]
    return dev, ok


def surface_centroid(pos: FloatArray, is_fluid: BoolArray, radius: float, l0: float) -> BoolArray:
    """Free-surface fluid particles: the centroid of their neighbours (all kinds) is off-centre.

    A particle on a flat surface of a square lattice has its neighbour centroid 0.625 l0 away
    (r_e = 2.1 l0), one row deeper 0.18 l0, an interior one 0.  The threshold is 0.3 l0.
    Unlike a number-density test this does not flag an expanded (n < beta n0) interior region.
    """
    pairs = build_pairs(pos, radius)
    n = len(pos)
    cnt = np.bincount(pairs.i, None, n) + np.bincount(pairs.j, None, n)
    sx = np.bincount(pairs.i, pairs.dx[:, 0], n) - np.bincount(pairs.j, pairs.dx[:, 0], n)
    sy = np.bincount(pairs.i, pairs.dx[:, 1], n) - np.bincount(pairs.j, pairs.dx[:, 1], n)
    off = np.hypot(sx, sy) / np.maximum(cnt, 1)
    return is_fluid & ((off > 0.3 * l0) | (cnt < 3))


def interior_fluid(pos: FloatArray, kind: NDArray[np.int8], re: float, l0: float) -> BoolArray:
    """Fluid particles at least r_e from every free-surface fluid particle (full support)."""
    fluid = kind == Kind.FLUID
    surface = surface_centroid(pos, fluid, re, l0)
    near = np.zeros(len(pos), dtype=bool)
    if surface.any():
        pairs = build_pairs(pos, re)
        near[pairs.i[surface[pairs.j]]] = True
        near[pairs.j[surface[pairs.i]]] = True
    return fluid & ~surface & ~near


@dataclass
class FrameMeasures:
    """Noise and drift numbers of one snapshot (sums, so frames can be pooled)."""

    noise_sq_sum: float  # sum over measured particles of (deviation / q)^2
    noise_count: int
    drift_sum: float  # sum over interior particles of |n_i/n0 - 1|
    drift_max: float
    drift_count: int
    nn_sum: float = 0.0  # sum over fluid particles of the nearest-neighbour distance / l0
    nn_close: int = 0  # how many of them have a neighbour closer than the collision distance
    nn_count: int = 0
    # fluid next to the plate (see ``near_wall`` of :func:`frame_measures`)
    wall_dn_sum: float = 0.0  # sum of n_i/n0 - 1
    wall_cp_sum: float = 0.0  # sum of p_i / q (the solver's pressure, clipped at 0)
    wall_count: int = 0


def frame_measures(
    pos: FloatArray,
    pressure: FloatArray,
    kind: NDArray[np.int8],
    *,
    l0: float,
    weight: str,
    re: float,
    n0: float,
    q: float,
    beta: float,
    region: tuple[float, float] | None = None,
    close_distance: float = 0.0,
    near_wall: tuple[float, float] | None = None,
) -> FrameMeasures:
    """Spatial pressure noise and number-density drift of one state.

    Noise: (p_i - kernel mean of neighbours' p) / q over fluid particles that are not free
    surface (n_i >= beta n0, the solvers' rule, so their pressure is not zeroed by
    construction) and lie inside ``region`` = (|x| max, y max) if given.  Drift: |n_i/n0 - 1|
    over interior fluid particles (:func:`interior_fluid`) inside ``region``.  Spacing: the
    nearest-neighbour distance (any kind) of every fluid particle inside ``region``, in l0, and
    how many are closer than ``close_distance`` l0 (where a collision model can act).
    Near wall: number density and pressure of the fluid particles with |x| <= ``near_wall[0]``
    and y < ``near_wall[1]`` (the rows just above a plate whose wall line is y = 0), so a caller
    can compare the pressure they carry with the one their mean compression implies.
    """
    fluid = kind == Kind.FLUID
    carries = fluid | (kind == Kind.WALL) | (kind == Kind.INFLOW)
    inside = np.ones(len(pos), dtype=bool)
    if region is not None:
        inside = (np.abs(pos[:, 0]) <= region[0]) & (pos[:, 1] <= region[1])
    n = number_density(pos, weight, re)
    dev, ok = pressure_deviation(pos, pressure, carries, NOISE_RADIUS * l0)
    sel = fluid & inside & ok & (n >= beta * n0)
    noise = dev[sel] / q
    interior = interior_fluid(pos, kind, re, l0) & inside
    drift = np.abs(n[interior] / n0 - 1.0)
    probe = fluid & inside
    nn = np.zeros(0)
    if probe.any() and len(pos) > 1:
        nn = cKDTree(pos).query(pos[probe], k=2)[0][:, 1] / l0
    wall_zone = np.zeros(len(pos), dtype=bool)
    if near_wall is not None:
        wall_zone = fluid & (np.abs(pos[:, 0]) <= near_wall[0]) & (pos[:, 1] < near_wall[1])
    return FrameMeasures(
        wall_dn_sum=float(np.sum(n[wall_zone] / n0 - 1.0)),
        wall_cp_sum=float(np.sum(pressure[wall_zone]) / q),
        wall_count=int(wall_zone.sum()),
        noise_sq_sum=float(np.sum(noise**2)),
        noise_count=int(sel.sum()),
        drift_sum=float(drift.sum()),
        drift_max=float(drift.max()) if drift.size else 0.0,
        drift_count=int(drift.size),
        nn_sum=float(nn.sum()),
        nn_close=int(np.sum(nn < close_distance)),
        nn_count=int(nn.size),
    )


def pooled(frames: list[FrameMeasures]) -> dict[str, float]:
    """Pool frames: RMS noise over all measured particle-frames; mean and max drift."""
    nc = sum(f.noise_count for f in frames)
    dc = sum(f.drift_count for f in frames)
    kc = sum(f.nn_count for f in frames)
    wc = sum(f.wall_count for f in frames)
    return {
        "near_wall_cp": sum(f.wall_cp_sum for f in frames) / wc if wc else np.nan,
        "near_wall_dn": sum(f.wall_dn_sum for f in frames) / wc if wc else np.nan,
        "noise_spatial": float(np.sqrt(sum(f.noise_sq_sum for f in frames) / nc)) if nc else np.nan,
        "density_drift_mean": sum(f.drift_sum for f in frames) / dc if dc else np.nan,
        "density_drift_max": max((f.drift_max for f in frames), default=np.nan),
        "nn_distance_mean": sum(f.nn_sum for f in frames) / kc if kc else np.nan,
        "close_fraction": sum(f.nn_close for f in frames) / kc if kc else np.nan,
    }


def penetrations(pos: FloatArray, kind: NDArray[np.int8], half_plate: float) -> int:
    """Fluid particles below the plate's wall line (y < 0) within the plate span."""
    fluid = kind == Kind.FLUID
    return int(np.sum(fluid & (pos[:, 1] < 0.0) & (np.abs(pos[:, 0]) <= half_plate)))


def stabilization_viscosity(weight: str, re_ratio: float, l0: float, alpha_s: float,
                            dt: float) -> float:
    """Viscosity [m^2/s] the stabilization (docs/method.md 5) adds to a smooth velocity field.

    u_i <- u_i + (alpha_s l0 / n0) sum_j |W'_ij| (u_j - u_i) once per step; for a smooth field
    the sum is (1/4) sum_j |W'_ij| r_ij^2 lap(u) on an isotropic lattice, so per unit time it is
    a diffusion with nu_s = alpha_s l0 sum_j |W'_ij| r_ij^2 / (4 n0 dt): it grows as dt shrinks.
    """
    wf = get_weight(weight)
    re = re_ratio * l0
    m = int(np.ceil(re_ratio)) + 1
    ix, iy = np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1), indexing="ij")
    r = l0 * np.hypot(ix.ravel(), iy.ravel())
    r = r[r > 0]
    n0 = float(wf.w(r, re).sum())
    moment = float(np.sum(np.abs(wf.dw(r, re)) * r**2))
    return alpha_s * l0 * moment / (4.0 * n0 * dt)


def plate_profile(samples: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Time mean and std of plate Cp samples (rows: times; columns: sensors at x/b = -X..X,
    symmetric about the middle one), folded onto x >= 0 by averaging the two sides."""
    mid = samples.shape[1] // 2
    mean, std = samples.mean(axis=0), samples.std(axis=0)
    return 0.5 * (mean[mid:] + mean[mid::-1]), 0.5 * (std[mid:] + std[mid::-1])


def cp_errors(xb: FloatArray, cp: FloatArray, x_max: float) -> tuple[float, float]:
    """RMS and max |Cp - Cp_exact| over the sensors at 0 <= x/b <= x_max."""
    inside = xb <= x_max + 1e-9
    err = cp[inside] - free_streamline_cp(xb[inside])
    return float(np.sqrt(np.mean(err**2))), float(np.max(np.abs(err)))


def tait_cp(dn: float, c0_over_u: float, gamma: float = 7.0) -> float:
    """Cp = p / (rho U^2 / 2) of the Tait equation at n/n0 = 1 + dn, not clipped."""
    return float(2.0 * c0_over_u**2 / gamma * ((1.0 + dn) ** gamma - 1.0))


def plate_force_ratio(xb: FloatArray, cp: FloatArray) -> float:
    """Integral of a plate Cp profile over 0 <= x/b <= xb[-1] against the free-streamline one.

    In a steady jet the plate force equals the jet's momentum flux rho U^2 b (integral of Cp
    d(x/b) over the whole plate = 2), whatever the profile's shape, so a ratio away from 1 says
    the plate pressure does not balance the momentum the jet brings - in a particle model either
    momentum is not conserved or the wall particles' pressure is not the force the fluid feels -
    rather than that the pressure was redistributed.
    """
    x = np.linspace(0.0, float(xb[-1]), 20001)
    exact = float(np.trapezoid(free_streamline_cp(x), x))
    return float(np.trapezoid(cp, xb)) / exact


def temporal_noise(series: FloatArray) -> float:
    """Standard deviation of a time series relative to its mean (NaN if the mean is 0)."""
    series = np.asarray(series, float)
    mean = float(series.mean()) if series.size else 0.0
    return float(series.std() / abs(mean)) if mean != 0 else np.nan
