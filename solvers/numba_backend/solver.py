"""The numba backend: the scheme's steps as compiled kernels over cell-linked lists.

The scheme (set-up, the order of a step, time step, open boundaries) is
:class:`mpsbench.run.scheme.SchemeSolver`; this backend supplies its pieces, so it agrees with
:class:`mpsbench.solvers.reference.ReferenceSolver` to rounding.  Every model runs here through
its own formulas (:mod:`.formulas`), so a plugin's weight, Laplacian or pressure gradient does too:

* diffusion: L held as per-entry coefficients of a CSR list built once (particles are fixed);
* flow (WC-MPS): the number density at r* fused with the equation of state and the free-surface
  test; a half-list layout (:mod:`.pairs`, each pair once, the default) or full rows
  (:mod:`.kernels`, ``pairwise=false`` or with the xu-jin gradient correction).

Boundary conventions (as the reference): wall particles take part in pressure and in every
operator; dummy particles complete the number density and carry the wall velocity into the
viscous term but are left out of the pressure gradient; inflow particles act like wall
particles until they cross the inlet.  Pairs of a dummy particle with a boundary particle that
moves rigidly with it are static: their number density is summed once at setup and the pairs
never enter the neighbour list.

Neighbours: one cell-list CSR list at max(r_e, r_e,lap) + skin, rebuilt when a particle has
moved more than skin/2, and a sub-list at r_e + skin for the kernels at the smaller radius.
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

from mpsbench.params import Option
from mpsbench.physics.boundaries import carry
from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.operators import DIM
from mpsbench.physics.particles import Kind
from mpsbench.run.protocol import Capabilities, Health, Problem
from mpsbench.run.scheme import EquationOfState, SchemeSolver

from . import formulas, kernels, pairs, steps
from .cells import CSRNeighbours, build_csr
from .geometry import box_period
from .mirror import mirror_velocity
from .neighbour_list import CellNeighbourList

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


class NumbaSolver(SchemeSolver):
    """numba-compiled cell-list WC-MPS and diffusion backend (agrees with ``reference``)."""

    name = "numba"
    version = "1.1"
    capabilities = Capabilities()
    options = (
        Option("threads", 0, "numba threads; 0: automatic (one below 8000 particles or in a "
               "worker process of a pool, else numba's thread count)", kind=int, minimum=0),
        Option("pairwise", True, "flow on half lists, each pair evaluated once; false: the "
               "row kernels on full lists", kind=bool),
    )
    parallel_min = 8_000
    """With ``threads=0``, problems with fewer particles run on one thread: a parallel region
    costs a barrier per kernel (a dozen per step), which small problems do not repay, and on a
    loaded machine (or next to other worker processes) a barrier can wait a whole scheduler
    time slice for a descheduled thread.  Inside a worker process of a pool (a study run with
    ``--jobs`` > 1) every problem runs on one thread: the pool already uses the cores."""

    def __init__(self, threads: int | None = 0, pairwise: bool = True) -> None:
        super().__init__()
        if threads is not None and (
            not isinstance(threads, int) or isinstance(threads, bool) or threads < 0
        ):
            raise ValueError(f"NumbaSolver: threads = {threads!r} is not allowed: an integer >= 0 "
                             "(0: automatic)")
        self.requested_threads = threads or None
        self.pairwise = bool(pairwise)
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
        t0 = time.perf_counter()
        with _threads(self.threads):
            super().setup(problem)
        self.timings["setup_s"] = time.perf_counter() - t0

    def step(self, dt: float) -> None:
        with _threads(self.threads):
            super().step(dt)

    def _compile(self) -> None:
        """The compiled models of this run and the constants in front of their sums."""
        self.period = box_period(self.box)
        self.fm = formulas.compile_models(self.weight, self.laplacian, self.gradient)
        self.gcorr = bool(self.laplacian.gradient_correction)
        self.pref = float(self.laplacian.prefactor(self.n0_lap, self.lam))
        self.gfactor = DIM / self.n0_lap  # the original gradient of the gradient correction
        self.grad_factor = float(self.gradient.prefactor(self.n0))
        self._moment = kernels.NO_MOMENT

    def _full_list(self, re: float) -> CSRNeighbours:
        """Every pair within the closed support of ``re`` (no static pairs left out)."""
        return build_csr(
            self.p.pos, CellNeighbourList.padded(re, 0.0), self.box, serial=self.threads == 1
        )

    # ------------------------------------------------------------------ diffusion
    def _setup_diffusion(self, ph: DiffusionPhysics) -> tuple[float, FloatArray]:
        self._compile()
        n = self.p.n
        self.p.fields[ph.field_name] = np.ascontiguousarray(
            self.p.fields[ph.field_name], dtype=np.float64
        )
        csr = self._full_list(max(self.re, self.re_lap))
        self.counters["neighbour_builds"] += 1
        self._diff_csr = csr
        wt, lap = self.fm.weight, self.fm.laplacian
        if lap.has_moment:
            self._moment = self._k(kernels.moments(wt, lap))(
                csr.offsets, csr.nbr, self.p.pos, self.period, self.re_lap, np.empty(n)
            )
        self._coef = np.empty(len(csr.nbr))
        rows = np.empty(n)
        self._k(steps.operator_entries(wt, lap))(
            csr.offsets, csr.nbr, self.p.pos, self.period, self.re_lap, self.pref, self._moment,
            self.gfactor, self.gcorr, self._coef, rows,
        )
        self._work = np.empty(n)
        self._upper: tuple[Any, Any, Any] | None = None
        if not self.gcorr and self.threads == 1:
            # c_ij = c_ji (symmetric pair formulas): keep each pair once, serial scatter
            row = np.repeat(np.arange(n), np.diff(csr.offsets))
            up = csr.nbr.astype(np.int64) > row
            offsets = np.zeros(n + 1, np.int64)
            np.cumsum(np.bincount(row[up], minlength=n), out=offsets[1:])
            self._upper = (
                offsets, np.ascontiguousarray(csr.nbr[up]), np.ascontiguousarray(self._coef[up])
            )
        density = self._k(kernels.number_density(wt))(
            csr.offsets, csr.nbr, self.p.pos, self.period, self.re, np.empty(n)
        )
        return (float(rows.max()) if n else 0.0), density

    def _diffuse(self, phi: FloatArray, factor: float) -> None:
        if self._upper is not None:
            steps.symmetric_step(*self._upper, phi, factor, self._work)
            return
        csr = self._diff_csr
        self._k(steps.operator_apply)(csr.offsets, csr.nbr, self._coef, phi, self._work)
        self._k(steps.axpy)(phi, factor, self._work)

    # ------------------------------------------------------------------ flow: set-up, layout
    def _setup_flow(self, ph: FlowPhysics) -> None:
        self._compile()
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
            self._k(steps.static_density(self.fm.weight))(
                csr.offsets, csr.nbr, p.pos, self.period, self.re, self.group, self.loose,
                self.static_n,
            )

    def _allocate(self) -> None:
        n = self.p.n
        self._lap = np.zeros((n, 2))
        self._rows = np.zeros(n)
        self._grad = np.empty((n, 2))
        self._du = np.zeros((n, 2))
        self._tmp = np.empty((n, 2))
        self._stab = np.zeros((n, 2))
        self._stab_factor = 0.0
        self._pmin = np.empty(n)
        self._inner = np.zeros(n, dtype=bool)
        if self.fm.laplacian.has_moment:
            self._moment = np.zeros(n)
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

    def _update_neighbours(self) -> None:
        self.neigh.update(self.p.pos)
        self.counters["neighbour_builds"] = self.neigh.builds

    def _particles_changed(self, keep: NDArray[np.bool_]) -> None:
        # the kernels want contiguous arrays; a boolean selection already is one
        self.static_n = carry(self.static_n, keep)
        self.group = carry(self.group + 1, keep) - 1  # new particles: no group
        self.loose = carry(self.loose, keep)
        self.neigh.set_static(group=self.group, loose=self.loose)
        self._allocate()

    def rebuild_neighbours(self) -> None:
        """Rebuild the neighbour list now (``mpsbench bench`` times this)."""
        if self.problem is None or isinstance(self.problem.physics, DiffusionPhysics):
            return
        with _threads(self.threads):
            self.neigh.invalidate()
            self.neigh.update(self.p.pos)

    # ------------------------------------------------------------------ flow: the step's pieces
    def _number_density(self) -> FloatArray:
        _, small = self._lists()
        wt = self.fm.weight
        if self._half:
            self._k(pairs.density_pairs(wt))(
                *small, self.p.pos, self.period, self.re, self._chunks()[1], self._acc_n
            )
            return self._acc_n.sum(axis=0) + self.static_n
        return self.static_n + self._k(kernels.number_density(wt))(
            *small, self.p.pos, self.period, self.re, np.empty(self.p.n)
        )

    def _viscous(self, mirror: bool) -> float:
        """Laplacian of the (mirrored) velocity into ``_lap`` (rows) or ``_acc_v`` (half)."""
        big, _ = self._lists()
        p, wt, lap = self.p, self.fm.weight, self.fm.laplacian
        u = p.vel
        if mirror:
            u = mirror_velocity(p, wt, self.re, self.box, self.threads == 1)
        if self._half:
            bounds = self._chunks()[0]
            if lap.has_moment:
                self._k(pairs.pair_sum_pairs(wt, lap.moment))(
                    *big, p.pos, self.period, self.re_lap, bounds, self._acc_n
                )
                self._k(pairs.sum_chunks)(self._acc_n, self._moment)
            self._k(pairs.laplacian_pairs(wt, lap))(
                *big, p.pos, self.period, u, self.re_lap, self.pref, self._moment, bounds,
                self._acc_v, self._acc_rows,
            )
            return float(pairs.fluid_row_max(self._acc_rows, p.kind))
        if lap.has_moment:
            self._k(kernels.moments(wt, lap))(*big, p.pos, self.period, self.re_lap,
                                              self._moment)
        self._k(kernels.laplacian_field(wt, lap))(
            *big, p.pos, self.period, u, self.re_lap, self.pref, self._moment, self.gfactor,
            self.gcorr, self._lap, self._rows, p.kind == Kind.FLUID,
        )
        return float(steps.max_over(self._rows, p.kind, True))  # fluid rows

    def _predict(self, dt: float, ph: FlowPhysics) -> None:
        p = self.p
        lap = self._acc_v if self._half else self._lap
        fn = pairs.predictor_from if self._half else steps.predictor
        self._k(fn)(p.pos, p.vel, lap, ph.nu > 0, ph.nu, ph.gravity[0], ph.gravity[1], dt, p.kind)

    def _density_pressure(self, eos: EquationOfState) -> None:
        p = self.p
        _, small = self._lists()
        state = (p.kind, eos.n0, eos.tait, eos.prefactor, eos.gamma, eos.clip, eos.beta,
                 self.number_density, p.pressure, self.free_surface, self._inner)
        if self._half:
            self._k(pairs.density_pairs(self.fm.weight))(
                *small, p.pos, self.period, self.re, self._chunks()[1], self._acc_n
            )
            self._k(pairs.pressure_from)(self._acc_n, self.static_n, *state)
            return
        self._k(steps.density_pressure(self.fm.weight))(
            *small, p.pos, self.period, self.re, self.static_n, *state
        )

    def _pressure_increment(self, factor: float) -> None:
        p, wt, grad = self.p, self.fm.weight, self.fm.gradient
        kind = p.kind
        _, small = self._lists()
        no_dummy = kind != Kind.DUMMY
        pmin = self._pmin if grad.uses_pmin else p.pressure
        if self._half:
            bounds = self._chunks()[1]
            if grad.uses_pmin:
                self._k(pairs.pmin_pairs(wt))(
                    *small, p.pos, self.period, p.pressure, no_dummy, self.re, bounds, self._acc_n
                )
                pairs.combine_min(self._acc_n, self._pmin)
            self._k(pairs.gradient_pairs(wt, grad))(
                *small, p.pos, self.period, p.pressure, pmin, no_dummy, kind, self.re, bounds,
                self._acc_v,
            )
            factors = np.array([self.grad_factor, factor])
            self._k(pairs.pressure_increment_from)(self._acc_v, kind, factors, self._du)
            return
        if grad.uses_pmin:
            self._k(kernels.neighbour_min(wt))(
                *small, p.pos, self.period, p.pressure, no_dummy, self.re, self._pmin
            )
        self._k(kernels.pressure_gradient(wt, grad))(
            *small, p.pos, self.period, p.pressure, pmin, no_dummy, self.re, self.grad_factor,
            self._grad, kind == Kind.FLUID,
        )
        self._k(steps.pressure_increment)(self._grad, kind, factor, self._du)

    def _collision(self, distance: float, restitution: float) -> None:
        p = self.p
        _, small = self._lists()
        self._k(steps.add_into)(p.vel, self._du, self._tmp)
        if self._half:
            self._k(pairs.collision_pairs)(
                *small, p.pos, self.period, self._tmp, p.kind, distance, restitution, 1.0,
                self._chunks()[1], self._acc_v,
            )
            self._k(pairs.add_from)(self._acc_v, self._du)
            return
        self._k(kernels.collision)(
            *small, p.pos, self.period, self._tmp, p.kind, distance, restitution, 1.0, self._stab
        )
        self._du += self._stab

    def _add_increment(self) -> None:
        self.p.vel += self._du

    def _stabilize(self, factor: float, with_walls: bool) -> None:
        p = self.p
        _, small = self._lists()
        if self._half:
            self._k(pairs.stabilization_pairs(self.fm.weight))(
                *small, p.pos, self.period, p.vel, p.kind, self._inner, with_walls, self.re,
                self._chunks()[1], self._acc_v,
            )
            self._stab_factor = factor
            return
        self._k(kernels.stabilization(self.fm.weight))(
            *small, p.pos, self.period, p.vel, p.kind, self._inner, with_walls, self.re, factor,
            self._stab,
        )

    def _move(self, dt: float, stabilized: bool) -> None:
        p = self.p
        if self._half:
            self._k(pairs.corrector_from)(
                p.pos, p.vel, self._du, dt, self._acc_v, self._stab_factor, stabilized
            )
        else:
            self._k(steps.corrector)(p.pos, p.vel, self._du, dt, self._stab, stabilized)

    # ------------------------------------------------------------------ cheap summaries
    def _max_speed(self) -> float:
        return float(steps.max_speed(self.p.vel))

    def health(self, margin: float) -> Health:
        assert self.problem is not None
        p, box = self.p, self.box
        name = getattr(self.problem.physics, "field_name", None)
        field = p.fields[name] if name is not None else _NO_FIELD
        finite, speed, outside, fmax = steps.health(
            p.pos, p.vel, p.pressure, p.kind, np.asarray(box.lo, np.float64),
            np.asarray(box.hi, np.float64), np.array([not a for a in box.periodic]),
            float(margin), np.ascontiguousarray(field, dtype=np.float64),
        )
        return Health(bool(finite), float(speed), int(outside), float(fmax))


_NO_FIELD = np.zeros(0)
