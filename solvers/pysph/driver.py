"""A PySPH simulation stepped from outside: particle arrays, scheme, integrator, one step.

PySPH (https://pysph.readthedocs.io) owns its time loop in ``Application.run()``; every piece
below it is public, and ``Solver.solve()`` is a loop around ``Integrator.step(t, dt)``.  This
module builds those pieces from an mpsbench :class:`~mpsbench.run.protocol.Problem`:

* particle arrays (``pysph.base.utils.get_particle_array``): FLUID -> array ``fluid``; WALL and
  DUMMY -> one array ``solid`` (PySPH has no wall/dummy split: every boundary row is a solid
  particle), m = rho0 l0^2 (2-D, per unit depth), h = hdx l0, rho = rho0; an integer property
  ``oid`` keeps each particle's index in the problem, so states come back in its order;
* the scheme (``WCSPHScheme`` or ``EDACScheme``) with the problem's rho0, c0, nu, gravity,
  its ``setup_properties`` and equations, the PEC integrator, ``LinkedListNNPS`` with a
  ``DomainManager`` along the periodic axes of the box;
* moving walls: both schemes read a solid particle's (u, v) as the wall velocity.  WCSPH's
  ``WCSPHStep`` moves solids with (ax, ay), which no WCSPH equation writes for solids, so they
  are set to the wall velocity once; EDAC has no solid stepper, :class:`MovingWallStep` is one;
* ``Solver.setup`` compiles the generated code (PySPH caches it in ``~/.pysph``; the first use
  of a configuration costs 30-140 s), after ``set_parallel_manager(None)`` (only PySPH's
  Application sets it otherwise); then ``initial_acceleration`` once, as ``Solver.solve()``.

A guard (``Integrator.set_post_stage_callback``) checks after each integrator stage, before
PySPH's next neighbour update, that the fluid is finite and slower than c0: PySPH itself does
no checks, and a NaN position makes ``LinkedListNNPS._bin`` write outside its cell array (the
segfault of PySPH's own dam break near t = 0.94 s with the Ferrari h update).  The guard
raises ``FloatingPointError``, which the runner records as ``diverged``.

Nothing here imports PySPH at module level.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind
from mpsbench.run.protocol import Problem

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Settings:
    """How the scheme is configured (the backend's options, resolved per scheme)."""

    scheme: str  # "wcsph" or "edac"
    kernel: str
    hdx: float
    alpha: float
    cfl: float
    update_h: bool
    threads: int  # 0: the serial build; >= 1: the OpenMP build on that many threads


def moving_wall_step() -> Any:
    """An IntegratorStep moving boundary particles at their own (u, v) (EDAC has none)."""
    from .steppers import MovingWallStep

    return MovingWallStep()


def configure_threads(threads: int) -> None:
    """OpenMP is PySPH's compile-time switch (a separate build); the thread count is set before
    every step, since the OpenMP runtime is shared with other libraries in the process."""
    from compyle.config import get_config

    get_config().use_openmp = threads > 0
    if threads > 0:
        # libgomp's default spin-waiting makes 2 threads several times slower than 1 on a
        # shared machine; it reads this when it starts
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
        from pysph.base.omp_threads import set_number_of_threads

        set_number_of_threads(threads)


class Simulation:
    """One PySPH simulation of a problem, advanced by the caller (module docstring)."""

    def __init__(self, problem: Problem, physics: FlowPhysics, velocities: FloatArray,
                 settings: Settings) -> None:
        self.settings = settings
        self.physics = physics
        self.l0 = problem.l0
        self.h = settings.hdx * problem.l0
        self.n = problem.particles.n
        self.kind = problem.particles.kind.copy()
        self.t = 0.0
        t0 = time.perf_counter()
        configure_threads(settings.threads)
        self._build(problem, velocities)
        self.setup_s = time.perf_counter() - t0

    # ------------------------------------------------------------------ set-up
    def _scheme(self) -> Any:
        ph, st = self.physics, self.settings
        gx, gy = ph.gravity
        if st.scheme == "wcsph":
            from pysph.sph.scheme import WCSPHScheme

            return WCSPHScheme(["fluid"], ["solid"], dim=2, rho0=ph.rho0, c0=ph.c0, h0=self.h,
                               hdx=st.hdx, gamma=ph.gamma, gx=gx, gy=gy, alpha=st.alpha,
                               beta=0.0, nu=ph.nu, hg_correction=True, update_h=st.update_h)
        from pysph.sph.wc.edac import EDACScheme

        return EDACScheme(["fluid"], ["solid"], dim=2, c0=ph.c0, nu=ph.nu, rho0=ph.rho0,
                          pb=0.0, gx=gx, gy=gy, h=self.h, alpha=st.alpha, clamp_p=True)

    def _build(self, problem: Problem, vel: FloatArray) -> None:
        from pysph.base import kernels
        from pysph.base.nnps import DomainManager, LinkedListNNPS
        from pysph.base.utils import get_particle_array
        from pysph.sph.integrator import PECIntegrator

        ph, st, p = self.physics, self.settings, problem.particles
        fluid_idx = np.flatnonzero(p.kind == Kind.FLUID)
        solid_idx = np.flatnonzero(p.kind != Kind.FLUID)
        mass = ph.rho0 * self.l0**2
        arrays = []
        for name, idx in (("fluid", fluid_idx), ("solid", solid_idx)):
            k = len(idx)
            arrays.append(get_particle_array(
                name=name, x=p.pos[idx, 0], y=p.pos[idx, 1], u=vel[idx, 0], v=vel[idx, 1],
                m=np.full(k, mass), h=np.full(k, self.h), rho=np.full(k, ph.rho0)))
        fluid, solid = arrays
        scheme = self._scheme()
        scheme.setup_properties(arrays)  # adds the scheme's properties, removes the others
        for pa, idx in ((fluid, fluid_idx), (solid, solid_idx)):
            pa.add_property("oid", type="int")
            pa.oid[:] = idx
            if "V" in pa.properties:  # EDAC: 1 / volume, as PySPH's examples set it
                pa.V[:] = 1.0 / self.l0**2
        extra: dict[str, Any] = {}
        if np.any(solid.u != 0) or np.any(solid.v != 0):
            if st.scheme == "wcsph":
                solid.ax[:] = solid.u
                solid.ay[:] = solid.v
            else:
                for prop in ("x0", "y0"):
                    if prop not in solid.properties:
                        solid.add_property(prop)
                extra["solid"] = moving_wall_step()
        self.kernel = getattr(kernels, st.kernel)(dim=2)
        dt0 = self.limit(0.0)[0]
        scheme.configure_solver(kernel=self.kernel, integrator_cls=PECIntegrator,
                                extra_steppers=extra or None, dt=dt0, tf=math.inf,
                                adaptive_timestep=st.scheme == "wcsph", cfl=st.cfl,
                                fixed_h=not st.update_h)
        solver = scheme.get_solver()
        box = problem.box
        domain = None
        if box.any_periodic:
            domain = DomainManager(xmin=box.lo[0], xmax=box.hi[0], ymin=box.lo[1],
                                   ymax=box.hi[1], periodic_in_x=box.periodic[0],
                                   periodic_in_y=box.periodic[1])
        nnps = LinkedListNNPS(dim=2, particles=arrays, radius_scale=self.kernel.radius_scale,
                              domain=domain, fixed_h=not st.update_h, cache=False)
        solver.set_parallel_manager(None)  # PySPH's Application sets it; serial here
        try:
            solver.setup(particles=arrays, equations=scheme.get_equations(), nnps=nnps,
                         kernel=self.kernel, fixed_h=not st.update_h)
        except SystemExit as exc:  # compyle exits the process when its C++ build fails
            raise RuntimeError(f"PySPH could not compile its generated code (exit {exc.code}; "
                               "the compiler's messages are on stderr)") from None
        self.arrays, self.solver, self.integrator = arrays, solver, solver.integrator
        self.integrator.set_post_stage_callback(self._guard)
        # as Solver.solve(): the PEC integrator needs the accelerations of the initial state
        self.integrator.initial_acceleration(self.t, dt0)

    # ------------------------------------------------------------------ stepping
    def _guard(self, t: float, dt: float, stage: int) -> None:
        f = self.arrays[0]
        k = f.get_number_of_particles(real=True)
        if not k:
            return
        x, y, u, v = f.x[:k], f.y[:k], f.u[:k], f.v[:k]
        if not (np.isfinite(x).all() and np.isfinite(y).all()):
            raise FloatingPointError(f"PySPH: non-finite fluid position after stage {stage}")
        umax = float(np.sqrt(np.max(u * u + v * v)))
        if not umax <= self.physics.c0:
            raise FloatingPointError(
                f"PySPH: fluid speed {umax:.4g} m/s above c0 = {self.physics.c0:.4g} m/s after "
                f"stage {stage} (stopped before PySPH's neighbour search sees it)")

    def step(self, dt: float) -> None:
        if self.settings.threads > 0:
            configure_threads(self.settings.threads)
        self.integrator.step(self.t, dt)  # initialize, stage 1, accelerations, stage 2
        self.t += dt
        for pa in self.arrays:
            pa.set_time(self.t)

    # ------------------------------------------------------------------ time step
    def max_speed(self) -> float:
        f = self.arrays[0]
        k = f.get_number_of_particles(real=True)
        return float(np.sqrt(np.max(f.u[:k] ** 2 + f.v[:k] ** 2))) if k else 0.0

    def limit(self, umax: float) -> tuple[float, str]:
        """The static rule of PySPH's examples, min(0.25 h / (c0 + |u|max), 0.125 h^2 / nu,
        0.25 sqrt(h / |g|)), and which term sets it."""
        ph = self.physics
        options = [(0.25 * self.h / (ph.c0 + umax), "cfl")]
        if ph.nu > 0:
            options.append((0.125 * self.h**2 / ph.nu, "viscous"))
        g = math.hypot(*ph.gravity)
        if g > 0:
            options.append((0.25 * math.sqrt(self.h / g), "force"))
        dt, which = min(options)
        return float(dt), which

    def stable_dt(self) -> tuple[float, str]:
        """WCSPH: PySPH's adaptive rule (``Integrator.compute_time_step``: cfl min(h / max of
        the MomentumEquation's dt_cfl, sqrt(h / |a|max)) from the last acceleration
        evaluation) capped by the viscous limit; EDAC: the examples' static rule."""
        static, which = self.limit(self.max_speed())
        if self.settings.scheme != "wcsph":
            return static, which
        dt = self.integrator.compute_time_step(static, self.settings.cfl)
        if dt is None:
            return static, which
        dt, which = float(dt), "adaptive"
        if self.physics.nu > 0 and 0.125 * self.h**2 / self.physics.nu < dt:
            dt, which = 0.125 * self.h**2 / self.physics.nu, "viscous"
        return dt, which

    # ------------------------------------------------------------------ state
    def read(self, pos: FloatArray, vel: FloatArray, pressure: FloatArray,
             rho: FloatArray) -> None:
        """Fill (N, 2), (N, 2), (N,), (N,) arrays in the problem's order (real particles
        only: PySPH appends periodic ghosts after them)."""
        for pa in self.arrays:
            k = pa.get_number_of_particles(real=True)
            oid = pa.oid[:k]
            pos[oid, 0], pos[oid, 1] = pa.x[:k], pa.y[:k]
            vel[oid, 0], vel[oid, 1] = pa.u[:k], pa.v[:k]
            pressure[oid], rho[oid] = pa.p[:k], pa.rho[:k]
