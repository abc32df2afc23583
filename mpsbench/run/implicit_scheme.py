"""The semi-implicit MPS step (Koshizuka & Oka 1996): a pressure Poisson equation per step.

:class:`SemiImplicitScheme` is a :class:`~mpsbench.run.scheme.SchemeSolver` with the same set-up
and the same step order (docs/method.md section 4, steps 1-7) except step 3: instead of the
equation of state it solves the PPE for p^{n+1} at r* (docs/method.md section 10):

1-2. predictor: viscosity (the chosen Laplacian) and gravity explicit, every particle moved;
3.   number density n* at r*, free surface (:data:`mpsbench.physics.ppe.SURFACE_RULES`),
     lap(p) = b with the chosen Laplacian (any registered model, plugins included) assembled as
     a scipy.sparse matrix over fluid, wall and inflow particles (dummy particles take no
     part), free-surface particles Dirichlet p = 0, source ``density`` / ``divergence`` /
     ``mixed`` (:func:`mpsbench.physics.ppe.source`), solved by :class:`LinearSolver`;
     negative pressures clipped when ``FlowPhysics.clip_negative_pressure``;
4-7. corrector with PGM1/2/3, collision, stabilization, wrap, open boundaries: unchanged.

Diffusion is backward Euler: (I - dt kappa L) phi^{n+1} = phi^n with L the chosen Laplacian
(its time error has the opposite sign to forward Euler's and the same first order).

Time step (:meth:`SemiImplicitScheme.stable_dt`): no sound speed.  With cfl and c_nu of the
problem's :class:`~mpsbench.physics.config.TimeStepping`,

    dt = min( cfl l0 / |u|max,  cfl l0 / sqrt(|g| h),  cfl l0 / sqrt(|p|max / rho0),
              c_nu 2 / (nu rho(L)),  2^k cfl l0 / c0 )

``flow``: a particle moves at most cfl l0 per step; ``gravity-wave``: a surface gravity wave
on the fluid's depth h (its extent along g, plus l0) crosses at most cfl l0 per step, the limit
of a fluid at rest (without it a resting column steps at the free-fall scale sqrt(l0/g) and its
surface layer goes unstable, docs/method.md section 10); ``pressure``: the pressure level acts
explicitly through the pair forces of the gradient models (PGM1's pmin repulsion, PGM3's
p_i + p_j), with the speed sqrt(p/rho0) (for a column at rest the same as the gravity-wave
limit; without it a uniformly compressed closed fluid steps at the viscous limit and those pair
forces amplify round-off by dt^2 p / (rho0 l0^2) per step); ``viscous``: the explicit viscous term
(docs/method.md section 4); ``start-up``: the first step is the acoustic step
cfl l0 / c0 of WC-MPS and step k at most 2^k times that (before the first
solve there is no pressure for the ``pressure`` limit to see: a compressed fluid at rest without
gravity would otherwise take its first step at the viscous limit).

Per solve the scheme records the method, iterations, the true relative residual, the tolerance,
the unknowns and the assembly / set-up / solve times: ``diagnostics()["linear_solve"]`` for the
last step, ``diagnostics()["linear_history"]`` per step (start time of the step, iterations,
residual, converged; and the tolerance), and ``counters`` (``linear_solves``,
``linear_iterations``, ``linear_iterations_max``, ``linear_residual_max``, ``linear_assembly_s``,
``linear_setup_s``, ``linear_solve_s``) over the run; records carry them (docs/columns.md).

A backend implements the hooks of :class:`~mpsbench.run.scheme.SchemeSolver` plus:

=========================  =====================================================================
``_ppe_laplacian()``       the chosen Laplacian at r_e,lap over the current pairs, as an (N, N)
                           scipy.sparse matrix, pairs with a dummy particle left out
``_divergence()``          div(u)_i (docs/method.md section 2) at the current positions, r_e, n0,
                           neighbours of every kind
``_neighbour_offset()``    |sum_j r_ij W_ij| / sum_j W_ij at r_e (the ``distribution`` rule)
``_diffusion_matrix()``    the Laplacian assembled by ``_setup_diffusion``
=========================  =====================================================================
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.particles import Kind
from mpsbench.physics.ppe import (
    COMPRESSIBILITY,
    SOURCES,
    SURFACE_RULES,
    assemble,
    carries_pressure,
    free_surface,
    source,
)
from mpsbench.run.linsolve import LinearSolver, NotConverged, SolveStats
from mpsbench.run.protocol import Problem
from mpsbench.run.scheme import SchemeSolver

FloatArray = NDArray[np.float64]

SLIVER = 0.25  # a step below this fraction of the previous one is a sliver (_density_step)

COUNTERS = ("linear_solves", "linear_iterations", "linear_iterations_max", "linear_residual_max",
            "linear_assembly_s", "linear_setup_s", "linear_solve_s")


class SemiImplicitScheme(SchemeSolver):
    """Semi-implicit MPS and backward-Euler diffusion (module docstring)."""

    def __init__(
        self,
        source: str = "density",
        relaxation: float = 0.01,
        density_relaxation: float = 0.2,
        surface: str = "density",
        surface_offset: float = 0.2,
        linear_solver: str = "cg",
        preconditioner: str = "jacobi",
        tol: float = 1e-8,
        max_iterations: int = 0,
        compressibility: str = "closed",
        blas_threads: int = 1,
    ) -> None:
        super().__init__()
        for name, value, allowed in (("source", source, SOURCES),
                                     ("surface", surface, SURFACE_RULES),
                                     ("compressibility", compressibility, COMPRESSIBILITY)):
            if value not in allowed:
                raise ValueError(f"{name} = {value!r} is not allowed: one of "
                                 f"{', '.join(allowed)}")
        if not (0.0 <= relaxation <= 1.0):
            raise ValueError(f"relaxation = {relaxation!r} is not allowed: a number in [0, 1]")
        if not (0.0 < density_relaxation <= 1.0):
            raise ValueError(f"density_relaxation = {density_relaxation!r} is not allowed: "
                             "a number in (0, 1]")
        self.source = source
        self.relaxation = float(relaxation)
        self.density_relaxation = float(density_relaxation)
        self.surface = surface
        self.surface_offset = float(surface_offset)
        self.compressibility = compressibility
        self.linear = LinearSolver(linear_solver, preconditioner, tol, max_iterations,
                                   blas_threads)
        self.counters.update({k: 0.0 for k in COUNTERS})
        self.last_solve: dict[str, Any] = {}
        # per solve (one per step): iterations, true relative residual, tolerance met
        self.solve_history: dict[str, list[Any]] = {"time": [], "iterations": [],
                                                    "residual": [], "converged": []}
        self._backward: tuple[float, sp.csr_matrix, bool] | None = None
        self.previous_dt: float | None = None

    def _setup(self, problem: Problem) -> None:
        # a solver set up again starts a new history (the counters are reset by setup())
        self.last_solve = {}
        self.solve_history = {k: [] for k in self.solve_history}
        self._backward = None
        self.previous_dt = None  # the step before, for _density_step
        super()._setup(problem)

    # ------------------------------------------------------------------ the step
    def _advance(self, dt: float) -> None:
        ph = self.problem.physics  # type: ignore[union-attr]
        if isinstance(ph, DiffusionPhysics):
            self._backward_euler(self.p.fields[ph.field_name], dt * ph.kappa)
            return
        super()._advance(dt)

    def _pressure_step(self, dt: float, ph: FlowPhysics) -> None:
        t0 = time.perf_counter()
        self._update_neighbours()
        n = self._number_density()
        self.number_density = n
        kind = self.p.kind
        offset = self._neighbour_offset() if self.surface == "distribution" else None
        surface = free_surface(self.surface, n, self.n0, ph.surface_beta, kind, offset,
                               self.surface_offset * self.l0)
        unknown = carries_pressure(kind) & ~surface
        lap = self._ppe_laplacian()
        div = self._divergence() if self.source != "density" else None
        b = source(self.source, n, self.n0, ph.rho0, dt, div, self.relaxation,
                   self.density_relaxation, dt_ref=self._density_step(dt))
        self.previous_dt = dt
        system = assemble(lap, unknown, b, kappa=1.0 / (ph.c0 * dt) ** 2,
                          compressibility=self.compressibility)
        assembly = time.perf_counter() - t0
        # warm start from the previous step's pressure, closed groups set to their level
        x, stats = self.linear.solve(system.matrix, system.rhs, system.symmetric,
                                     x0=system.level(self.p.pressure[unknown]))
        self._record(stats, assembly, dirichlet=int((carries_pressure(kind) & surface).sum()),
                     closed_groups=system.closed_groups)
        pres = system.expand(x)
        if ph.clip_negative_pressure:
            np.maximum(pres, 0.0, out=pres)
        self.p.pressure[:] = pres
        self.free_surface = surface

    def _density_step(self, dt: float) -> float | None:
        """The step of the density source's 1/dt^2 (:func:`mpsbench.physics.ppe.source`): dt,
        except in a sliver step, shorter than SLIVER times the previous one, which the runner
        takes between two events close together (down to 0.4 us after 0.41 ms steps in the
        Lobovsky dam break): the previous step there, so that the sliver keeps the previous
        step's pressure instead of (previous / dt)^2 times it."""
        prev = self.previous_dt
        return prev if prev is not None and dt < SLIVER * prev else None

    def _backward_euler(self, phi: FloatArray, factor: float) -> None:
        """(I - factor L) phi^{n+1} = phi^n; the matrix (and the preconditioner) are kept while
        the factor stays the same."""
        t0 = time.perf_counter()
        if self._backward is None or self._backward[0] != factor:
            lap = self._diffusion_matrix()
            m = sp.csr_matrix(sp.identity(lap.shape[0], format="csr") - factor * lap)
            sym = bool(abs(m - m.T).max() <= 1e-12 * abs(m).max()) if m.nnz else True
            self._backward = (factor, m, sym)
        _, m, sym = self._backward
        assembly = time.perf_counter() - t0
        x, stats = self.linear.solve(m, phi, sym, x0=phi.copy(), reuse=True)
        self._record(stats, assembly)
        phi[:] = x

    def _record(self, stats: SolveStats, assembly: float, **extra: Any) -> None:
        c = self.counters
        c["linear_solves"] += 1
        c["linear_iterations"] += stats.iterations
        c["linear_iterations_max"] = max(c["linear_iterations_max"], stats.iterations)
        c["linear_residual_max"] = max(c["linear_residual_max"], stats.residual)
        c["linear_assembly_s"] += assembly
        c["linear_setup_s"] += stats.setup_s
        c["linear_solve_s"] += stats.solve_s
        h = self.solve_history
        h["time"].append(self.time)
        h["iterations"].append(stats.iterations)
        h["residual"].append(stats.residual)
        h["converged"].append(stats.converged)
        self.last_solve = {
            "method": stats.method, "iterations": stats.iterations, "residual": stats.residual,
            "tol": stats.tol, "converged": stats.converged, "unknowns": stats.unknowns,
            "assembly_s": assembly, "setup_s": stats.setup_s, "solve_s": stats.solve_s, **extra,
        }
        if not stats.converged:
            raise NotConverged(
                f"{stats.method} did not reach tol {stats.tol:g} in {stats.iterations} "
                f"iterations: relative residual {stats.residual:.3g} ({stats.unknowns} unknowns)"
            )

    # ------------------------------------------------------------------ protocol
    def stable_dt(self) -> float:
        assert self.problem is not None
        ph = self.problem.physics
        ts = self.problem.time_stepping
        if ts.dt is not None or isinstance(ph, DiffusionPhysics):
            return super().stable_dt()
        limits: dict[str, float] = {}
        umax = self._max_speed() if self.p.n else 0.0
        if umax > 0:
            limits["flow"] = ts.cfl * self.l0 / umax
        g = math.hypot(*ph.gravity)
        if g > 0:
            limits["gravity-wave"] = ts.cfl * self.l0 / math.sqrt(g * self._depth(ph.gravity))
        pmax = float(np.abs(self.p.pressure).max()) if self.p.n else 0.0
        if pmax > 0:
            limits["pressure"] = ts.cfl * self.l0 / math.sqrt(pmax / ph.rho0)
        if ph.nu > 0 and self.rho_lap > 0:
            limits["viscous"] = ts.c_nu * 2.0 / (ph.nu * self.rho_lap)
        # start-up: the first step at the acoustic step of WC-MPS, step k at most 2^k times
        # that, until the limits above (which need a pressure and a flow) take over
        limits["start-up"] = ts.cfl * self.l0 / ph.c0 * 2.0 ** min(self.n_steps, 60)
        self.dt_limit = min(limits, key=lambda k: limits[k])
        return float(limits[self.dt_limit])

    def _depth(self, gravity: tuple[float, float]) -> float:
        """The fluid's extent along gravity [m], at least l0 (the depth of the gravity-wave
        limit; 0 fluid particles: l0)."""
        fluid = self.p.kind == Kind.FLUID
        if not fluid.any():
            return self.l0
        g = np.asarray(gravity, float)
        along = self.p.pos[fluid] @ (g / np.linalg.norm(g))
        return max(float(along.max() - along.min()) + self.l0, self.l0)

    def diagnostics(self) -> dict[str, Any]:
        out = super().diagnostics()
        out["linear_solve"] = dict(self.last_solve)
        out["linear_history"] = {
            "time": np.asarray(self.solve_history["time"], float),
            "iterations": np.asarray(self.solve_history["iterations"], int),
            "residual": np.asarray(self.solve_history["residual"], float),
            "converged": np.asarray(self.solve_history["converged"], bool),
            "tol": self.linear.tol,
        }
        return out

    # ------------------------------------------------------------------ the backend's hooks
    def _ppe_laplacian(self) -> sp.csr_matrix:
        raise NotImplementedError

    def _divergence(self) -> FloatArray:
        raise NotImplementedError

    def _neighbour_offset(self) -> FloatArray:
        raise NotImplementedError

    def _diffusion_matrix(self) -> sp.csr_matrix:
        raise NotImplementedError
