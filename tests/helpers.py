"""Small helpers shared by the tests (importable as ``tests.helpers``)."""

from __future__ import annotations

import numpy as np

from mpsbench.physics.particles import block


def free_lattice(n_side: int, l0: float = 1.0) -> np.ndarray:
    """A free (non-periodic) n_side x n_side square lattice centred on the origin."""
    half = n_side * l0 / 2.0
    return block(-half, -half, n_side, n_side, l0).pos


def interior_mask(pos: np.ndarray, depth: float) -> np.ndarray:
    """Particles at least ``depth`` from the edge of the cloud's bounding box."""
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    return np.all((pos - lo >= depth - 1e-12) & (hi - pos >= depth - 1e-12), axis=1)
