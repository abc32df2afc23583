"""``ko-local``: the Koshizuka-Oka Laplacian with a local instead of a global normalisation.

Koshizuka & Oka (1996) write lap(phi)_i = (2D / (lambda n0)) sum_j (phi_j - phi_i) W_ij, where
lambda n0 = sum_j W_ij r_ij^2 is taken once, on the ideal lattice.  Here that second moment is
measured around each particle, S_i = sum_j W_ij r_ij^2, and the pair uses the mean of its two
ends, so the coefficients stay symmetric (the viscous term keeps conserving momentum):

    c_ij = 2 D W_ij / ((S_i + S_j) / 2)

On a full, regular neighbourhood S_i = lambda n0 and the model is the original one; on a
disordered or truncated neighbourhood the normalisation follows the particles that are there.

The model is three formulas in plain arithmetic: mpsbench evaluates them on numpy arrays for the
reference backend and compiles them into the numba backend's kernels, so ko-local runs on both.
"""

from __future__ import annotations

import numpy as np

from mpsbench.physics.laplacians import LaplacianModel


class LocalKoshizukaOka(LaplacianModel):
    """LM1 with a per-pair second-moment normalisation: 2D W_ij / mean(S_i, S_j)."""

    name = "ko-local"
    description = "LM1 with a local normalisation: 2D W_ij / mean(S_i, S_j), S_i = sum W r^2"
    source = "mpsbench example plugin (after Koshizuka & Oka 1996)"

    @staticmethod
    def moment(r, w, dw, d2w):
        """The per-particle sum S_i = sum_j W_ij r_ij^2 [m^2] (summed over i's pairs)."""
        return w * (r * r)

    @staticmethod
    def pair(r, w, dw, d2w, s_i, s_j):
        """W_ij / mean(S_i, S_j); S > 0 wherever W > 0 (the pair itself is in the sum)."""
        return w / np.maximum(0.5 * (s_i + s_j), 1e-300)

    @staticmethod
    def prefactor(n0, lam):
        """2D (the lattice constants n0, lambda are not needed)."""
        return 2.0 * 2
