"""PySPH's WCSPH on the bench's own particles: the ``--pysph`` contender of ``mpsbench bench``.

PySPH (https://pysph.readthedocs.io) is optional; nothing here imports it before a stepper is
set up, and :func:`pysph_missing` says so in one line when it is not installed.

The scheme is configured as PySPH's own dam-break example configures its default scheme
(``pysph/examples/dam_break_2d.py``, PySPH 1.0b2): ``WCSPHScheme`` with the Tait equation
(gamma 7), artificial viscosity alpha = 0.1, beta = 0, the hourglass correction, h = 1.3 dx
with ``update_h``, the WendlandQuintic kernel, the PEC integrator and PySPH's adaptive time
step with its default CFL number 0.3.  What it runs on is the bench workload
(:func:`mpsbench.testing.bench.workload`): the same particles (fluid column, and the wall and
dummy rows as PySPH's one ``boundary`` array, as its example's 4-layer tank), the same sheared
start velocities, rho0, gravity and sound speed c0 = 10 sqrt(2 g H) (the example's rule
too).  So N is the same and so is the physical run, and wall time per simulated second
compares like with like (``time_to_solution_speedup``).

The bench owns the time loop, as for every contender: ``setup(problem)`` builds the arrays and
PySPH's solver and compiles its generated code (minutes the first time a configuration is
seen; later processes load it from ``~/.pysph``), ``stable_dt()`` is the time step PySPH's own
loop would take (``Integrator.compute_time_step``, without the example's damping of the first
50 steps: the bench times a run already under way), ``step(dt)`` is one PEC step
(``Integrator.step``), as ``Solver.solve`` does it.

OpenMP is PySPH's compile-time switch: ``threads`` >= 1 compiles with OpenMP and runs that
many threads (set before every step, since the OpenMP runtime is shared with numba); 0 is the
serial build.
"""

from __future__ import annotations

import importlib.util
import math
import os
from typing import Any

import numpy as np

from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind
from mpsbench.run.protocol import Problem

NAME = "pysph-wcsph"
INSTALL_HINT = ("pip install pysph (1.0b2: builds from source in about 8 minutes; needs a C++ "
                "compiler with OpenMP, at run time too)")
HDX = 1.3  # h / dx
ALPHA = 0.1  # artificial viscosity
CFL = 0.3  # PySPH's default


def pysph_missing() -> str | None:
    """None when PySPH can be imported, else the one-line reason with the install command."""
    if importlib.util.find_spec("pysph") is None:
        return f"PySPH is not installed: {INSTALL_HINT}"
    return None


def default_threads() -> int:
    """The CPUs this process may use (numba's default thread count too)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on every platform
        return os.cpu_count() or 1


class PySPHWCSPH:
    """PySPH's WCSPH dam-break scheme stepped by the bench (see the module docstring)."""

    name = NAME

    def __init__(self, threads: int | None = None) -> None:
        self.threads = default_threads() if threads is None else int(threads)
        if self.threads < 0:
            raise ValueError(f"PySPH threads = {threads!r} is not allowed: 0 (serial) or more")
        self.openmp = self.threads > 0
        self.time = 0.0
        self.version: str | None = None

    def setup(self, problem: Problem) -> None:
        # compile-time switch of the code PySPH generates: set before anything compiles
        from compyle.config import get_config

        get_config().use_openmp = self.openmp
        import pysph
        from pysph.base.kernels import WendlandQuintic
        from pysph.base.nnps import LinkedListNNPS
        from pysph.base.utils import get_particle_array
        from pysph.sph.integrator import PECIntegrator
        from pysph.sph.scheme import WCSPHScheme

        self.version = str(pysph.__version__)
        physics = problem.physics
        if not isinstance(physics, FlowPhysics):
            raise ValueError("the PySPH contender runs flow problems only")
        p = problem.particles
        dx = problem.l0
        h = HDX * dx
        rho0, c0 = physics.rho0, physics.c0
        fluid = p.kind == Kind.FLUID
        arrays = []
        for name, rows in (("fluid", fluid), ("boundary", ~fluid)):
            k = int(np.count_nonzero(rows))
            arrays.append(get_particle_array(
                name=name, x=p.pos[rows, 0], y=p.pos[rows, 1], u=p.vel[rows, 0],
                v=p.vel[rows, 1], m=np.full(k, rho0 * dx * dx), h=np.full(k, h),
                rho=np.full(k, rho0)))
        gx, gy = physics.gravity
        scheme = WCSPHScheme(["fluid"], ["boundary"], dim=2, rho0=rho0, c0=c0, h0=h, hdx=HDX,
                             gamma=7.0, gx=gx, gy=gy, alpha=ALPHA, beta=0.0,
                             hg_correction=True, update_h=True)
        scheme.setup_properties(arrays)
        kernel = WendlandQuintic(dim=2)
        self._dt0 = 0.125 * h / c0  # the example's first time step
        scheme.configure_solver(kernel=kernel, integrator_cls=PECIntegrator, dt=self._dt0,
                                tf=math.inf, adaptive_timestep=True, cfl=CFL, fixed_h=False)
        solver = scheme.get_solver()
        nnps = LinkedListNNPS(dim=2, particles=arrays, radius_scale=kernel.radius_scale,
                              fixed_h=False, cache=False)
        solver.set_parallel_manager(None)  # serial; PySPH's Application sets this before setup
        self._set_threads()
        solver.setup(particles=arrays, equations=scheme.get_equations(), nnps=nnps,
                     kernel=kernel, fixed_h=False)
        self.arrays, self.solver, self.integrator = arrays, solver, solver.integrator
        self.n = p.n
        self.time = 0.0
        # as Solver.solve: the PEC integrator needs the accelerations of the first state
        self.integrator.initial_acceleration(self.time, self._dt0)

    def _set_threads(self) -> None:
        if self.openmp:
            from pysph.base.omp_threads import set_number_of_threads

            set_number_of_threads(self.threads)

    def stable_dt(self) -> float:
        dt = self.integrator.compute_time_step(self._dt0, CFL)
        return float(self._dt0 if dt is None else dt)

    def step(self, dt: float) -> None:
        self._set_threads()
        self.integrator.step(self.time, dt)
        self.time += dt
        for pa in self.arrays:
            pa.set_time(self.time)
        # PySPH does no checks: a NaN position would crash its neighbour search (a segfault) at
        # the next step, so stop here (two passes over the fluid: far below the step's cost)
        fluid = self.arrays[0]
        if not (np.all(np.isfinite(fluid.x)) and np.all(np.isfinite(fluid.u))):
            raise FloatingPointError(f"PySPH: non-finite fluid state at t = {self.time:.4g} s")

    def fluid_state(self) -> dict[str, Any]:
        """Positions and velocities of the fluid (for a check that it ran the same flow)."""
        f = self.arrays[0]
        k = f.get_number_of_particles(real=True)
        return {"pos": np.column_stack([f.x[:k], f.y[:k]]),
                "vel": np.column_stack([f.u[:k], f.v[:k]])}
