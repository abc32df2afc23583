"""The Solver protocol, the Problem a solver is given, capabilities, options, and the solver
registry.

A backend implements :class:`Solver` (usually by subclassing :class:`SolverBase`, which owns the
time, step count, status and counters; or :class:`mpsbench.run.scheme.SchemeSolver`, which also
owns the WC-MPS and diffusion steps and asks the backend for its kernels).  It never owns the
time loop: the runner (:mod:`mpsbench.run.runner`) asks for ``stable_dt()``, calls ``step(dt)``,
checks ``health()`` and lets probes observe ``state()`` on their schedule.  This mirrors scipy's
``OdeSolver`` / ``solve_ivp`` split.

A backend declares its options (``options``: :class:`mpsbench.params.Option`, as a case declares
its parameters); a solver is named by a spec, ``NAME`` or ``NAME:key=value,...``
(:class:`SolverSpec`), on the command line, in study files and in records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Protocol, runtime_checkable

import numpy as np

from mpsbench.params import Option
from mpsbench.physics.config import (
    DiffusionPhysics,
    FlowPhysics,
    Inflow,
    Models,
    Region,
    TimeStepping,
    WallMotion,
)
from mpsbench.physics.particles import Box, Kind, Particles
from mpsbench.registry import Registry


class Status(StrEnum):
    """The state of a solver, and how a run ended (docs/solver-contract.md section 12).

    ``diverged``: the simulation broke down (non-finite values, runaway speed, particles leaving
    the domain); ``failed``: an exception (a solver or case bug); ``unsupported``: the solver's
    capabilities exclude the run (shown with the reason, never a failure of the case);
    ``timed-out``: a step or wall-clock limit stopped the run (the time reached is recorded);
    ``crashed``: the process running it died (a signal such as SIGSEGV in native code).
    """

    READY = "ready"
    RUNNING = "running"
    COMPLETED = "completed"
    DIVERGED = "diverged"
    FAILED = "failed"
    UNSUPPORTED = "unsupported"
    TIMED_OUT = "timed-out"
    CRASHED = "crashed"


class UnsupportedProblem(ValueError):
    """The solver does not support what the problem needs; ``reasons`` lists each gap."""

    def __init__(self, solver: str, reasons: list[str]) -> None:
        self.reasons = reasons
        super().__init__(f"solver {solver!r} cannot run this problem: " + "; ".join(reasons))


@dataclass
class Problem:
    """Everything a solver needs to start a run.

    ``particles`` is the initial state (the solver copies it).  ``box`` bounds the domain and
    says which axes are periodic.  ``l0`` is the initial particle spacing [m].
    """

    particles: Particles
    box: Box
    l0: float
    physics: DiffusionPhysics | FlowPhysics
    models: Models = field(default_factory=Models)
    time_stepping: TimeStepping = field(default_factory=TimeStepping)
    inflow: Inflow | None = None
    outflows: tuple[Region, ...] = ()
    wall_motions: tuple[WallMotion, ...] = ()
    name: str = ""

    def __post_init__(self) -> None:
        if not (isinstance(self.l0, (int, float)) and self.l0 > 0):
            raise ValueError(f"Problem.l0 = {self.l0!r} is not allowed: a number > 0 (m)")
        if self.particles.n == 0:
            raise ValueError("Problem.particles is empty: at least one particle is needed")

    def requirements(self) -> dict[str, set[str]]:
        """What this problem asks of a solver, by capability category."""
        boundaries: set[str] = set()
        if self.box.periodic == (True, True):
            boundaries.add("periodic")
        elif self.box.periodic[0]:
            boundaries.add("periodic-x")
        elif self.box.periodic[1]:
            boundaries.add("periodic-y")
        if np.any(self.particles.kind != Kind.FLUID):
            boundaries.add("walls")
        if self.wall_motions:
            boundaries.add("moving-walls")
        if any(not m.displace for m in self.wall_motions):
            boundaries.add("sliding-walls")
        if self.inflow is not None:
            boundaries.add("inflow")
        if self.outflows:
            boundaries.add("outflow")
        features: set[str] = set()
        ph = self.physics
        if isinstance(ph, FlowPhysics):
            if ph.collision:
                features.add("collision")
            if ph.stabilization:
                features.add("stabilization")
            if ph.shifting:
                features.add("shifting")
            if ph.wall_velocity == "mirror":
                features.add("mirror-walls")
        if self.models.gradient_correction:
            features.add("gradient-correction")
        return {
            "physics": {ph.kind},
            "boundaries": boundaries,
            "features": features,
            "laplacians": {self.models.laplacian},
            "weights": {self.models.weight},
            "gradients": {self.models.gradient} if isinstance(ph, FlowPhysics) else set(),
        }


_SINGULAR = {
    "physics": "physics",
    "boundaries": "boundary",
    "features": "feature",
    "laplacians": "Laplacian",
    "weights": "weighting function",
    "gradients": "pressure gradient",
}


SCHEMES = ("explicit", "semi-implicit")
"""The time-integration families of :attr:`Capabilities.scheme`."""

IGNORABLE = ("laplacians", "weights", "gradients", "radii", "time-stepping")
"""Problem settings a backend may declare it does not use (``Capabilities.ignores``): an
outside code with its own kernels has no MPS Laplacian, weighting function, pressure gradient
or effective radius to choose, and its own stable time step rule.  Each name stands for the
:class:`~mpsbench.physics.config.Models` / :class:`~mpsbench.physics.config.TimeStepping`
fields in :data:`IGNORED_FIELDS`; a case parameter that sets only such fields does not apply
to that backend (its runs are not repeated per value, and reports say so)."""

IGNORED_FIELDS: dict[str, tuple[str, ...]] = {
    "laplacians": ("models.laplacian", "models.gradient_correction"),
    "weights": ("models.weight",),
    "gradients": ("models.gradient",),
    "radii": ("models.re_ratio", "models.re_ratio_laplacian", "models.n0_from"),
    "time-stepping": ("time_stepping.cfl", "time_stepping.c_nu"),
}


@dataclass(frozen=True)
class Capabilities:
    """What a backend supports.  ``None`` for a model category means "any registered model".

    ``ignores``: settings of :data:`IGNORABLE` the backend does not use at all (not "any": a
    problem asking for any Laplacian runs, with none of them); ``Problem.requirements`` of those
    categories are then never gaps.
    """

    physics: frozenset[str] = frozenset({"diffusion", "flow"})
    boundaries: frozenset[str] = frozenset(
        {"periodic", "periodic-x", "periodic-y", "walls", "moving-walls", "inflow", "outflow"}
    )
    features: frozenset[str] = frozenset(
        {"collision", "stabilization", "mirror-walls", "gradient-correction"}
    )
    laplacians: frozenset[str] | None = None
    weights: frozenset[str] | None = None
    gradients: frozenset[str] | None = None
    ignores: frozenset[str] = frozenset()
    # "explicit": the WC-MPS step of docs/solver-contract.md (forward-Euler diffusion, pressure
    # from the equation of state, the explicit dt rule); "semi-implicit": a pressure Poisson
    # equation and backward-Euler diffusion (docs/method.md section 10).  The kit's oracles of
    # the explicit one-step update apply to the first only.
    scheme: str = "explicit"

    def __post_init__(self) -> None:
        unknown = sorted(set(self.ignores) - set(IGNORABLE))
        if unknown:
            raise ValueError(f"Capabilities.ignores = {unknown} is not allowed: names from "
                             f"{', '.join(IGNORABLE)}")
        if self.scheme not in SCHEMES:
            raise ValueError(f"Capabilities.scheme = {self.scheme!r} is not allowed: one of "
                             f"{', '.join(SCHEMES)}")

    @classmethod
    def own_kernels(cls, physics: frozenset[str], boundaries: frozenset[str]) -> Capabilities:
        """An outside code with its own kernels and time step (PySPH, an external program): no
        MPS model or feature to choose, every :data:`IGNORABLE` setting ignored."""
        return cls(physics=physics, boundaries=boundaries, features=frozenset(),
                   laplacians=frozenset(), weights=frozenset(), gradients=frozenset(),
                   ignores=frozenset(IGNORABLE))

    def ignored_fields(self) -> set[str]:
        """The Problem fields (``models.laplacian``, ...) this backend does not use."""
        return {f for name in self.ignores for f in IGNORED_FIELDS[name]}

    def gaps(self, problem: Problem) -> list[str]:
        """Reasons this backend cannot run ``problem`` (empty when it can)."""
        out = []
        for category, needed in problem.requirements().items():
            have = getattr(self, category)
            if have is None or category in self.ignores:
                continue
            for item in sorted(needed - set(have)):
                out.append(f"{_SINGULAR.get(category, category)} {item!r} not supported")
        return out

    def as_dict(self) -> dict[str, Any]:
        return {
            k: (v if isinstance(v, str) else sorted(v) if v is not None else "any")
            for k, v in self.__dict__.items()
        }


@dataclass(frozen=True)
class Health:
    """What the runner checks after every step (cheap to get: no copy of the state).

    ``finite``: every position, velocity and pressure is finite; ``max_fluid_speed`` [m/s]
    (NaN when a value is not finite, 0 without fluid); ``fluid_outside``: fluid
    particles farther than the margin outside the box along a non-periodic axis;
    ``field_max``: max |phi| of the diffusion field (NaN when one is not finite; 0 without one).
    """

    finite: bool
    max_fluid_speed: float
    fluid_outside: int
    field_max: float = 0.0


def health_of(p: Particles, box: Box, margin: float, field_name: str | None) -> Health:
    """:class:`Health` of a state, with numpy (the default :meth:`SolverBase.health`)."""
    finite = bool(np.isfinite(p.pos).all() and np.isfinite(p.vel).all()
                  and np.isfinite(p.pressure).all())
    speed, outside = (0.0 if finite else math.nan), 0
    # Masks over whole columns, not row gathers: p.pos[fluid] of an (N, 2) array costs ~100 us
    # at N = 6,400, more than a numba diffusion step, and this runs after every step.
    fluid = p.kind == Kind.FLUID
    if finite and fluid.any():
        speed2 = p.vel[:, 0] ** 2 + p.vel[:, 1] ** 2
        speed = float(np.sqrt(np.max(speed2, where=fluid, initial=0.0)))
        if not all(box.periodic):
            outside = int(np.count_nonzero(box.outside(p.pos, margin) & fluid))
    field_max = 0.0
    if field_name is not None:
        phi = p.fields[field_name]
        if not np.isfinite(phi).all():
            field_max = math.nan
        elif len(phi):
            field_max = float(np.abs(phi).max())
    return Health(finite, speed, outside, field_max)


@runtime_checkable
class Solver(Protocol):
    """What the runner needs from a backend."""

    name: str
    version: str
    capabilities: Capabilities
    time: float
    n_steps: int
    status: Status

    def setup(self, problem: Problem) -> None:
        """Take a problem (raise :class:`UnsupportedProblem` if it cannot be run)."""

    def stable_dt(self) -> float:
        """The largest stable time step for the current state [s]."""

    def step(self, dt: float) -> None:
        """Advance by ``dt`` seconds."""

    def state(self) -> Particles:
        """The current particles (a view: copy before keeping it)."""

    def health(self, margin: float) -> Health:
        """The runner's per-step check (``margin`` [m]: how far outside the box counts)."""

    def diagnostics(self) -> dict[str, Any]:
        """Extra per-particle quantities: ``number_density``, ``n0``, ``free_surface``."""


class SolverBase:
    """Bookkeeping shared by backends: time, step count, status, counters, capability checks.

    Subclasses implement ``_setup(problem)``, ``_advance(dt)``, ``stable_dt()`` and ``state()``;
    ``health()`` and the particle count per step come from ``state()`` unless a backend has a
    cheaper way (a device backend: without copying the state to the host).  ``options``: the
    keyword arguments of the constructor a solver spec may set (``NAME:key=value``).
    """

    name: str = "base"
    version: str = "0"
    capabilities: Capabilities = Capabilities()
    options: tuple[Option, ...] = ()
    # True for a backend whose native code can take the process down (a segfault in a compiled
    # library, a hang no Python check can interrupt): sweeps then run each of its runs in a
    # supervised child process even with one job (mpsbench.results.executors).
    isolate: bool = False

    def __init__(self) -> None:
        self.time = 0.0
        self.n_steps = 0
        self.status = Status.READY
        self.problem: Problem | None = None
        self.counters: dict[str, float] = {"particle_steps": 0.0, "neighbour_builds": 0.0}

    def setup(self, problem: Problem) -> None:
        gaps = self.capabilities.gaps(problem)
        if gaps:
            raise UnsupportedProblem(self.name, gaps)
        self.problem = problem
        self.time = 0.0
        self.n_steps = 0
        self.counters = {k: 0.0 for k in self.counters}
        self._setup(problem)
        self.status = Status.RUNNING

    def _require_setup(self, call: str) -> Problem:
        """The problem :meth:`setup` took; before it, a RuntimeError that names ``call``."""
        if self.problem is None:
            raise RuntimeError(f"{self.name}: call setup(problem) before {call}")
        return self.problem

    def step(self, dt: float) -> None:
        self._require_setup("step()")
        self._advance(dt)
        self.time += dt
        self.n_steps += 1
        self.counters["particle_steps"] += self.particle_count()

    def particle_count(self) -> int:
        """Particles in the current state (counted into ``particle_steps`` after each step)."""
        return self.state().n

    def health(self, margin: float) -> Health:
        problem = self._require_setup("health()")
        return health_of(self.state(), problem.box, margin,
                         getattr(problem.physics, "field_name", None))

    def diagnostics(self) -> dict[str, Any]:
        return {}

    # ---- to implement
    def _setup(self, problem: Problem) -> None:
        raise NotImplementedError

    def _advance(self, dt: float) -> None:
        raise NotImplementedError

    def stable_dt(self) -> float:
        raise NotImplementedError

    def state(self) -> Particles:
        raise NotImplementedError


def _validate_solver(obj: Any) -> None:
    if not isinstance(obj, type):
        raise TypeError(f"a solver entry must be a class, got {type(obj).__name__}")
    missing = [
        a
        for a in ("name", "version", "capabilities", "setup", "stable_dt", "step", "state")
        if not hasattr(obj, a)
    ]
    if missing:
        raise TypeError(f"solver class {obj.__name__} lacks {', '.join(missing)}")


SOLVERS: Registry[type] = Registry("solver", group="mpsbench.solvers", validate=_validate_solver)
"""Every backend, built-in or plugin, comes through the ``mpsbench.solvers`` entry-point group
(the built-ins are declared in mpsbench's own pyproject.toml)."""
