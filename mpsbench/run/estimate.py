"""What a run will cost, from its parameters alone: particles, pairs, memory and time steps.

A case builds its :class:`~mpsbench.run.protocol.Problem` inside ``execute``, which can take
minutes (and all the memory) for a fine spacing.  ``Case.estimate(params)`` returns a
:class:`RunEstimate` computed with arithmetic and the helpers here, without building anything,
so ``mpsbench validate`` and ``mpsbench study run`` can refuse a plan that cannot fit in memory,
ask before a very large one, and refuse a fixed time step above the explicit stability limit
(:mod:`mpsbench.results.guard` applies those rules).

Memory model (:func:`memory_bytes`): peak resident memory of one run grows by about
``BYTES_PER_PARTICLE`` per particle plus ``BYTES_PER_PAIR`` per neighbour pair, on top of the
process itself (``BYTES_PER_PROCESS``).  Measured with the reference backend (peak RSS of
set-up and three steps, 25,600 and 102,400 particles): diffusion 256 B per particle + 132 B
per pair (r_e/l0 = 2.1 ... 6.0), dam break 410 B + 118 B; the constants round those up by
about a fifth.  The numba backend needs less per particle but about 180 MB more for the
compiler, which ``BYTES_PER_PROCESS`` covers.

Time steps: where a backend chooses dt (:meth:`mpsbench.physics.config.TimeStepping.stable_dt`),
the estimate uses the same rule, with the Gershgorin bound of the Laplacian taken on the ideal
square lattice of the run's spacing (:func:`lattice_laplacian_bound`; it scales as 1 / l0^2).

Stability of a fixed dt (:func:`diffusion_dt_limit`): forward Euler is stable while
dt <= 2 / (kappa rho), rho the spectral radius of the Laplacian; on the periodic lattice that is
the maximum of its Fourier symbol (:func:`lattice_laplacian_radius`, 1.1 to 1.8 times below the
Gershgorin bound for the built-in models), so the limit is exact there.  A jittered cloud's
radius is somewhat larger (its limit somewhat lower) than the lattice's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

BYTES_PER_PARTICLE = 500
BYTES_PER_PAIR = 160
BYTES_PER_PROCESS = 250 * 2**20


@dataclass(frozen=True)
class RunEstimate:
    """The cost of one run of a case (all its solver runs), before anything is built.

    ``particles`` and ``pairs`` are those of its largest solver run (pairs counted once, at the
    largest support radius); ``steps`` sums the time steps of all its solver runs (None when
    the case cannot tell).  With a fixed time step, ``dt`` is that step and ``dt_limit`` the
    explicit stability limit it must not exceed; ``dt_rule`` says where the limit comes from.
    """

    particles: int
    pairs: int
    steps: int | None = None
    dt: float | None = None
    dt_limit: float | None = None
    dt_rule: str = ""
    solver_runs: int = 1

    @property
    def memory_bytes(self) -> int:
        return memory_bytes(self.particles, self.pairs)

    @property
    def particle_steps(self) -> float | None:
        return None if self.steps is None else float(self.particles) * self.steps

    @property
    def dt_too_large(self) -> bool:
        return (self.dt is not None and self.dt_limit is not None
                and self.dt > self.dt_limit * (1 + 1e-9))


def memory_bytes(particles: int, pairs: int) -> int:
    """Estimated peak resident memory [bytes] of a run with this many particles and pairs."""
    return int(BYTES_PER_PROCESS + BYTES_PER_PARTICLE * particles + BYTES_PER_PAIR * pairs)


@lru_cache(maxsize=64)
def lattice_neighbours(re_ratio: float) -> int:
    """Neighbours of a particle of the square lattice within r_e = ``re_ratio`` l0."""
    from mpsbench.physics.weights import within_support

    m = int(math.ceil(re_ratio)) + 1
    ix, iy = np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1), indexing="ij")
    r = np.hypot(ix.ravel(), iy.ravel()).astype(float)
    return int(((r > 0) & within_support(r, float(re_ratio))).sum())


def pairs_for(particles: int, re_ratio: float) -> int:
    """Neighbour pairs (each once) of ``particles`` at lattice density within ``re_ratio`` l0."""
    return int(particles * lattice_neighbours(re_ratio) // 2)


@lru_cache(maxsize=256)
def lattice_laplacian_bound(weight: str, laplacian: str, re_ratio: float) -> float:
    """Gershgorin bound 2 max_i sum_j |c_ij| of a Laplacian on the unit square lattice: what
    the backends' time-step rule uses (on a lattice of spacing l0: this number / l0^2)."""
    _, c = _lattice_stencil(weight, laplacian, re_ratio)
    return float(2.0 * np.abs(c).sum())


@lru_cache(maxsize=1024)
def lattice_laplacian_radius(weight: str, laplacian: str, re_ratio: float, n_side: int) -> float:
    """Spectral radius of a Laplacian on the periodic unit lattice of ``n_side`` x ``n_side``
    particles: max over its Fourier modes k of |sum_j c_j (cos(k . r_j) - 1)| (the operator is
    circulant there, so these are its eigenvalues).  For more than 128 particles a side the
    modes of a 128-lattice are searched and the maximum refined (an upper bound of the modes
    of any finer lattice, to round-off).  On a lattice of spacing l0: this number / l0^2.
    """
    offsets, c = _lattice_stencil(weight, laplacian, re_ratio)

    def symbol(k: np.ndarray) -> np.ndarray:
        return np.abs((np.cos(k @ offsets.T) - 1.0) @ c)

    n = min(int(n_side), 128)
    # the stencil is mirror-symmetric in x and y: the modes in [0, pi]^2 are all there is
    m = 2.0 * np.pi * np.arange(n // 2 + 1) / n
    kx, ky = np.meshgrid(m, m, indexing="ij")
    grid = np.column_stack([kx.ravel(), ky.ravel()])
    values = symbol(grid)
    best = float(values.max())
    if n_side > n:  # refine around the best mode (the symbol is smooth)
        k0 = grid[int(values.argmax())]
        h = 2.0 * np.pi / n
        for _ in range(30):
            d = np.linspace(-h, h, 9)
            dx, dy = np.meshgrid(d, d, indexing="ij")
            cand = np.clip(k0 + np.column_stack([dx.ravel(), dy.ravel()]), 0.0, np.pi)
            vals = symbol(cand)
            k0, best, h = cand[int(vals.argmax())], max(best, float(vals.max())), h / 4
    return best


@lru_cache(maxsize=256)
def _lattice_stencil(weight: str, laplacian: str, re_ratio: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour offsets r_j and coefficients c_j of one particle of the unit lattice (with
    the lattice's own n0 and lambda, as a run on the lattice uses)."""
    from mpsbench.physics.laplacians import get_laplacian
    from mpsbench.physics.operators import build_pairs, lattice_constants
    from mpsbench.physics.operators import lattice_pairs as periodic_lattice
    from mpsbench.physics.weights import get_weight

    n_side = 2 * int(math.ceil(re_ratio)) + 3
    pos, box = periodic_lattice(n_side, 1.0)
    wf = get_weight(weight)
    model = get_laplacian(laplacian)
    n0, lam = lattice_constants(wf, re_ratio, 1.0)
    pairs = build_pairs(pos, float(re_ratio), box)
    c = model.coefficients(pairs, wf, float(re_ratio), n0, lam)
    first, second = pairs.i == 0, pairs.j == 0
    offsets = np.concatenate([pairs.dx[first], -pairs.dx[second]])
    return offsets, np.concatenate([c[first], c[second]])


def diffusion_dt_limit(kappa: float, n_side: int, weight: str, laplacian: str,
                       re_ratio: float) -> float:
    """Forward-Euler stability limit 2 / (kappa max|lambda(L)|) [s] of explicit diffusion on
    the periodic lattice of ``n_side`` particles a side of the unit square (l0 = 1 / n_side):
    above it the operator's highest mode grows by |1 - dt kappa lambda| > 1 every step."""
    radius = lattice_laplacian_radius(weight, laplacian, re_ratio, n_side) * n_side**2
    return 2.0 / (kappa * radius)


def flow_dt(l0: float, c0: float, umax: float, cfl: float, nu: float = 0.0,
            c_nu: float = 0.5, rho_lap: float = 0.0) -> float:
    """The time step of :meth:`~mpsbench.physics.config.TimeStepping.stable_dt` for a flow
    whose largest speed is ``umax`` [s]: the acoustic limit, and the viscous one when given."""
    dt = cfl * l0 / (c0 + umax)
    if nu > 0 and rho_lap > 0:
        dt = min(dt, c_nu * 2.0 / (nu * rho_lap))
    return dt


def steps_for(duration: float, dt: float) -> int:
    """Time steps to cover ``duration`` with steps of ``dt`` (at least one)."""
    if not (dt > 0 and math.isfinite(dt)):
        return 0
    return max(1, int(math.ceil(duration / dt - 1e-9)))
