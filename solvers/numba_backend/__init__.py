"""The numba backend (registry name ``numba``): the reference physics, compiled, on cell lists.

Needs numba (the ``fast`` extra).  Without it, importing this package raises ImportError with
the install command, so the solver registry lists ``numba`` as unavailable with that reason.

* :mod:`.solver`: :class:`NumbaSolver`, the hooks of :class:`mpsbench.run.scheme.SchemeSolver`
  as compiled kernels (they agree with the reference to rounding: tests/test_numba_agreement.py);
  options ``threads`` and ``sort`` (``--solver numba:threads=1``).
* :mod:`.formulas`: the models' own formulas (weights, Laplacians, pressure gradients, the
  stabilization) compiled; every kernel that evaluates a model is made by a factory that closes
  over them (:mod:`._jit`), so any registered model, a plugin's too, runs here.
* :mod:`.geometry`, :mod:`.cells`, :mod:`.neighbour_list`: the minimum image, cell-list builds
  (CSR rows in both directions, half lists with each pair once), the skinned list with a
  sub-list at the smaller radius, and a pair list equal to
  :func:`mpsbench.physics.neighbours.build_pairs`.
* :mod:`.kernels`: row functions (one particle's neighbour sum of a model: number density, a
  Laplacian's moment, the original gradient, divergence, p_min, the pressure gradient, the
  Laplacian on 2-vector fields (+ xu-jin gradient correction, row sums), collision and
  stabilization increments) and the operator kernels on full lists built on them.
* :mod:`.fused`: the WC-MPS step as five passes, each neighbour sum with the per-particle
  updates that follow it, rows computed by their own particle (no per-thread accumulators).
* :mod:`.layout`: with ``sort=true``, the particles sorted along a Z curve at each neighbour
  rebuild (locality), and the ids that give the caller the problem's order back.
* :mod:`.steps`: the equation of state, the health summary, the
  diffusion operator as per-entry coefficients.
* :mod:`.mirror`: the ``mirror`` wall velocities (kernel-weighted linear fit at mirror points).
* :mod:`.timing`: ``python -m mpsbench.solvers.numba_backend.timing`` times one pass of the row
  kernels against the numpy operators; :mod:`.traffic`: ``python -m
  mpsbench.solvers.numba_backend.traffic`` counts the bytes a step streams (docs/performance.md).

Compiled code is cached on disk (in ``__pycache__`` next to the sources, or ``NUMBA_CACHE_DIR``),
one entry per kernel and model combination, keyed by a fingerprint of the code it depends on
and the kernel's compile flags (:mod:`._jit`): the first process compiles the kernels its run
needs (12 for the default dam break on one thread, about 20 CPU-s; the first compilation in a
process is announced on stderr and its total reported), later ones load them in about 1 s
(``mpsbench bench`` reports it as ``jit_compile_s``).
"""

import os

try:
    import numba  # noqa: F401
except ImportError as exc:  # pragma: no cover - exercised only without numba
    raise ImportError("numba is not installed: pip install 'mpsbench[fast]'") from exc

# numba's OpenMP threading layer (libgomp, loaded at the first parallel kernel) spins in every
# barrier by default.  On a loaded machine, or next to other worker processes, the spinning
# thread steals the core the working one needs: measured at N = 40k with a load of 6 on 2 cores,
# a step took 3x the single-thread wall time and 3x its CPU time.  Sleeping waits cost a few
# microseconds per kernel on an idle machine.  A value the user set wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from . import cells, formulas, fused, geometry, kernels, layout, mirror, neighbour_list, steps
from .cells import CSRNeighbours, build_csr
from .neighbour_list import CellNeighbourList, build_pairs_cells
from .solver import NumbaSolver

__all__ = [
    "CSRNeighbours",
    "CellNeighbourList",
    "NumbaSolver",
    "build_csr",
    "build_pairs_cells",
    "cells",
    "formulas",
    "fused",
    "geometry",
    "kernels",
    "layout",
    "mirror",
    "neighbour_list",
    "steps",
]
