"""The numba backend: the scheme's steps as compiled kernels over cell-linked lists.

The scheme (set-up, the order of a step, time step, open boundaries) is
:class:`mpsbench.run.scheme.SchemeSolver`; this backend supplies its pieces, so it agrees with
:class:`mpsbench.solvers.reference.ReferenceSolver` to rounding.  Every model runs here through
its own formulas (:mod:`.formulas`), so a plugin's weight, Laplacian or pressure gradient does too:

* diffusion: L held as per-entry coefficients of a CSR list built once (particles are fixed);
* flow (WC-MPS): five fused passes per step (:mod:`.fused`: each neighbour sum with the
  per-particle updates that follow it, rows of a full list computed by their own particle);
  with ``sort=true`` on particles kept sorted along a space-filling curve (:mod:`.layout`),
  ``state()`` and ``diagnostics()`` giving the problem's order back.  The default keeps the
  problem's order: on the quick tier's dam break the sorted runs' other summation order made
  two runs of the model grid diverge that the reference and the unsorted backend complete
  (docs/performance.md).

Boundary conventions (as the reference): wall particles take part in pressure and in every
operator; dummy particles complete the number density and carry the wall velocity into the
viscous term but are left out of the pressure gradient; inflow particles act like wall
particles until they cross the inlet.  Pairs of a dummy particle with a boundary particle that
moves rigidly with it are static: their number density is summed once at setup and the pairs
never enter the neighbour list.

Neighbours: one cell-list CSR list at max(r_e, r_e,lap) + skin, rebuilt when a particle has
moved more than skin/2 (the move kernels report the largest displacement), and a sub-list at
r_e + skin for the kernels at the smaller radius.
"""

from __future__ import annotations

import multiprocessing
import time
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from mpsbench.params import Option
from mpsbench.physics import operators as ops
from mpsbench.physics.boundaries import carry
from mpsbench.physics.config import DiffusionPhysics, FlowPhysics
from mpsbench.physics.neighbours import PairList
from mpsbench.physics.operators import DIM, SHIFTING
from mpsbench.physics.particles import Kind, Particles
from mpsbench.run.protocol import Capabilities, Health, Problem
from mpsbench.run.scheme import SCHEME_BOUNDARIES, SCHEME_FEATURES, EquationOfState, SchemeSolver

from . import formulas, fused, kernels, steps
from ._jit import report, set_vectorized, watch_compiles
from .cells import CSRNeighbours, build_csr
from .geometry import box_period
from .layout import Birth, morton_order
from .mirror import mirror_velocity
from .neighbour_list import CellNeighbourList

FloatArray = NDArray[np.float64]


class _RunContext:
    """A run's numba threads and kernel flags around a block, the caller's restored after it.

    A class rather than a generator context: it is entered around every step, and a
    generator-based context costs about 1 us, a tenth of a small diffusion step (400
    particles).  With one thread the serial kernel builds run and the threading layer is left
    alone (it is not even started: a forked worker process must not touch OpenMP, see
    :mod:`._jit`).
    """

    __slots__ = ("threads", "vectorize", "_threads_before", "_vector_before")

    def __init__(self, threads: int, vectorize: bool) -> None:
        self.threads = threads
        self.vectorize = vectorize
        self._threads_before = threads
        self._vector_before = vectorize

    def __enter__(self) -> None:
        self._vector_before = set_vectorized(self.vectorize)
        if self.threads != 1:
            self._threads_before = numba.get_num_threads()
            if self._threads_before != self.threads:
                numba.set_num_threads(self.threads)

    def __exit__(self, *exc: object) -> None:
        if self.threads != 1 and self._threads_before != self.threads:
            numba.set_num_threads(self._threads_before)
        set_vectorized(self._vector_before)


class NumbaSolver(SchemeSolver):
    """numba-compiled cell-list WC-MPS and diffusion backend (agrees with ``reference``)."""

    name = "numba"
    version = "2.0"
    capabilities = Capabilities(boundaries=SCHEME_BOUNDARIES, features=SCHEME_FEATURES)
    options = (
        Option("threads", 0, "numba threads; 0: automatic (one below 8000 particles or in a "
               "worker process of a pool, else numba's thread count)", kind=int, minimum=0),
        Option("sort", False, "flow: sort the particles along a space-filling curve at each "
               "neighbour rebuild (memory locality); false: keep the problem's order",
               kind=bool),
        Option("vectorize", True, "compile the neighbour sums with reassoc, so LLVM "
               "vectorises them with gather loads; false: scalar loops (faster where gathers "
               "are slow: 1.36-1.54x on this project's machine; measure with mpsbench "
               "bench --solver numba --solver numba:vectorize=false)", kind=bool),
    )
    parallel_min = 8_000
    """With ``threads=0``, problems with fewer particles run on one thread: a parallel region
    costs a barrier per kernel (a dozen per step), which small problems do not repay, and on a
    loaded machine (or next to other worker processes) a barrier can wait a whole scheduler
    time slice for a descheduled thread.  Inside a worker process of a pool (a study run with
    ``--jobs`` > 1) every problem runs on one thread: the pool already uses the cores."""

    def __init__(self, threads: int | None = 0, sort: bool = False,
                 vectorize: bool = True) -> None:
        super().__init__()
        if threads is not None and (
            not isinstance(threads, int) or isinstance(threads, bool) or threads < 0
        ):
            raise ValueError(f"NumbaSolver: threads = {threads!r} is not allowed: an integer >= 0 "
                             "(0: automatic)")
        self.requested_threads = threads or None
        self.sort = bool(sort)
        self.vectorize = bool(vectorize)
        self.threads = 1
        self.timings: dict[str, float] = {}
        self._watched: list[Any] = []
        self.compile_times: dict[str, float] = {}  # kernel -> seconds compiling (cache misses)

    def _compiled(self) -> _RunContext:
        """This run's numba threads and kernel flags (:func:`._jit.set_vectorized`)."""
        return _RunContext(self.threads, self.vectorize)

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
        with self._compiled(), watch_compiles() as watch:
            super().setup(problem)
        self.timings["setup_s"] = time.perf_counter() - t0
        box = problem.box
        # what health() hands its kernel after every step, made once
        self._health_box = (np.asarray(box.lo, np.float64), np.asarray(box.hi, np.float64),
                            np.array([not a for a in box.periodic]))
        self._field_name = getattr(problem.physics, "field_name", None)
        self._watched = [watch]  # the first step compiles the step's kernels: watched too

    def step(self, dt: float) -> None:
        if not self._watched:
            with self._compiled():
                super().step(dt)
            return
        with self._compiled(), watch_compiles() as watch:
            super().step(dt)
        self._watched.append(watch)
        kernels = sum(w.kernels for w in self._watched)
        seconds = sum(w.seconds for w in self._watched)
        self.timings["jit_compile_s"] = seconds
        self.counters["compile_s"] = seconds  # the record's compile_s (the ETA leaves it out)
        self.timings["kernels_compiled"] = kernels
        self.compile_times = {k: v for w in self._watched for k, v in w.each.items()}
        self._watched = []
        report(kernels, seconds)

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
        self._periodic = bool(self.box.any_periodic)
        r_max = max(self.re, self.re_lap)
        small = self.re if self.re < r_max else None
        self.neigh = CellNeighbourList(
            r_max, self.skin_ratio * self.l0, self.box, r_small=small, serial=self.threads == 1
        )
        self._sort_cell = self.re + self.skin_ratio * self.l0
        grad = self.fm.gradient
        self._pmin_mode = fused.PMIN_NONE
        if grad.uses_pmin:
            reads = ops.reads(grad.pair.py_func) + (True,) * 4
            self._pmin_mode = fused.PMIN_TABLE if reads[3] else fused.PMIN_ROW
        self.birth = Birth(self.p.n)
        self._adopt(self.p)
        self._set_static()

    def _adopt(self, p: Any) -> None:
        """Take ``p`` as the particles: positions and velocities into (2, n) arrays that
        ``p.pos`` and ``p.vel`` view, per-particle work arrays for its size."""
        n = p.n
        self._X = np.ascontiguousarray(p.pos.T)
        self._V = np.ascontiguousarray(p.vel.T)
        self._X2 = np.empty_like(self._X)
        self._V2 = np.empty_like(self._V)
        self._views()
        self._DU = np.zeros((2, n))
        self._W = np.empty((2, n))
        self._Xref = self._X.copy()
        self._disp = np.inf  # max displacement since the list was built (none yet)
        self._speed2: float | None = None  # max |u|^2 after the last move
        self._pmin = np.empty(n)
        self._inner = np.zeros(n, dtype=bool)
        self._no_dummy = np.ascontiguousarray(p.kind != Kind.DUMMY)
        if self.fm.laplacian.has_moment:
            self._moment = np.zeros(n)
        self._sched = fused.Schedule.of(n)
        self._partial = np.zeros((self._sched.blocks, 2))
        if len(self.number_density) != n:
            self.number_density = np.zeros(n)
            self.free_surface = np.zeros(n, dtype=bool)

    def _views(self) -> None:
        self.p.pos = self._X.T
        self.p.vel = self._V.T

    def _swap(self) -> None:
        """The kernel just written ``X2``, ``V2`` holds the state: make it current."""
        self._X, self._X2 = self._X2, self._X
        self._V, self._V2 = self._V2, self._V
        self._views()

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
            self.static_n = self._static_density(self._full_list(self.re))

    def _static_density(self, csr: CSRNeighbours) -> FloatArray:
        """sum_j W_ij over each particle's static pairs (same rigid group, not both loose).

        numpy with the weight's own vectorised formula, once per set-up: a compiled kernel
        cost 0.6 s of a cold start for a sum that takes milliseconds here.  Entries are summed
        row by row in list order, as a row loop would."""
        rows = csr.rows()
        nbr = csr.nbr.astype(np.int64)
        g = self.group
        static = (g[rows] >= 0) & (g[nbr] == g[rows]) & ~(self.loose[rows] & self.loose[nbr])
        pairs = PairList(rows[static], nbr[static], np.empty((0, 2)), np.empty(0), self.p.n,
                         self.re)
        pairs.refresh(self.p.pos, self.box)  # dx and r as the reference computes them
        r = pairs.r
        w = np.zeros(len(r))
        apart = r > 0.0  # a coincident pair has no weight (and W(0) may divide by zero)
        w[apart] = self.weight.w(r[apart], self.re)
        # bincount with weights sums in float64 (numpy's stubs type it as integer)
        return np.bincount(pairs.i, w, self.p.n).astype(np.float64)

    def _sort(self) -> None:
        """Permute every per-particle array along the Z curve of the current positions."""
        if not self.sort:
            return
        order = morton_order(self._X, self._sort_cell)
        if np.array_equal(order, np.arange(len(order))):
            return
        p = self.p
        self._X = np.ascontiguousarray(self._X[:, order])
        self._V = np.ascontiguousarray(self._V[:, order])
        p.kind = p.kind[order]
        p.pressure = p.pressure[order]
        p.fields = {k: v[order] for k, v in p.fields.items()}
        self._views()
        for name in ("number_density", "free_surface", "static_n", "group", "loose",
                     "_no_dummy"):
            setattr(self, name, getattr(self, name)[order])
        self.birth.permute(order)
        self.neigh.set_static(group=self.group, loose=self.loose)

    def _rebuild(self) -> None:
        self._sort()
        self.neigh.build(self.p.pos)
        self._Xref[:] = self._X
        self._disp = 0.0
        self.counters["neighbour_builds"] = self.neigh.builds

    def _update_neighbours(self) -> None:
        if not self.neigh.valid_after(self._disp, self.p.n):
            self._rebuild()

    def _particles_changed(self, keep: NDArray[np.bool_]) -> None:
        # particles only left (an outflow, most steps of a jet): the list loses their rows
        # and entries instead of being rebuilt (four rebuilds in five on the water jet)
        reference, moved = self._Xref, self._disp
        compacted = len(keep) == len(self.static_n) and self.neigh.compact(keep)
        # the kernels want contiguous arrays; a boolean selection already is one
        self.static_n = carry(self.static_n, keep)
        self.group = carry(self.group + 1, keep) - 1  # new particles: no group
        self.loose = carry(self.loose, keep)
        self.birth.carry(keep)
        if not compacted:
            self.neigh.set_static(group=self.group, loose=self.loose)
        self._adopt(self.p)
        if compacted:
            self._Xref = np.ascontiguousarray(reference[:, keep])
            self._disp = moved

    def rebuild_neighbours(self) -> None:
        """Sort the particles and rebuild the neighbour list now (``mpsbench bench`` times
        this)."""
        if self.problem is None or isinstance(self.problem.physics, DiffusionPhysics):
            return
        with self._compiled():
            self._rebuild()

    def _lists(self) -> tuple[tuple[Any, Any], tuple[Any, Any]]:
        """((offsets, nbr) of the big list, (offsets, nbr) of the list at r_e)."""
        big = self.neigh.csr
        assert big is not None
        small = self.neigh.small if self.neigh.small is not None else big
        return (big.offsets, big.nbr), (small.offsets, small.nbr)

    # ------------------------------------------------------------------ flow: the step's passes
    def _number_density(self) -> FloatArray:
        self._density(None)
        return self.number_density

    def _density(self, eos: EquationOfState | None) -> None:
        p = self.p
        _, small = self._lists()
        e = eos if eos is not None else EquationOfState(False, 1.0, 1.0, False, 0.0, 1.0)
        self._k(fused.density_pressure(self.fm.weight, self._periodic))(
            *small, self._X, self.period, self.re, self.static_n, p.kind, e.n0, e.tait,
            e.prefactor, e.gamma, e.clip, e.beta, eos is not None, self.number_density,
            p.pressure, self.free_surface, self._inner, self._sched.order, self._sched.bounds,
        )

    def _density_pressure(self, eos: EquationOfState) -> None:
        self._density(eos)

    def _laplacian(self, dt: float, nu: float, gravity: tuple[float, float], U: Any) -> float:
        """The predictor kernel (viscous when nu > 0); new state in ``X2``, ``V2``; returns the
        max fluid row sum and records the displacement."""
        big, _ = self._lists()
        p, wt, lap = self.p, self.fm.weight, self.fm.laplacian
        viscous = nu > 0
        if viscous and lap.has_moment:
            self._k(kernels.moments(wt, lap))(*big, p.pos, self.period, self.re_lap,
                                              self._moment)
        self._k(fused.predict(wt, lap, self._periodic))(
            *big, self._X, self._V, U, self.period, self.re_lap, self.pref, self._moment,
            self.gfactor, self.gcorr, viscous, nu, gravity[0], gravity[1], dt, p.kind,
            self._Xref, self._X2, self._V2, self._sched.order, self._sched.bounds,
            self._partial,
        )
        rows, disp2 = fused.combine_max(self._partial)
        self._pending_disp = float(np.sqrt(disp2))
        return float(rows)

    def _row_sums(self) -> float:
        return self._laplacian(0.0, 1.0, (0.0, 0.0), self._V)  # X2, V2 are not taken

    def _predict(self, dt: float, ph: FlowPhysics) -> float | None:
        U = self._V
        if ph.nu > 0 and ph.wall_velocity == "mirror":
            vel = mirror_velocity(self.p, self.fm.weight, self.re, self.box, self.threads == 1)
            U = np.ascontiguousarray(vel.T)
        rows = self._laplacian(dt, ph.nu, ph.gravity, U)
        self._swap()
        self._disp = self._pending_disp
        self._speed2 = None
        return rows if ph.nu > 0 else None

    def _correct(self, factor: float, collision: tuple[float, float] | None) -> None:
        p, wt, grad = self.p, self.fm.weight, self.fm.gradient
        _, small = self._lists()
        pmin = p.pressure
        if self._pmin_mode == fused.PMIN_TABLE:
            self._k(fused.pmin_all(wt, self._periodic))(
                *small, self._X, self.period, p.pressure, self._no_dummy, self.re, self._pmin,
                self._sched.order, self._sched.bounds,
            )
            pmin = self._pmin
        self._k(fused.correct(wt, grad, self._periodic, self._pmin_mode))(
            *small, self._X, self.period, p.pressure, pmin, self._no_dummy, self.re,
            self.grad_factor, factor, p.kind, self._V, self._DU, self._W, collision is not None,
            self._sched.order, self._sched.bounds,
        )
        if collision is not None:
            self._k(fused.collide(self._periodic))(
                *small, self._X, self.period, self._W, p.kind, collision[0], collision[1], 1.0,
                self._V, self._DU, self._sched.order, self._sched.bounds,
            )

    def _move(self, dt: float, stabilization: tuple[float, bool] | None) -> None:
        p = self.p
        _, small = self._lists()
        factor, walls = stabilization if stabilization is not None else (0.0, True)
        self._k(fused.move(self.fm.weight, self._periodic))(
            *small, self._X, self._V, self._DU, self.period, p.kind, self._inner, walls, self.re,
            factor, stabilization is not None, dt, self._Xref, self._X2, self._V2,
            self._sched.order, self._sched.bounds, self._partial,
        )
        disp2, speed2 = fused.combine_max(self._partial)
        self._swap()
        self._disp = float(np.sqrt(disp2))
        self._speed2 = float(speed2)

    def _shift(self, factor: float, cap: float) -> None:
        self._update_neighbours()  # the moved positions may need a new list
        p = self.p
        _, small = self._lists()
        self._k(fused.shift(self.fm.weight, self._periodic))(
            *small, self._X, self._V, self.period, p.kind, self.free_surface, self.re, factor,
            SHIFTING.gradient_factor(self.n0), cap, self._Xref, self._X2, self._V2,
            self._sched.order, self._sched.bounds, self._partial,
        )
        disp2, speed2 = fused.combine_max(self._partial)
        self._swap()
        self._disp = float(np.sqrt(disp2))
        self._speed2 = float(speed2)

    # ------------------------------------------------------------------ the caller's view
    def state(self) -> Particles:
        """The particles in the problem's order (with ``sort``, a copy: the solver keeps its own,
        sorted along a space-filling curve; :mod:`.layout`)."""
        if not hasattr(self, "birth") or not self.sort:
            return self.p
        return self.p.subset(self.birth.external())

    def diagnostics(self) -> dict[str, Any]:
        out = super().diagnostics()
        if hasattr(self, "birth") and self.sort:
            ext = self.birth.external()
            out["number_density"] = self.number_density[ext]
            out["free_surface"] = self.free_surface[ext]
        return out

    # ------------------------------------------------------------------ cheap summaries
    def _max_speed(self) -> float:
        if self._speed2 is not None and hasattr(self, "birth"):
            return float(np.sqrt(self._speed2))
        return super()._max_speed()

    def health(self, margin: float) -> Health:
        self._require_setup("health()")
        p = self.p
        name = self._field_name
        field = _NO_FIELD if name is None else np.ascontiguousarray(p.fields[name], np.float64)
        X, V = (p.pos.T, p.vel.T) if name is not None else (self._X, self._V)
        lo, hi, free_axis = self._health_box
        finite, speed, outside, fmax = steps.health(
            X, V, p.pressure, p.kind, lo, hi, free_axis, float(margin), field
        )
        return Health(bool(finite), float(speed), int(outside), float(fmax))


_NO_FIELD = np.zeros(0)
