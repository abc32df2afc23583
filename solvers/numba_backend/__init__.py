"""The numba backend's compute layer: cell-linked neighbour lists and per-particle MPS kernels.

Needs numba (the ``fast`` extra).  Without it, importing this package raises ImportError with
the install command, so the solver registry lists ``numba`` as unavailable with that reason.

* :mod:`.cells`: cell-list builds (CSR rows in both directions, a half pair list equal to
  :func:`mpsbench.neighbours.build_pairs`), and :class:`.cells.CellNeighbourList` (skin upkeep).
* :mod:`.kernels`: number density, gradients (original, pgm1-3), divergence, the four Laplacian
  models (+ xu-jin gradient correction) on scalar and 2-vector fields, the Laplacian row sum
  for the stable time step, collision and stabilization increments.
* :mod:`.steps`: the per-particle updates of a WC-MPS step, setup constants, the diffusion
  operator as per-entry coefficients.
* :mod:`.solver`: :class:`NumbaSolver`, registry name ``numba``.
* :mod:`.timing`: ``python -m mpsbench.solvers.numba_backend.timing`` times one pass against
  the numpy operators.
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

from . import cells, kernels, steps
from .cells import CellNeighbourList, CSRNeighbours, build_csr, build_pairs_cells
from .solver import NumbaSolver

__all__ = [
    "CSRNeighbours",
    "CellNeighbourList",
    "NumbaSolver",
    "build_csr",
    "build_pairs_cells",
    "cells",
    "kernels",
    "steps",
]
