"""PySPH's WCSPH and EDAC schemes behind the Solver protocol: ``pysph-wcsph``, ``pysph-edac``.

The harness's problem maps onto PySPH as :mod:`.driver` describes (fluid and solid arrays,
gravity, rho0, c0, nu, moving walls, periodic axes).  What does not map is declared:

* no MPS model choice: PySPH has its own kernel (WendlandQuintic for WCSPH, QuinticSpline for
  EDAC, h = ``hdx`` l0) and its own momentum equations, so the Laplacian, the weighting
  function, the pressure gradient, the effective radii r_e and n0 do not apply
  (``Capabilities.ignores``: case parameters that set only those are not swept for this backend
  and the reports say they do not apply);
* its own stable time step (WCSPH: PySPH's adaptive rule with CFL ``cfl``; EDAC: the static rule
  of PySPH's examples); ``TimeStepping.cfl`` and ``c_nu`` do not apply, a fixed ``dt`` does;
* not supported (refused as ``unsupported`` with the reason): diffusion, inflow and outflow,
  collision, stabilization, mirrored wall velocities, gradient correction, the linear
  equation of state.  ``clip_negative_pressure`` and ``surface_beta`` (MPS free-surface
  detection) have no counterpart and do not apply either.

Pressure in ``state()``: PySPH's p of fluid and solid particles (WCSPH: Tait from the density,
solids with the Hughes-Graham clamp; EDAC: the pressure equation, solids extrapolated from the
fluid), dummy rows included (MPS gives them 0).  A PySPH step is a PEC predictor-corrector step
with two force evaluations and two neighbour updates: compare throughput per simulated second
as well as per step.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from typing import Any

import numpy as np

from mpsbench.params import Option
from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind, Particles
from mpsbench.run.protocol import Capabilities, Problem, SolverBase, UnsupportedProblem

from .driver import Settings, Simulation


def _pysph_version() -> str:
    try:
        return version("pysph")
    except PackageNotFoundError:  # pragma: no cover - the package checks before import
        return "?"


CAPABILITIES = Capabilities.own_kernels(
    physics=frozenset({"flow"}),
    boundaries=frozenset({"periodic", "periodic-x", "periodic-y", "walls", "moving-walls"}),
)


class PySPHSolver(SolverBase):
    """A PySPH scheme stepped by the runner (module docstring); subclasses pick the scheme."""

    scheme = ""
    default_kernel = ""
    default_alpha = 0.0
    version = _pysph_version()
    capabilities = CAPABILITIES
    # PySPH's generated code can segfault on a state it does not check (a NaN position in its
    # neighbour search): sweeps run each run in a supervised child process
    isolate = True

    def __init__(self, threads: int = 0, hdx: float = 1.3, alpha: float | None = None,
                 cfl: float = 0.3, update_h: bool = False, kernel: str = "") -> None:
        super().__init__()
        self.settings = Settings(self.scheme, kernel or self.default_kernel, float(hdx),
                                 self.default_alpha if alpha is None or alpha < 0 else alpha,
                                 float(cfl), bool(update_h), int(threads))
        self.sim: Simulation | None = None
        self._state: Particles | None = None
        self._rho = np.zeros(0)
        self.dt_limit = ""

    def _setup(self, problem: Problem) -> None:
        ph = problem.physics
        if not isinstance(ph, FlowPhysics):  # (the capabilities refuse it first)
            raise UnsupportedProblem(self.name, [f"physics {ph.kind!r} not supported"])
        if ph.eos != "tait" and self.scheme == "wcsph":
            raise UnsupportedProblem(self.name, [f"equation of state {ph.eos!r} not supported "
                                                 "(PySPH's WCSPH is Tait)"])
        vel = problem.particles.vel.copy()
        tags = problem.particles.fields.get("wall_tag")
        for motion in problem.wall_motions:
            if tags is not None:
                vel[(tags == motion.tag) & (problem.particles.kind != Kind.FLUID)] = (
                    motion.velocity)
        self._template = problem.particles.copy()
        self._template.vel[:] = vel
        self.sim = Simulation(problem, ph, vel, self.settings)
        self._state = None
        self._rho = np.zeros(problem.particles.n)
        self.counters["compile_s"] = self.sim.setup_s

    def _advance(self, dt: float) -> None:
        assert self.sim is not None
        self.sim.step(dt)
        self._state = None
        # two neighbour updates per PEC step (one per force evaluation)
        self.counters["neighbour_builds"] += 2

    def stable_dt(self) -> float:
        assert self.problem is not None and self.sim is not None
        fixed = self.problem.time_stepping.dt
        if fixed is not None:
            self.dt_limit = "fixed"
            return float(fixed)
        dt, self.dt_limit = self.sim.stable_dt()
        return dt

    def state(self) -> Particles:
        if self.sim is None:
            raise RuntimeError(f"{self.name}: call setup(problem) before state()")
        if self._state is None:
            p = self._template.copy()
            self.sim.read(p.pos, p.vel, p.pressure, self._rho)
            self._state = p
        return self._state

    def particle_count(self) -> int:
        return self._template.n if self.sim is not None else 0

    def diagnostics(self) -> dict[str, Any]:
        if self.sim is None:
            return {}
        self.state()
        return {"dt_limit": self.dt_limit, "density": self._rho, "h": self.sim.h,
                "kernel": self.settings.kernel, "scheme": self.scheme}


_COMMON = (
    Option("threads", 0, "OpenMP threads; 0: PySPH's serial build (OpenMP is a separate "
           "build, compiled on first use)", kind=int, minimum=0),
    Option("hdx", 1.3, "smoothing length h / l0", minimum=0.5, maximum=4.0),
    Option("cfl", 0.3, "CFL number of PySPH's adaptive time step (WCSPH)", minimum=0.01,
           maximum=1.0),
)


class PySPHWCSPH(PySPHSolver):
    """PySPH's WCSPH (Tait, Monaghan artificial viscosity, XSPH, Hughes-Graham walls)."""

    name = "pysph-wcsph"
    scheme = "wcsph"
    default_kernel = "WendlandQuintic"
    default_alpha = 0.1
    options = (
        *_COMMON,
        Option("alpha", 0.1, "Monaghan artificial viscosity (PySPH's dam break: 0.1)",
               minimum=0.0, maximum=2.0),
        Option("update_h", False, "Ferrari's smoothing-length update (PySPH's dam-break "
               "example; blows up near t = 0.94 s of it)", kind=bool),
    )


class PySPHEDAC(PySPHSolver):
    """PySPH's EDAC (entropically damped artificial compressibility, Adami walls)."""

    name = "pysph-edac"
    scheme = "edac"
    default_kernel = "QuinticSpline"
    default_alpha = 0.0
    options = (
        *_COMMON,
        Option("alpha", 0.0, "artificial viscosity (PySPH's EDAC dam break: 0)", minimum=0.0,
               maximum=2.0),
    )
