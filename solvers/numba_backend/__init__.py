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

try:
    import numba  # noqa: F401
except ImportError as exc:  # pragma: no cover - exercised only without numba
    raise ImportError("numba is not installed: pip install 'mpsbench[fast]'") from exc

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
