"""Probes on hand-made particle states with known answers, and the VTU writer."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from mpsbench.physics.particles import Kind, Particles, block
from mpsbench.run.probes import (
    Callback,
    LayerAverage,
    PointPressure,
    Probe,
    Profile,
    Snapshot,
    SurgeFront,
    WaterHeight,
    kernel_average,
)


class Frozen:
    """Stands in for a solver: a fixed state, a time and diagnostics."""

    def __init__(self, p: Particles, time: float = 0.0, diag: dict[str, Any] | None = None):
        self.p = p
        self.time = time
        self._diag = diag or {}

    def state(self) -> Particles:
        return self.p

    def diagnostics(self) -> dict[str, Any]:
        return self._diag


def with_kinds(*parts: tuple[Particles, Kind]) -> Particles:
    out = []
    for p, kind in parts:
        p.kind[:] = kind
        out.append(p)
    return Particles.concat(out)


def measure(probe: Probe, p: Particles, **kw: Any) -> Any:
    return probe.measure(Frozen(p, **kw))


# --------------------------------------------------------------------------- kernel average


def test_kernel_average_of_a_linear_field_is_exact_on_symmetric_points() -> None:
    p = block(0.0, 0.0, 20, 20, 0.1)
    values = 2.0 + 3.0 * p.pos[:, 0] - 1.5 * p.pos[:, 1]
    # a particle position and a cell corner, both deep inside: symmetric neighbourhoods
    points = np.array([[1.05, 0.95], [1.0, 1.0]])
    got = kernel_average(points, p.pos, values, 0.25)
    want = 2.0 + 3.0 * points[:, 0] - 1.5 * points[:, 1]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_kernel_average_empty_and_coincident() -> None:
    pos = np.array([[0.0, 0.0], [1.0, 0.0]])
    got = kernel_average(np.array([[0.0, 0.0], [5.0, 5.0]]), pos, np.array([7.0, 1.0]), 0.5)
    assert got[0] == 7.0  # the coincident particle (r = 0, weight 1) counts
    assert math.isnan(got[1])
    assert math.isnan(kernel_average(np.zeros((1, 2)), np.zeros((0, 2)), np.zeros(0), 1.0)[0])


def test_kernel_average_wraps_across_a_periodic_box() -> None:
    p = block(0.0, 0.0, 20, 20, 0.05)
    values = np.where(p.pos[:, 0] < 0.5, 1.0, 3.0)
    point = np.array([[0.0, 0.5]])  # on the seam: half the neighbours are images
    assert kernel_average(point, p.pos, values, 0.12)[0] == pytest.approx(1.0)
    wrapped = kernel_average(point, p.pos, values, 0.12, boxsize=np.array([1.0, 1.0]))
    assert wrapped[0] == pytest.approx(2.0, abs=1e-12)


# --------------------------------------------------------------------------- probes


def couette_state() -> Particles:
    """Fluid with u = 0.5 + 2 y, v = -x, pressure = 10 + y; walls with wild values."""
    fluid = block(0.0, 0.0, 20, 20, 0.05)
    fluid.vel[:, 0] = 0.5 + 2.0 * fluid.pos[:, 1]
    fluid.vel[:, 1] = -fluid.pos[:, 0]
    fluid.pressure[:] = 10.0 + fluid.pos[:, 1]
    wall = block(0.0, -0.2, 20, 4, 0.05)
    wall.vel[:] = 100.0
    wall.pressure[:] = 1e6
    return with_kinds((fluid, Kind.FLUID), (wall, Kind.WALL))


@pytest.mark.parametrize(
    "quantity, exact",
    [
        ("u", lambda x, y: 0.5 + 2.0 * y),
        ("v", lambda x, y: -x),
        ("pressure", lambda x, y: 10.0 + y),
        ("speed", lambda x, y: np.hypot(0.5 + 2.0 * y, x)),
    ],
)
def test_profile_along_a_line(quantity: str, exact: Any) -> None:
    p = couette_state()
    probe = Profile("prof", (0.525, 0.225), (0.525, 0.725), 11, quantity, radius=0.12, every=1.0)
    got = measure(probe, p)
    x, y = probe.points[:, 0], probe.points[:, 1]
    tol = 1e-12 if quantity != "speed" else 2e-3  # speed is not linear: kernel smoothing error
    np.testing.assert_allclose(got, exact(x, y), rtol=0, atol=tol)


def test_profile_of_a_named_field_and_an_unknown_quantity() -> None:
    p = couette_state()
    p.fields["phi"] = 4.0 * p.pos[:, 0]
    probe = Profile("phi", (0.5, 0.5), (0.6, 0.5), 2, "phi", radius=0.12, every=1.0)
    np.testing.assert_allclose(measure(probe, p), [2.0, 2.4], atol=1e-12)
    with pytest.raises(KeyError, match="unknown quantity"):
        measure(Profile("x", (0, 0), (1, 1), 2, "nope", radius=0.1, every=1.0), p)


def test_layer_average_bins_fluid_only() -> None:
    fluid = Particles.from_positions(np.array([[0, 0.5], [1, 0.5], [0, 1.5], [0, 9.0]]))
    fluid.vel[:, 0] = [1.0, 3.0, 10.0, 99.0]  # the last one is outside the edges
    wall = Particles.from_positions(np.array([[0.0, 0.4]]))
    wall.vel[:, 0] = 1000.0
    p = with_kinds((fluid, Kind.FLUID), (wall, Kind.WALL))
    probe = LayerAverage("u", axis=1, edges=[0.0, 1.0, 2.0, 3.0], quantity="u", every=1.0)
    got = measure(probe, p)
    np.testing.assert_array_equal(probe.centres, [0.5, 1.5, 2.5])
    assert got[0] == 2.0 and got[1] == 10.0 and math.isnan(got[2])


def test_point_pressure_sensors() -> None:
    fluid = block(0.0, 0.0, 10, 10, 0.01)
    fluid.pressure[:] = 5.0
    wall = block(0.1, 0.0, 1, 10, 0.01)
    wall.pressure[:] = 9.0
    dummy = block(0.11, 0.0, 3, 10, 0.01)
    dummy.pressure[:] = 1e6  # never counted
    p = with_kinds((fluid, Kind.FLUID), (wall, Kind.WALL), (dummy, Kind.DUMMY))
    inside = [0.045, 0.05]
    on_wall = [0.105, 0.05]
    far = [1.0, 1.0]
    sensors = PointPressure("p", [inside, on_wall, far], radius=0.025, at=[0.0])
    got = measure(sensors, p)
    assert got[0] == pytest.approx(5.0, abs=1e-12)
    assert 5.0 < got[1] < 9.0  # a mix of fluid and wall pressure
    assert got[2] == 0.0  # dry sensor
    fluid_only = PointPressure("p", [on_wall], radius=0.025, include_wall=False, at=[0.0])
    assert measure(fluid_only, p)[0] == pytest.approx(5.0, abs=1e-12)


def test_surge_front_and_water_height() -> None:
    fluid = Particles.from_positions(np.array([[0.1, 0.05], [0.4, 0.02], [0.9, 0.5], [0.0, 0.3]]))
    wall = Particles.from_positions(np.array([[2.0, 0.0], [0.0, 5.0]]))
    p = with_kinds((fluid, Kind.FLUID), (wall, Kind.WALL))
    assert measure(SurgeFront("front", every=1.0), p) == 0.9
    assert measure(SurgeFront("front", below=0.1, every=1.0), p) == 0.4  # ignore the splash
    assert measure(SurgeFront("y", axis=1, every=1.0), p) == 0.5
    assert math.isnan(measure(SurgeFront("front", below=-1.0, every=1.0), p))
    assert measure(WaterHeight("h", x=0.05, half_width=0.06, every=1.0), p) == 0.3
    assert measure(WaterHeight("h", x=0.4, half_width=0.01, every=1.0), p) == 0.02
    assert measure(WaterHeight("h", x=5.0, half_width=0.1, every=1.0), p) == 0.0


def test_snapshot_copies_state_and_number_density() -> None:
    p = couette_state()
    nd = np.linspace(0.0, 1.0, p.n)
    solver = Frozen(p, time=0.3, diag={"number_density": nd})
    snap = Snapshot("s", at=[0.3])
    snap.start(1.0)
    snap.maybe_record(solver)
    p.pos[:] = -1.0
    nd[:] = -1.0
    (copy,) = snap.values
    assert snap.t == [0.3]
    assert copy.pos.min() >= -0.2 and copy.fields["number_density"][-1] == 1.0
    bare = Snapshot("s", with_diagnostics=False, every=1.0).measure(solver)
    assert "number_density" not in bare.fields


def test_callback_and_schedule() -> None:
    probe = Callback("t2", lambda s: 2 * s.time, every=0.25)
    probe.start(1.0)
    assert probe._schedule == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert probe.next_time() == 0.0
    solver = Frozen(block(0, 0, 1, 1, 1.0))
    for t in (0.0, 0.1, 0.25, 0.5):
        solver.time = t
        probe.maybe_record(solver)
    assert probe.t == [0.0, 0.25, 0.5] and probe.values == [0.0, 0.5, 1.0]
    assert probe.next_time() == 0.75
    np.testing.assert_array_equal(probe.array(), [0.0, 0.5, 1.0])
    at = Callback("at", lambda s: 1, at=[0.7, 0.2, 3.0])
    at.start(1.0)
    assert at._schedule == [0.2, 0.7]


# --------------------------------------------------------------------------- VTU


def test_kernel_average_of_columns_is_each_column_averaged() -> None:
    """(n, k) values give the k averages of one neighbour search, bit for bit those of k calls,
    and NaN rows where no particle is near."""
    rng = np.random.default_rng(3)
    pos = rng.random((200, 2))
    vals = rng.normal(size=(200, 2))
    pts = np.array([[0.5, 0.5], [0.1, 0.9], [5.0, 5.0]])
    both = kernel_average(pts, pos, vals, 0.15)
    assert both.shape == (3, 2)
    for c in range(2):
        np.testing.assert_array_equal(both[:, c], kernel_average(pts, pos, vals[:, c], 0.15))
    assert np.isnan(both[2]).all() and np.isfinite(both[:2]).all()
