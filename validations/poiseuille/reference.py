"""Start-up plane Poiseuille flow driven by a body force: the series solution and its truncation.

Morris, J. P., Fox, P. J. and Zhu, Y. (1997), Modeling low Reynolds number incompressible flows
using SPH, J. Comput. Phys. 136:214-226, doi:10.1006/jcph.1997.5776.  Liquid between fixed
plates y = 0 and y = L [m] is at rest at t = 0 and is driven from then on by a uniform body
force per unit mass F [m/s^2] along +x; nu [m^2/s] is the kinematic viscosity.  The flow stays
parallel, so u(y, t) [m/s] solves u_t = nu u_yy + F with u(0, t) = u(L, t) = 0 and u(y, 0) = 0:

    u(y, t) = F y (L - y) / (2 nu)
              - sum_{n >= 0} 4 F L^2 / (nu pi^3 k^3) sin(k pi y / L) exp(-k^2 pi^2 nu t / L^2),

k = 2n + 1: the sum is the sine series of the steady parabola, each mode decaying at its own
rate, so u(y, 0) = 0 and u -> F y (L - y) / (2 nu).  The steady maximum is
u_max = F L^2 / (8 nu) at y = L/2; Morris et al.'s L = 1e-3 m, nu = 1e-6 m^2/s, F = 2e-4 m/s^2
(the defaults) give 2.5e-5 m/s.  Written with the parabola as F y (y - L) / (2 nu) and "+ sum",
as some reproductions of the paper's equation have it, the same expression is -u, the flow in -x;
here F > 0 drives the flow in +x, and the tests check the sign against the PDE.

Truncation rule.  With tau = pi^2 nu t / L^2 and K = 2N + 1, the terms left out after N terms
are bounded at every y by

    B(N, t) = (4 F L^2 / (nu pi^3)) exp(-K^2 tau) (1 / K^3 + 1 / (4 K^2))   [m/s]

(|sin| <= 1, exp(-k^2 tau) <= exp(-K^2 tau) for k >= K, and over odd k >= K,
sum 1/k^3 <= 1/K^3 + (1/2) int_K^inf dk/k^3).  :meth:`Poiseuille.velocity` sums the smallest
N with B(N, t) <= rtol u_max, rtol = 1e-10 by default (2.5e-15 m/s for Morris et al.'s flow).
N falls fast with t: at the default rtol it is 4 at t = 0.0225 s, 1 at t = 1 s and 0 (u is the
parabola to within the bound) once tau is above about 23; as t -> 0 it grows towards
sqrt(0.26 / rtol) / 2 (about 25 000 terms at rtol = 1e-10), since no mode has decayed yet.
t = 0 itself returns the initial condition u = 0 exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: Morris et al.'s (1997) flow: plate gap [m], kinematic viscosity [m^2/s], body force [m/s^2].
MORRIS_L = 1.0e-3
MORRIS_NU = 1.0e-6
MORRIS_F = 2.0e-4

DEFAULT_RTOL = 1.0e-10
#: Below this the bound asks for more than double precision can add up (~1e-16 per term).
MIN_RTOL = 1.0e-14
_CHUNK = 2048  # terms summed at once: memory len(y) * _CHUNK doubles


@dataclass(frozen=True)
class Poiseuille:
    """Plates y = 0 and y = gap [m], viscosity nu [m^2/s], body force F [m/s^2] along +x."""

    gap: float = MORRIS_L
    nu: float = MORRIS_NU
    force: float = MORRIS_F

    def __post_init__(self) -> None:
        for name in ("gap", "nu"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"Poiseuille {name} must be positive, got {getattr(self, name)!r}")

    @property
    def u_max(self) -> float:
        """Steady centreline velocity F L^2 / (8 nu) [m/s]."""
        return self.force * self.gap**2 / (8.0 * self.nu)

    @property
    def diffusion_time(self) -> float:
        """L^2 / (pi^2 nu) [s], the e-folding time of the slowest mode."""
        return self.gap**2 / (math.pi**2 * self.nu)

    def _heights(self, y: ArrayLike) -> FloatArray:
        y_arr = np.asarray(y, dtype=float)
        outside = (y_arr < 0.0) | (y_arr > self.gap)
        if np.any(outside):
            bad = np.atleast_1d(y_arr)[np.atleast_1d(outside)]
            raise ValueError(f"heights outside the gap [0, {self.gap:g}] m: {bad[:5].tolist()}")
        return y_arr

    def steady(self, y: ArrayLike) -> FloatArray:
        """The t -> infinity profile F y (L - y) / (2 nu) [m/s]."""
        y_arr = self._heights(y)
        return self.force * y_arr * (self.gap - y_arr) / (2.0 * self.nu)

    def truncation_bound(self, t: float, n_terms: int) -> float:
        """B(N, t) [m/s]: bound at every y on the terms left out after ``n_terms`` terms."""
        if n_terms < 0:
            raise ValueError(f"n_terms must be >= 0, got {n_terms}")
        return abs(self.u_max) * self._relative_bound(_tau(self, t), 2 * n_terms + 1)

    @staticmethod
    def _relative_bound(tau: float, k: int) -> float:
        """B / u_max = (32 / pi^3) exp(-K^2 tau) (1/K^3 + 1/(4 K^2)), underflowing to 0."""
        log_b = math.log(32.0 / math.pi**3) - k * k * tau + math.log(1.0 / k**3 + 0.25 / k**2)
        return math.exp(log_b) if log_b > -745.0 else 0.0

    def terms_needed(self, t: float, rtol: float = DEFAULT_RTOL) -> int:
        """Smallest N with B(N, t) <= rtol u_max (the truncation rule of the module docstring)."""
        if not MIN_RTOL <= rtol < 1.0:
            raise ValueError(f"rtol must be in [{MIN_RTOL:g}, 1), got {rtol!r}")
        tau = _tau(self, t)
        if self._relative_bound(tau, 1) <= rtol:
            return 0
        lo, hi = 0, 1  # bound(lo) > rtol >= bound(hi) once hi is found; the bound falls with N
        while self._relative_bound(tau, 2 * hi + 1) > rtol:
            lo, hi = hi, 2 * hi
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if self._relative_bound(tau, 2 * mid + 1) > rtol:
                lo = mid
            else:
                hi = mid
        return hi

    def velocity(self, y: ArrayLike, t: float, rtol: float = DEFAULT_RTOL,
                 n_terms: int | None = None) -> FloatArray:
        """u(y, t) [m/s] at heights y [m] and time t [s] >= 0.

        The series is cut by the truncation rule (error below rtol u_max at every y) unless
        ``n_terms`` fixes the number of terms, which the tests use to check the bound.
        """
        y_arr = self._heights(y)
        tau = _tau(self, t)
        if t == 0.0 and n_terms is None:
            return np.zeros_like(y_arr)  # the initial condition, exactly
        n = self.terms_needed(t, rtol) if n_terms is None else n_terms
        if n < 0:
            raise ValueError(f"n_terms must be >= 0, got {n}")
        steady = self.steady(y_arr)
        flat = np.atleast_1d(y_arr).ravel()
        transient = np.zeros_like(flat)
        scale = 4.0 * self.force * self.gap**2 / (self.nu * math.pi**3)
        # Underflow of exp(-k^2 tau) and of its products to 0 is the intended value of a
        # decayed mode (the test suite runs with numpy errors raised).
        with np.errstate(under="ignore"):
            for start in range(0, n, _CHUNK):
                k = 2.0 * np.arange(start, min(n, start + _CHUNK)) + 1.0
                coef = scale / k**3 * np.exp(-(k**2) * tau)
                transient += np.sin(np.multiply.outer(flat, k) * (math.pi / self.gap)) @ coef
        return steady - transient.reshape(y_arr.shape)


def _tau(flow: Poiseuille, t: float) -> float:
    if not t >= 0.0:
        raise ValueError(f"time must be >= 0, got {t!r} s")
    return math.pi**2 * flow.nu * t / flow.gap**2
