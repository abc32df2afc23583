"""``ko-local``: the Koshizuka-Oka Laplacian with a local instead of a global normalisation.

Koshizuka & Oka (1996) write lap(phi)_i = (2D / (lambda n0)) sum_j (phi_j - phi_i) W_ij, where
lambda n0 = sum_j W_ij r_ij^2 is taken once, on the ideal lattice.  Here that second moment is
measured around each particle, S_i = sum_j W_ij r_ij^2, and the pair uses the mean of its two
ends, so the coefficients stay symmetric (the viscous term keeps conserving momentum):

    c_ij = 2 D W_ij / ((S_i + S_j) / 2)

On a full, regular neighbourhood S_i = lambda n0 and the model is the original one; on a
disordered or truncated neighbourhood the normalisation follows the particles that are there.
"""

from __future__ import annotations

import numpy as np

from mpsbench.physics.operators import LaplacianModel


class LocalKoshizukaOka(LaplacianModel):
    """LM1 with a per-pair second-moment normalisation: 2D W_ij / mean(S_i, S_j)."""

    name = "ko-local"
    description = "LM1 with a local normalisation: 2D W_ij / mean(S_i, S_j), S_i = sum W r^2"
    source = "mpsbench example plugin (after Koshizuka & Oka 1996)"

    def coefficients(self, pairs, weight, re, n0, lam, dim=2):
        """Per-pair coefficients c_ij, aligned with ``pairs`` (symmetric in i and j).

        ``pairs`` has ``i``, ``j``, ``r`` (distances [m]) and ``sum_sym`` (per-particle sums);
        ``weight.w(r, re)`` is the weighting function, zero beyond ``re`` [m].  ``n0`` and
        ``lam`` (the lattice constants) are not needed by this model.
        """
        w = weight.w(pairs.r, re)
        moment = pairs.sum_sym(w * pairs.r**2)  # S_i [m^2]
        s = 0.5 * (moment[pairs.i] + moment[pairs.j])
        out = np.zeros_like(w)
        np.divide(2.0 * dim * w, s, out=out, where=s > 0)
        return out
