"""Diffusion: the exact solution and the errors of an end field (docs/method.md 6a).

phi0 = sin(2 pi x) sin(2 pi y) on the periodic unit square decays as exp(-8 pi^2 kappa t);
kappa = ln 2 / (8 pi^2) m^2/s halves the amplitude at END_TIME = 1 s.
"""

from __future__ import annotations

import math

import numpy as np

KAPPA = math.log(2.0) / (8.0 * math.pi**2)  # m^2/s
END_TIME = 1.0  # s: exp(-8 pi^2 KAPPA END_TIME) = 0.5
EXACT_RATE = 8.0 * math.pi**2 * KAPPA  # 1/s (= ln 2)
FIELD = "phi"


def phi0(pos: np.ndarray) -> np.ndarray:
    return np.sin(2 * np.pi * pos[:, 0]) * np.sin(2 * np.pi * pos[:, 1])


def field_errors(
    phi: np.ndarray, exact: np.ndarray, start: np.ndarray, t: float
) -> dict[str, float]:
    """Relative L2 / Linf errors and the decay-rate ratio of an end field."""
    amplitude = float(phi @ start / (start @ start))
    rate = -math.log(amplitude) / t if amplitude > 0 else math.inf
    return {
        "l2_error": float(np.linalg.norm(phi - exact) / np.linalg.norm(exact)),
        "linf_error": float(np.max(np.abs(phi - exact)) / np.max(np.abs(exact))),
        "decay_ratio": rate / EXACT_RATE,
    }
