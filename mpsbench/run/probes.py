"""Probes observe a running solver on a schedule and keep a time series.

A probe records at ``every`` seconds (from t = 0) or at the given ``at`` times; the runner shortens
steps to land exactly on them.  ``probe.t`` holds the times and ``probe.values`` the recorded
values.  Kernel averages use the WF2-shaped weight (1 - r/R)^3 over fluid particles within the
probe radius (a Shepard average: sum w q / sum w).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from mpsbench.physics.particles import Kind, Particles
from mpsbench.physics.powers import whole_power

FloatArray = NDArray[np.float64]


class Probe:
    """Base class: subclasses implement :meth:`measure`."""

    def __init__(
        self, name: str, every: float | None = None, at: Sequence[float] | None = None
    ) -> None:
        if every is None and at is None:
            raise ValueError(f"probe {name!r}: give every= (seconds) or at= (times)")
        if every is not None and not every > 0:
            raise ValueError(f"probe {name!r}: every = {every!r} must be > 0 s")
        self.name = name
        self.every = every
        self.at = sorted(float(t) for t in at) if at is not None else None
        self.t: list[float] = []
        self.values: list[Any] = []
        self._schedule: list[float] = []
        self._k = 0

    def start(self, end_time: float) -> None:
        self.t, self.values, self._k = [], [], 0
        if self.at is not None:
            self._schedule = [t for t in self.at if t <= end_time * (1 + 1e-12)]
        else:
            assert self.every is not None
            if not math.isfinite(end_time):
                self._schedule = []  # step-count runs: record every step instead
            else:
                n = int(math.floor(end_time / self.every + 1e-9))
                self._schedule = [k * self.every for k in range(n + 1)]

    def next_time(self) -> float:
        return self._schedule[self._k] if self._k < len(self._schedule) else math.inf

    def maybe_record(self, solver: Any) -> None:
        if not self._schedule and self.every is not None:  # step-count run
            self._record(solver)
            return
        while self._k < len(self._schedule) and solver.time >= self._schedule[
            self._k
        ] - 1e-12 * max(1.0, self._schedule[self._k]):
            self._k += 1
            self._record(solver)

    def _record(self, solver: Any) -> None:
        self.t.append(float(solver.time))
        self.values.append(self.measure(solver))

    def measure(self, solver: Any) -> Any:
        raise NotImplementedError

    def array(self) -> FloatArray:
        return np.asarray(self.values, dtype=float)


def kernel_average(
    points: FloatArray,
    positions: FloatArray,
    values: FloatArray,
    radius: float,
    boxsize: FloatArray | None = None,
) -> FloatArray:
    """Shepard average of ``values`` at ``points`` with weight (1 - r/R)^3; NaN where empty.

    ``values`` (n,) gives (m,); (n, k) gives (m, k), every column from one neighbour search."""
    points = np.atleast_2d(np.asarray(points, float))
    shape = (len(points), *np.shape(values)[1:])
    if len(positions) == 0:
        return np.full(shape, np.nan)
    tree = cKDTree(positions, boxsize=boxsize)
    sdm = tree.sparse_distance_matrix(
        cKDTree(points, boxsize=boxsize), radius, output_type="coo_matrix"
    )
    # (the coo output keeps exact zeros, so coincident points are counted)
    w = whole_power(1.0 - sdm.data / radius, 3)
    den = np.bincount(sdm.col, w, len(points))
    ok = den > 0
    out = np.full(shape, np.nan)
    if values.ndim == 1:
        num = np.bincount(sdm.col, w * values[sdm.row], len(points))
        out[ok] = num[ok] / den[ok]
        return out
    for c in range(values.shape[1]):
        num = np.bincount(sdm.col, w * values[sdm.row, c], len(points))
        out[ok, c] = num[ok] / den[ok]
    return out


def _quantity(p: Particles, quantity: str) -> FloatArray:
    if quantity == "u":
        return p.vel[:, 0]
    if quantity == "v":
        return p.vel[:, 1]
    if quantity == "speed":
        return np.hypot(p.vel[:, 0], p.vel[:, 1])
    if quantity == "pressure":
        return p.pressure
    if quantity in p.fields:
        return p.fields[quantity]
    raise KeyError(f"unknown quantity {quantity!r}: use u, v, speed, pressure or a field name")


class Profile(Probe):
    """A quantity (``u``, ``v``, ``speed``, ``pressure`` or a field) along a line.

    Values are kernel averages of the fluid particles within ``radius`` of each point.
    """

    def __init__(
        self,
        name: str,
        start: Sequence[float],
        end: Sequence[float],
        n_points: int,
        quantity: str,
        radius: float,
        **schedule: Any,
    ) -> None:
        super().__init__(name, **schedule)
        s = np.linspace(0.0, 1.0, n_points)
        a, b = np.asarray(start, float), np.asarray(end, float)
        self.points = a + s[:, None] * (b - a)
        self.quantity = quantity
        self.radius = radius

    def measure(self, solver: Any) -> FloatArray:
        p = solver.state()
        f = p.kind == Kind.FLUID
        return kernel_average(self.points, p.pos[f], _quantity(p, self.quantity)[f], self.radius)


class LayerAverage(Probe):
    """Mean of a quantity over fluid particles in bins along one axis (e.g. u(y) in Couette)."""

    def __init__(
        self, name: str, axis: int, edges: Sequence[float], quantity: str, **schedule: Any
    ) -> None:
        super().__init__(name, **schedule)
        self.axis = axis
        self.edges = np.asarray(edges, float)
        self.centres = 0.5 * (self.edges[1:] + self.edges[:-1])
        self.quantity = quantity

    def measure(self, solver: Any) -> FloatArray:
        p = solver.state()
        f = p.kind == Kind.FLUID
        x = p.pos[f, self.axis]
        q = _quantity(p, self.quantity)[f]
        idx = np.digitize(x, self.edges) - 1
        ok = (idx >= 0) & (idx < len(self.centres))
        num = np.bincount(idx[ok], q[ok], len(self.centres))
        den = np.bincount(idx[ok], None, len(self.centres))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0, num / np.maximum(den, 1), np.nan)


class PointPressure(Probe):
    """Kernel-averaged pressure of fluid (and wall) particles around sensor points.

    For a wall sensor put the point on the wall line and use a radius of about 2-3 l0.
    """

    def __init__(
        self,
        name: str,
        points: Sequence[Sequence[float]],
        radius: float,
        include_wall: bool = True,
        **schedule: Any,
    ) -> None:
        super().__init__(name, **schedule)
        self.points = np.atleast_2d(np.asarray(points, float))
        self.radius = radius
        self.include_wall = include_wall

    def measure(self, solver: Any) -> FloatArray:
        p = solver.state()
        use = p.kind == Kind.FLUID
        if self.include_wall:
            use = use | (p.kind == Kind.WALL)
        out = kernel_average(self.points, p.pos[use], p.pressure[use], self.radius)
        return np.nan_to_num(out, nan=0.0)  # no particle near the sensor: dry, p = 0


class SurgeFront(Probe):
    """Largest coordinate of the fluid along ``axis`` (the leading edge of a surge)."""

    def __init__(
        self, name: str, axis: int = 0, below: float | None = None, **schedule: Any
    ) -> None:
        super().__init__(name, **schedule)
        self.axis = axis
        self.below = below  # only particles with y < below (ignore splashes)

    def measure(self, solver: Any) -> float:
        p = solver.state()
        f = p.kind == Kind.FLUID
        if self.below is not None:
            f &= p.pos[:, 1] < self.below
        return float(p.pos[f, self.axis].max()) if f.any() else math.nan


class WaterHeight(Probe):
    """Highest fluid particle within ``half_width`` of x = ``x``."""

    def __init__(self, name: str, x: float, half_width: float, **schedule: Any) -> None:
        super().__init__(name, **schedule)
        self.x = x
        self.half_width = half_width

    def measure(self, solver: Any) -> float:
        p = solver.state()
        f = (p.kind == Kind.FLUID) & (np.abs(p.pos[:, 0] - self.x) <= self.half_width)
        return float(p.pos[f, 1].max()) if f.any() else 0.0


class Snapshot(Probe):
    """Copies of the particle state (positions, velocity, pressure, kind, fields)."""

    def __init__(self, name: str, with_diagnostics: bool = True, **schedule: Any) -> None:
        super().__init__(name, **schedule)
        self.with_diagnostics = with_diagnostics

    def measure(self, solver: Any) -> Particles:
        p = solver.state().copy()
        if self.with_diagnostics:
            diag = solver.diagnostics()
            nd = diag.get("number_density")
            if nd is not None and len(nd) == p.n:
                p.fields["number_density"] = np.asarray(nd, float).copy()
        return p


class Callback(Probe):
    """Any function of the solver, for one-off measurements."""

    def __init__(self, name: str, fn: Callable[[Any], Any], **schedule: Any) -> None:
        super().__init__(name, **schedule)
        self.fn = fn

    def measure(self, solver: Any) -> Any:
        return self.fn(solver)
