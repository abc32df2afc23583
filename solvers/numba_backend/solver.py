"""The numba backend: the reference backend's physics over a cell-linked list, compiled.

Same models, boundary conventions and order of operations as
:class:`mpsbench.solvers.reference.ReferenceSolver` (docs/method.md sections 2-5), so the two
agree to rounding:

* diffusion: phi <- phi + dt kappa L phi, L held as per-entry coefficients of a CSR list built
  once (particles are fixed);
* flow (WC-MPS): predictor (viscosity + gravity), number density at r* fused with the equation
  of state and the free-surface test, corrector with pgm1/2/3, optional collision (a boundary
  neighbour is infinitely heavy), optional stabilization (with or without wall neighbours).

Boundary conventions (as the reference): wall particles take part in pressure and in every
operator; dummy particles complete the number density and carry the wall velocity into the
viscous term but are left out of the pressure gradient; inflow particles act like wall
particles until they cross the inlet.  Pairs of a dummy particle with a boundary particle that
moves rigidly with it are static: their number density is summed once at setup and the pairs
never enter the neighbour list.

Neighbours: one cell-list CSR list at max(r_e, r_e,lap) + skin, rebuilt when a particle has
moved more than skin/2, and a sub-list at r_e + skin for the kernels at the smaller radius.
The ``mirror`` wall velocities (a kernel-weighted linear fit at mirror points) are compiled too
(:mod:`.mirror`); inflow and outflow bookkeeping (not hot) reuse the reference backend's code.
"""

from __future__ import annotations

import multiprocessing
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from mpsbench.physics.boundaries import InflowBoundary, carry, update_open_boundaries
from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.operators import lattice_constants
from mpsbench.physics.particles import Kind, Particles
from mpsbench.physics.weights import get_weight
from mpsbench.run.protocol import Capabilities, Problem, SolverBase

from . import kernels, pairs, steps
from .cells import CellNeighbourList, CSRNeighbours, box_period, build_csr
from .mirror import mirror_velocity

FloatArray = NDArray[np.float64]



@contextmanager
def _threads(k: int) -> Iterator[None]:
    """Run the block with ``k`` numba threads, then restore the caller's setting.

    With one thread the serial kernel builds run and the threading layer is left alone (it
    is not even started: a forked worker process must not touch OpenMP, see :mod:`._jit`).
    """
    if k == 1:
        yield
        return
    before = numba.get_num_threads()
    if before == k:
        yield
        return
    numba.set_num_threads(k)
    try:
        yield
    finally:
        numba.set_num_threads(before)


class NumbaSolver(SolverBase):
    """numba-compiled cell-list WC-MPS and diffusion backend (agrees with ``reference``)."""

    name = "numba"
    version = "1.0"
    capabilities = Capabilities(
        laplacians=frozenset(kernels.LAPLACIAN_CODES),
        weights=frozenset(kernels.WEIGHT_CODES),
        gradients=frozenset(kernels.GRADIENT_CODES),
    )
    skin_ratio = 0.3  # neighbour-list skin in units of l0 (as the reference)
    parallel_min = 8_000
    """With ``threads=None``, problems with fewer particles run on one thread: a parallel region
    costs a barrier per kernel (a dozen per step), which small problems do not repay, and on a
    loaded machine (or next to other worker processes) a barrier can wait a whole scheduler
    time slice for a descheduled thread.  Inside a worker process of a pool (a study run with
    ``--jobs`` > 1) every problem runs on one thread: the pool already uses the cores."""

    def __init__(self, threads: int | None = None, pairwise: bool = True) -> None:
        super().__init__()
        if threads is not None and (not isinstance(threads, int) or threads < 1):
            raise ValueError(f"NumbaSolver: threads = {threads!r} is not allowed: an integer >= 1")
        self.requested_threads = threads
        self.pairwise = bool(pairwise)
        """Flow on half lists (:mod:`.pairs`: each pair evaluated once); False: the row kernels
        of :mod:`.kernels` on full lists (also used with the xu-jin gradient correction)."""
        self.threads = 1
        self.timings: dict[str, float] = {}

    def _k(self, fn: Any) -> Any:
        """The build of a compiled kernel for this run: serial on one thread (:mod:`._jit`)."""
        return fn.serial if self.threads == 1 else fn

    def _choose_threads(self, n: int) -> int:
        available = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
        if self.requested_threads is not None:
            return min(self.requested_threads, available)
        if n < self.parallel_min or multiprocessing.parent_process() is not None:
            return 1
        return numba.get_num_threads()

    def setup(self, problem: Problem) -> None:
        self.threads = self._choose_threads(problem.particles.n)
        with _threads(self.threads):
            super().setup(problem)

    def step(self, dt: float) -> None:
        with _threads(self.threads):
            super().step(dt)

    # ------------------------------------------------------------------ setup
    def _setup(self, problem: Problem) -> None:
        t0 = time.perf_counter()
        m = problem.models
        self.l0 = problem.l0
        self.box = problem.box
        self.period = box_period(problem.box)
        self.weight = get_weight(m.weight)
        self.wcode = kernels.weight_code(m.weight)
        self.lcode = kernels.laplacian_code(m.laplacian)
        self.gcode = kernels.GRADIENT_CODES[m.gradient]
        self.gcorr = bool(m.gradient_correction)
        self.re = m.re_ratio * self.l0
        self.re_lap = m.re_lap_ratio * self.l0
        self.p = problem.particles.copy()
        self.inflow: InflowBoundary | None = None
        if problem.inflow is not None:
            self.inflow = InflowBoundary(problem.inflow, self.l0)
            self.p = Particles.concat([self.p, self.inflow.initial()])
        for motion in problem.wall_motions:
            tagged = self.p.fields.get("wall_tag", np.full(self.p.n, -1.0)) == motion.tag
            self.p.vel[tagged & (self.p.kind != Kind.FLUID)] = motion.velocity
        self.n0, _ = self._reference_constants(self.re)
        self.n0_lap, self.lam = self._reference_constants(self.re_lap)
        self.pref = kernels.laplacian_prefactor(self.lcode, self.n0_lap, self.lam)
        self.number_density = np.zeros(self.p.n)
        self.free_surface = np.zeros(self.p.n, dtype=bool)
        self._lap_rowsum = 0.0
        if isinstance(problem.physics, DiffusionPhysics):
            self._setup_diffusion(problem.physics)
        else:
            self._setup_flow(problem.physics)
        self.timings["setup_s"] = time.perf_counter() - t0

    def _full_list(self, re: float) -> CSRNeighbours:
        """Every pair within the closed support of ``re`` (no static pairs left out)."""
        return build_csr(
            self.p.pos, CellNeighbourList.padded(re, 0.0), self.box, serial=self.threads == 1
        )

    def _reference_constants(self, re: float) -> tuple[float, float]:
        """n0 and lambda: ideal lattice, or the fullest-support particle of the initial state."""
        assert self.problem is not None
        if self.problem.models.n0_from == "lattice":
            return lattice_constants(self.weight, re / self.l0, self.l0)
        csr = self._full_list(re)
        n = self._k(kernels.number_density)(
            csr.offsets, csr.nbr, self.p.pos, self.period, self.wcode, re, np.empty(self.p.n)
        )
        cand = self.p.kind == Kind.FLUID
        if not cand.any():
            cand = np.ones(self.p.n, dtype=bool)
        idx = int(np.nonzero(cand)[0][np.argmax(n[cand])])
        n0, moment = steps.row_constants(
            csr.offsets, csr.nbr, self.p.pos, self.period, self.wcode, re, idx
        )
        if n0 <= 0:
            raise ValueError(f"no particle has neighbours within r_e = {re}")
        return float(n0), float(moment / n0)

    # ------------------------------------------------------------------ diffusion
    def _setup_diffusion(self, physics: DiffusionPhysics) -> None:
        if physics.field_name not in self.p.fields:
            raise ValueError(
                f"diffusion needs the scalar field {physics.field_name!r} "
                "in Problem.particles.fields"
            )
        self.p.fields[physics.field_name] = np.ascontiguousarray(
            self.p.fields[physics.field_name], dtype=np.float64
        )
        csr = self._full_list(max(self.re, self.re_lap))
        self.counters["neighbour_builds"] += 1
        self._diff_csr = csr
        self._coef = np.empty(len(csr.nbr))
        rows = np.empty(self.p.n)
        self._k(steps.operator_entries)(
            csr.offsets, csr.nbr, self.p.pos, self.period, self.lcode, self.wcode, self.re_lap,
            self.pref, self.n0_lap, self.gcorr, self._coef, rows,
        )
        self._lap_rowsum = float(rows.max()) if self.p.n else 0.0
        self._work = np.empty(self.p.n)
        self._upper: tuple[Any, Any, Any] | None = None
        if not self.gcorr and self.threads == 1:
            # c_ij = c_ji (a function of r_ij only): keep each pair once, serial scatter
            row = np.repeat(np.arange(self.p.n), np.diff(csr.offsets))
            up = csr.nbr.astype(np.int64) > row
            offsets = np.zeros(self.p.n + 1, np.int64)
            np.cumsum(np.bincount(row[up], minlength=self.p.n), out=offsets[1:])
            self._upper = (
                offsets, np.ascontiguousarray(csr.nbr[up]), np.ascontiguousarray(self._coef[up])
            )
        self.number_density = self._k(kernels.number_density)(
            csr.offsets, csr.nbr, self.p.pos, self.period, self.wcode, self.re, np.empty(self.p.n)
        )

    def _advance_diffusion(self, dt: float, physics: DiffusionPhysics) -> None:
        phi = self.p.fields[physics.field_name]
        if self._upper is not None:
            steps.symmetric_step(*self._upper, phi, dt * physics.kappa, self._work)
            return
        csr = self._diff_csr
        self._k(steps.operator_apply)(csr.offsets, csr.nbr, self._coef, phi, self._work)
        self._k(steps.axpy)(phi, dt * physics.kappa, self._work)

    # ------------------------------------------------------------------ flow
    def _setup_flow(self, physics: FlowPhysics) -> None:
        r_max = max(self.re, self.re_lap)
        small = self.re if self.re < r_max else None
        self._half = self.pairwise and not self.gcorr
        self.neigh = CellNeighbourList(
            r_max, self.skin_ratio * self.l0, self.box, r_small=small, half=self._half,
            serial=self.threads == 1,
        )
        self._chunk_build = -1
        self._set_static()
        self._allocate()
        self.neigh.update(self.p.pos)
        self.counters["neighbour_builds"] = self.neigh.builds
        _, small_list = self._lists()
        if self._half:
            self._k(pairs.density_pairs)(
                *small_list, self.p.pos, self.period, self.wcode, self.re, self._chunks()[1],
                self._acc_n,
            )
            self.number_density = self._acc_n.sum(axis=0) + self.static_n
        else:
            self.number_density = self.static_n + self._k(kernels.number_density)(
                *small_list, self.p.pos, self.period, self.wcode, self.re, np.empty(self.p.n)
            )
        self._viscous(self.p.vel, mirror=False)  # the row sums for the first stable_dt()

    def _set_static(self) -> None:
        """Rigid groups and the static number density (pairs that never change)."""
        p = self.p
        kind = p.kind
        solid = (kind != Kind.FLUID) & (kind != Kind.INFLOW)
        group = np.full(p.n, -1, np.int64)
        if solid.any():
            v = p.vel[solid] + 0.0  # -0.0 and 0.0 are the same velocity
            _, inv = np.unique(v, axis=0, return_inverse=True)
            group[solid] = inv.ravel()
        self.group = group
        self.loose = np.ascontiguousarray(kind == Kind.WALL)
        self.neigh.set_static(group=self.group, loose=self.loose)
        self.static_n = np.zeros(p.n)
        if solid.any():
            csr = self._full_list(self.re)
            self._k(steps.static_density)(
                csr.offsets, csr.nbr, p.pos, self.period, self.wcode, self.re, self.group,
                self.loose, self.static_n,
            )

    def _allocate(self) -> None:
        n = self.p.n
        self._lap = np.zeros((n, 2))
        self._rows = np.zeros(n)
        self._grad = np.empty((n, 2))
        self._du = np.empty((n, 2))
        self._tmp = np.empty((n, 2))
        self._stab = np.zeros((n, 2))
        self._pmin = np.empty(n)
        self._inner = np.zeros(n, dtype=bool)
        k = pairs.CHUNKS
        self._acc_v = np.zeros((k, n, 2))  # per-chunk accumulators of the half-list kernels
        self._acc_n = np.zeros((k, n))
        self._acc_rows = np.zeros((k, n))
        if len(self.number_density) != n:
            self.number_density = np.zeros(n)
            self.free_surface = np.zeros(n, dtype=bool)

    def _lists(self) -> tuple[tuple[Any, Any], tuple[Any, Any]]:
        """((offsets, nbr) of the big list, (offsets, nbr) of the list at r_e)."""
        big = self.neigh.csr
        assert big is not None
        small = self.neigh.small if self.neigh.small is not None else big
        return (big.offsets, big.nbr), (small.offsets, small.nbr)

    def _chunks(self) -> tuple[Any, Any]:
        """Chunk bounds of the big and the small half list (recomputed after a rebuild)."""
        if self._chunk_build != self.neigh.builds:
            big, small = self._lists()
            self._bounds = (pairs.chunk_bounds(big[0]), pairs.chunk_bounds(small[0]))
            self._chunk_build = self.neigh.builds
        return self._bounds

    def _viscous(self, vel: FloatArray, mirror: bool) -> None:
        """Laplacian of the (mirrored) velocity (``_lap`` or ``_acc_v``); max |c| row sum over
        fluid particles into ``_lap_rowsum``."""
        big, _ = self._lists()
        u = vel
        if mirror:
            u = mirror_velocity(self.p, self.wcode, self.re, self.box, self.threads == 1)
        if self._half:
            self._k(pairs.laplacian_pairs)(
                *big, self.p.pos, self.period, u, self.lcode, self.wcode, self.re_lap, self.pref,
                self._chunks()[0], self._acc_v, self._acc_rows,
            )
            self._lap_rowsum = float(pairs.fluid_row_max(self._acc_rows, self.p.kind))
            return
        self._k(kernels.laplacian_field)(
            *big, self.p.pos, self.period, u, self.lcode, self.wcode, self.re_lap, self.pref,
            self.n0_lap, self.gcorr, self._lap, self._rows, self.p.kind == Kind.FLUID,
        )
        self._lap_rowsum = float(steps.max_over(self._rows, self.p.kind, True))  # fluid rows

    def _advance_flow(self, dt: float, ph: FlowPhysics) -> None:
        if self._half:
            self._advance_pairs(dt, ph)
        else:
            self._advance_rows(dt, ph)
        if self.box.any_periodic:
            self.box.wrap(self.p.pos)
        self._update_open_boundaries(dt)

    def _advance_pairs(self, dt: float, ph: FlowPhysics) -> None:
        """One WC-MPS step on half lists (same steps as :meth:`_advance_rows`)."""
        p = self.p
        kind = p.kind
        acc = self._acc_v
        # ---- predictor: viscosity + gravity, then move
        self.neigh.update(p.pos)
        if ph.nu > 0:
            self._viscous(p.vel, mirror=ph.wall_velocity == "mirror")
        self._k(pairs.predictor_from)(
            p.pos, p.vel, acc, ph.nu > 0, ph.nu, ph.gravity[0], ph.gravity[1], dt, kind
        )
        if self.box.any_periodic:
            self.box.wrap(p.pos)
        # ---- number density at r*, equation of state, free surface
        self.neigh.update(p.pos)
        _, small = self._lists()
        bounds = self._chunks()[1]
        self._k(pairs.density_pairs)(
            *small, p.pos, self.period, self.wcode, self.re, bounds, self._acc_n
        )
        tait = ph.eos == "tait"
        pref = ph.rho0 * ph.c0**2 / ph.gamma if tait else ph.rho0 * ph.c0**2
        self._k(pairs.pressure_from)(
            self._acc_n, self.static_n, kind, self.n0, tait, pref, ph.gamma,
            ph.clip_negative_pressure, ph.surface_beta, self.number_density, p.pressure,
            self.free_surface, self._inner,
        )
        # ---- corrector: pressure gradient without dummy particles
        no_dummy = kind != Kind.DUMMY
        if self.gcode in (1, 2):
            self._k(pairs.pmin_pairs)(
                *small, p.pos, self.period, p.pressure, no_dummy, self.wcode, self.re, bounds,
                self._acc_n,
            )
            pairs._combine_min(self._acc_n, self._pmin)
        self._k(pairs.gradient_pairs)(
            *small, p.pos, self.period, p.pressure, self._pmin, no_dummy, kind, self.gcode,
            self.wcode, self.re, bounds, acc,
        )
        factor = np.array([kernels.DIM / self.n0, -(dt / ph.rho0)])
        self._k(pairs.pressure_increment_from)(acc, kind, factor, self._du)
        if ph.collision:
            self._k(steps.add_into)(p.vel, self._du, self._tmp)
            self._k(pairs.collision_pairs)(
                *small, p.pos, self.period, self._tmp, kind, ph.collision_distance * self.l0,
                ph.restitution, 1.0, bounds, acc,
            )
            self._k(pairs.add_from)(acc, self._du)
        p.vel += self._du
        if ph.stabilization:
            self._k(pairs.stabilization_pairs)(
                *small, p.pos, self.period, p.vel, kind, self._inner, ph.stabilization_walls,
                self.wcode, self.re, bounds, acc,
            )
        self._k(pairs.corrector_from)(
            p.pos, p.vel, self._du, dt, acc, -ph.alpha_s * self.l0 / self.n0, ph.stabilization
        )

    def _advance_rows(self, dt: float, ph: FlowPhysics) -> None:
        """One WC-MPS step with the row kernels on full lists."""
        p = self.p
        kind = p.kind
        # ---- predictor: viscosity + gravity, then move
        self.neigh.update(p.pos)
        if ph.nu > 0:  # (without viscosity the row sums are not needed either)
            self._viscous(p.vel, mirror=ph.wall_velocity == "mirror")
        self._k(steps.predictor)(
            p.pos, p.vel, self._lap, ph.nu > 0, ph.nu, ph.gravity[0], ph.gravity[1], dt, kind
        )
        if self.box.any_periodic:
            self.box.wrap(p.pos)
        # ---- number density at r*, equation of state, free surface
        self.neigh.update(p.pos)
        _, small = self._lists()
        tait = ph.eos == "tait"
        pref = ph.rho0 * ph.c0**2 / ph.gamma if tait else ph.rho0 * ph.c0**2
        self._k(steps.density_pressure)(
            *small, p.pos, self.period, self.wcode, self.re, self.static_n, kind, self.n0, tait,
            pref, ph.gamma, ph.clip_negative_pressure, ph.surface_beta, self.number_density,
            p.pressure, self.free_surface, self._inner,
        )
        # ---- corrector: pressure gradient without dummy particles
        no_dummy = kind != Kind.DUMMY
        if self.gcode == 2:
            self._k(kernels.neighbour_min)(
                *small, p.pos, self.period, p.pressure, no_dummy, self.wcode, self.re, self._pmin
            )
        self._k(kernels.pressure_gradient)(
            *small, p.pos, self.period, p.pressure, self._pmin if self.gcode == 2 else p.pressure,
            no_dummy, self.gcode, self.wcode, self.re, self.n0, self._grad, kind == Kind.FLUID,
        )
        self._k(steps.pressure_increment)(self._grad, kind, -(dt / ph.rho0), self._du)
        if ph.collision:
            self._k(steps.add_into)(p.vel, self._du, self._tmp)
            self._k(kernels.collision)(
                *small, p.pos, self.period, self._tmp, kind, ph.collision_distance * self.l0,
                ph.restitution, 1.0, self._stab,
            )
            self._du += self._stab
        p.vel += self._du
        if ph.stabilization:
            self._k(kernels.stabilization)(
                *small, p.pos, self.period, p.vel, kind, self._inner, ph.stabilization_walls,
                self.wcode, self.re, self.n0, self.l0, ph.alpha_s, self._stab,
            )
        self._k(steps.corrector)(p.pos, p.vel, self._du, dt, self._stab, ph.stabilization)

    def _update_open_boundaries(self, dt: float) -> None:
        assert self.problem is not None
        if self.inflow is None and not self.problem.outflows:
            return
        self.p, keep = update_open_boundaries(self.p, self.inflow, self.problem.outflows, dt)
        if keep is not None:
            # the kernels want contiguous arrays; a boolean selection already is one
            self.number_density = carry(self.number_density, keep)
            self.free_surface = carry(self.free_surface, keep)
            self.static_n = carry(self.static_n, keep)
            self.group = carry(self.group + 1, keep) - 1  # new particles: no group
            self.loose = carry(self.loose, keep)
            self.neigh.set_static(group=self.group, loose=self.loose)
            self._allocate()

    # ------------------------------------------------------------------ protocol
    def _advance(self, dt: float) -> None:
        ph = self.problem.physics  # type: ignore[union-attr]
        if isinstance(ph, DiffusionPhysics):
            self._advance_diffusion(dt, ph)
        else:
            self._advance_flow(dt, ph)
            self.counters["neighbour_builds"] = self.neigh.builds

    def stable_dt(self) -> float:
        assert self.problem is not None
        ph = self.problem.physics
        if isinstance(ph, DiffusionPhysics):
            # the diffusion row sums include the diagonal: 2 sum_j |c_ij|, as in the reference
            return self.problem.time_stepping.stable_dt(ph, self.l0, 0.0, self._lap_rowsum)
        umax = float(steps.max_speed(self.p.vel)) if self.p.n else 0.0
        return self.problem.time_stepping.stable_dt(ph, self.l0, umax, 2.0 * self._lap_rowsum)

    def state(self) -> Particles:
        return self.p

    def rebuild_neighbours(self) -> None:
        """Rebuild the neighbour list now (``mpsbench bench`` times this)."""
        if self.problem is None or isinstance(self.problem.physics, DiffusionPhysics):
            return
        with _threads(self.threads):
            self.neigh.invalidate()
            self.neigh.update(self.p.pos)

    def diagnostics(self) -> dict[str, Any]:
        return {
            "number_density": self.number_density,
            "n0": self.n0,
            "free_surface": self.free_surface,
        }
