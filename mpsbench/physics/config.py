"""Frozen, validated configuration dataclasses: models, physics, time stepping, boundaries.

Every value is checked when the object is built; a bad value raises :class:`ConfigError` naming
the field, the value and what is allowed.  Units are SI.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields
from typing import Any, Literal

import numpy as np

from mpsbench.errors import ConfigError


def _fail(owner: str, name: str, value: Any, allowed: str) -> None:
    raise ConfigError(f"{owner}.{name} = {value!r} is not allowed: {allowed}")


def _is_number(value: Any) -> bool:
    """A real number (numpy scalars included) that is not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _positive(owner: str, name: str, value: Any, allow_zero: bool = False) -> None:
    ok = _is_number(value) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        _fail(owner, name, value, "a finite number " + (">= 0" if allow_zero else "> 0"))


def _choice(owner: str, name: str, value: Any, choices: tuple[str, ...]) -> None:
    if value not in choices:
        _fail(owner, name, value, "one of " + ", ".join(repr(c) for c in choices))


def _in_range(owner: str, name: str, value: Any, lo: float, hi: float) -> None:
    ok = _is_number(value) and lo <= value <= hi
    if not ok:
        _fail(owner, name, value, f"a number in [{lo}, {hi}]")


def _boolean(owner: str, name: str, value: Any) -> None:
    if not isinstance(value, (bool, np.bool_)):
        _fail(owner, name, value, "True or False")


def _vector(owner: str, name: str, value: Any, unit: str, nonzero: bool = False) -> None:
    ok = (
        isinstance(value, (tuple, list, np.ndarray))
        and len(value) == 2
        and all(_is_number(v) and math.isfinite(v) for v in value)
    )
    if ok and nonzero:
        ok = math.hypot(*value) > 0
    if not ok:
        what = "a non-zero" if nonzero else "a"
        _fail(owner, name, value, f"{what} pair of finite numbers (x, y) in {unit}")


def _registered(owner: str, name: str, value: Any, registry: Any) -> None:
    if not isinstance(value, str) or value not in registry:
        _fail(owner, name, value, "one of " + ", ".join(repr(n) for n in registry.names()))


@dataclass(frozen=True)
class Models:
    """Which MPS models a run uses.

    ``re_ratio`` is r_e/l0 for number density, pressure gradient, collision and stabilization;
    ``re_ratio_laplacian`` is r_e/l0 for the Laplacian (defaults to ``re_ratio``).
    ``n0_from``: ``"initial"`` takes n0 and lambda at an interior particle of the initial
    arrangement; ``"lattice"`` takes them from the ideal square lattice of spacing l0 (use it
    when the initial arrangement is jittered).
    """

    weight: str = "wf2"
    laplacian: str = "xu-jin"
    gradient: str = "pgm1"
    re_ratio: float = 2.1
    re_ratio_laplacian: float | None = None
    gradient_correction: bool = False
    n0_from: Literal["initial", "lattice"] = "initial"

    def __post_init__(self) -> None:
        from mpsbench.physics.gradients import GRADIENTS
        from mpsbench.physics.laplacians import LAPLACIANS
        from mpsbench.physics.weights import WEIGHTS

        _registered("Models", "weight", self.weight, WEIGHTS)
        _registered("Models", "laplacian", self.laplacian, LAPLACIANS)
        _registered("Models", "gradient", self.gradient, GRADIENTS)
        _in_range("Models", "re_ratio", self.re_ratio, 1.0, 10.0)
        if self.re_ratio_laplacian is not None:
            _in_range("Models", "re_ratio_laplacian", self.re_ratio_laplacian, 1.0, 10.0)
        _boolean("Models", "gradient_correction", self.gradient_correction)
        if self.gradient_correction and self.laplacian != "xu-jin":
            _fail("Models", "gradient_correction", True, "only with laplacian 'xu-jin'")
        _choice("Models", "n0_from", self.n0_from, ("initial", "lattice"))

    @property
    def re_lap_ratio(self) -> float:
        return self.re_ratio if self.re_ratio_laplacian is None else self.re_ratio_laplacian


@dataclass(frozen=True)
class DiffusionPhysics:
    """Scalar diffusion on fixed particles: d phi/dt = kappa lap(phi), forward Euler.

    The scalar lives in ``Particles.fields[field_name]``; ``kappa`` in m^2/s.
    """

    kappa: float = 1.0
    field_name: str = "phi"

    kind = "diffusion"

    def __post_init__(self) -> None:
        _positive("DiffusionPhysics", "kappa", self.kappa)
        if not isinstance(self.field_name, str) or not self.field_name:
            _fail("DiffusionPhysics", "field_name", self.field_name, "a non-empty string")


STABILIZATION_RATES = ("step", "acoustic")
"""What ``FlowPhysics.alpha_s`` is per: a time step, or an acoustic step (docs/method.md 5)."""


@dataclass(frozen=True)
class FlowPhysics:
    """WC-MPS flow (docs/method.md sections 4-5).

    rho0 [kg/m^3], nu [m^2/s], gravity [m/s^2], c0 [m/s] (sound speed of the equation of state).
    """

    rho0: float = 1000.0
    nu: float = 1.0e-6
    gravity: tuple[float, float] = (0.0, -9.81)
    c0: float = 10.0
    eos: Literal["tait", "linear"] = "tait"
    gamma: float = 7.0
    clip_negative_pressure: bool = True
    surface_beta: float = 0.97
    collision: bool = False
    collision_distance: float = 0.8  # alpha_c, fraction of l0
    restitution: float = 0.2
    stabilization: bool = False
    alpha_s: float = 0.01
    stabilization_walls: bool = True  # wall and dummy particles are neighbours in its sum
    # "step": alpha_s per time step (the paper's form: its added viscosity grows as 1/dt);
    # "acoustic": alpha_s per acoustic step cfl l0 / c0, whatever the scheme's step
    stabilization_rate: Literal["step", "acoustic"] = "step"
    wall_velocity: Literal["prescribed", "mirror"] = "prescribed"
    # particle shifting after the move (docs/method.md section 5b): D = shifting_coefficient
    # r_e max|u| dt
    shifting: bool = False
    shifting_coefficient: float = 1.0

    kind = "flow"

    def __post_init__(self) -> None:
        o = "FlowPhysics"
        _positive(o, "rho0", self.rho0)
        _positive(o, "nu", self.nu, allow_zero=True)
        _vector(o, "gravity", self.gravity, "m/s^2")
        _positive(o, "c0", self.c0)
        _choice(o, "eos", self.eos, ("tait", "linear"))
        _positive(o, "gamma", self.gamma)
        _in_range(o, "surface_beta", self.surface_beta, 0.5, 1.0)
        _in_range(o, "collision_distance", self.collision_distance, 0.0, 1.0)
        _in_range(o, "restitution", self.restitution, 0.0, 1.0)
        _in_range(o, "alpha_s", self.alpha_s, 0.0, 1.0)
        _choice(o, "wall_velocity", self.wall_velocity, ("prescribed", "mirror"))
        _choice(o, "stabilization_rate", self.stabilization_rate, STABILIZATION_RATES)
        _in_range(o, "shifting_coefficient", self.shifting_coefficient, 0.0, 10.0)
        for flag in ("clip_negative_pressure", "collision", "stabilization", "stabilization_walls",
                     "shifting"):
            _boolean(o, flag, getattr(self, flag))

    def stabilization_alpha(self, dt: float, l0: float, cfl: float) -> float:
        """The stabilization coefficient of a step of ``dt`` [s] (docs/method.md section 5).

        ``step``: ``alpha_s`` (each step smooths the velocities by the same fraction, so the
        added viscosity is proportional to 1/dt); ``acoustic``: ``alpha_s dt c0 / (cfl l0)``,
        alpha_s per acoustic step cfl l0 / c0: the damping per unit of time is that of a
        WC-MPS run of the same problem at rest, whatever step the scheme takes (a
        semi-implicit step is 10-20 times the acoustic one).
        """
        if self.stabilization_rate == "step":
            return self.alpha_s
        return self.alpha_s * dt * self.c0 / (cfl * l0)


@dataclass(frozen=True)
class TimeStepping:
    """dt = min(cfl l0 / (c0 + |u|max), c_nu 2 / (nu rho(L))) unless ``dt`` is fixed.

    rho(L) is the Gershgorin bound of the Laplacian's spectral radius, 2 max_i sum_j |c_ij|
    (docs/method.md section 4: derive the viscous limit from the model, not a fixed constant); for
    diffusion the limit is c_nu 2 / (kappa rho(L)).  ``c_nu`` is the fraction of the
    forward-Euler limit 2 / rho(L) used.  :meth:`stable_dt` is the rule every backend applies.
    """

    dt: float | None = None
    cfl: float = 0.2
    c_nu: float = 0.5

    def __post_init__(self) -> None:
        if self.dt is not None:
            _positive("TimeStepping", "dt", self.dt)
        _in_range("TimeStepping", "cfl", self.cfl, 1e-6, 1.0)
        _in_range("TimeStepping", "c_nu", self.c_nu, 1e-6, 1.0)

    def stable_dt(
        self, physics: DiffusionPhysics | FlowPhysics, l0: float, umax: float, rho_lap: float
    ) -> float:
        """The time step [s] for the current state.

        ``umax``: largest particle speed [m/s]; ``rho_lap``: the Gershgorin bound of the
        Laplacian's spectral radius [1/m^2] (0 when unknown: no viscous limit).
        """
        return self.limit(physics, l0, umax, rho_lap)[0]

    def limit(
        self, physics: DiffusionPhysics | FlowPhysics, l0: float, umax: float, rho_lap: float
    ) -> tuple[float, str]:
        """:meth:`stable_dt` and which limit sets it: ``fixed``, ``cfl`` (sound speed and flow
        speed), ``viscous`` (flow) or ``diffusion``."""
        if self.dt is not None:
            return self.dt, "fixed"
        if isinstance(physics, DiffusionPhysics):
            dt = self.c_nu * 2.0 / (physics.kappa * rho_lap) if rho_lap > 0 else math.inf
            return dt, "diffusion"
        dt = self.cfl * l0 / (physics.c0 + umax)
        which = "cfl"
        if physics.nu > 0 and rho_lap > 0:
            viscous = self.c_nu * 2.0 / (physics.nu * rho_lap)
            if viscous < dt:
                dt, which = viscous, "viscous"
        return float(dt), which


@dataclass(frozen=True)
class Inflow:
    """Particles enter with ``velocity`` through a straight inlet.

    The inlet is the segment from ``start`` to ``end``; the reservoir holds ``layers`` rows of
    inflow particles upstream of it (they carry ``velocity`` and count as boundary particles
    until they cross the inlet line, then become fluid).  A new row is created upstream each
    time the last one has advanced by l0.
    """

    start: tuple[float, float]
    end: tuple[float, float]
    velocity: tuple[float, float]
    layers: int = 4

    def __post_init__(self) -> None:
        _vector("Inflow", "start", self.start, "m")
        _vector("Inflow", "end", self.end, "m")
        if tuple(self.start) == tuple(self.end):
            _fail("Inflow", "end", self.end, f"a point different from start = {self.start}")
        _vector("Inflow", "velocity", self.velocity, "m/s", nonzero=True)
        ok = isinstance(self.layers, numbers.Integral) and not isinstance(self.layers, bool)
        if not ok or self.layers < 1:
            _fail("Inflow", "layers", self.layers, "an integer >= 1")


@dataclass(frozen=True)
class Region:
    """Axis-aligned rectangle [lo, hi]; particles inside an outflow region are removed."""

    lo: tuple[float, float]
    hi: tuple[float, float]

    def __post_init__(self) -> None:
        _vector("Region", "lo", self.lo, "m")
        _vector("Region", "hi", self.hi, "m")
        if not (self.hi[0] > self.lo[0] and self.hi[1] > self.lo[1]):
            _fail("Region", "hi", self.hi, f"greater than lo = {self.lo} on both axes")


@dataclass(frozen=True)
class WallMotion:
    """Boundary particles tagged ``tag`` (``Particles.fields['wall_tag']``) move at ``velocity``.

    ``displace = False``: the particles carry ``velocity`` (the viscous term and the
    stabilization see it) but keep their positions, a wall sliding along itself such as a
    cavity's lid or a belt: its surface moves, its particles stay.  A solver supports it when
    its capabilities list the boundary ``sliding-walls``.
    """

    tag: int
    velocity: tuple[float, float]
    displace: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.tag, numbers.Integral) or isinstance(self.tag, bool):
            _fail("WallMotion", "tag", self.tag, "an integer")
        _vector("WallMotion", "velocity", self.velocity, "m/s")
        _boolean("WallMotion", "displace", self.displace)


def replace_validated(obj: Any, **changes: Any) -> Any:
    """``dataclasses.replace`` that rejects unknown field names with the list of known ones."""
    from dataclasses import replace

    known = {f.name for f in fields(obj)}
    unknown = sorted(set(changes) - known)
    if unknown:
        raise ConfigError(
            f"{type(obj).__name__} has no field(s) {', '.join(unknown)}; "
            f"known: {', '.join(sorted(known))}"
        )
    return replace(obj, **changes)


