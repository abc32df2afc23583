"""The numba backend (registry name ``numba``): the reference physics, compiled, on cell lists.

Needs numba (the ``fast`` extra).  Without it, importing this package raises ImportError with
the install command, so the solver registry lists ``numba`` as unavailable with that reason.

* :mod:`.solver`: :class:`NumbaSolver`, the same models, boundary conventions and order of
  operations as the reference backend (they agree to rounding: tests/test_numba_agreement.py).
* :mod:`.cells`: cell-list builds (CSR rows in both directions, half lists with each pair once,
  a half pair list equal to :func:`mpsbench.physics.neighbours.build_pairs`), and
  :class:`.cells.CellNeighbourList` (skin upkeep, a sub-list at the smaller radius).
* :mod:`.pairs`: the WC-MPS step on half lists (each pair evaluated once, two per-chunk
  accumulators so that the result does not depend on the thread count): the solver's default.
* :mod:`.kernels`: per-particle row kernels on full lists: number density, gradients (original,
  pgm1-3), divergence, the four Laplacian models (+ xu-jin gradient correction) on scalar and
  2-vector fields, the Laplacian row sum, collision and stabilization increments.
* :mod:`.steps`: per-particle updates of a WC-MPS step, setup constants (n0, lambda, static
  number density), the diffusion operator as per-entry coefficients.
* :mod:`.mirror`: the ``mirror`` wall velocities (kernel-weighted linear fit at mirror points).
* :mod:`.timing`: ``python -m mpsbench.solvers.numba_backend.timing`` times one pass of the row
  kernels against the numpy operators.

Compiled code is cached on disk (``cache=True``, in ``__pycache__`` next to the sources, or
``NUMBA_CACHE_DIR``): the first process compiles for about 20 s, later ones load in about 0.3 s
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

from . import cells, formulas, geometry, kernels, mirror, neighbour_list, pairs, steps
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
    "geometry",
    "kernels",
    "mirror",
    "neighbour_list",
    "pairs",
    "steps",
]
