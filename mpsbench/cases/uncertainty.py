"""Numerical and validation uncertainty of one metric (docs/method.md section 9).

Pure functions on numbers, no records: :mod:`mpsbench.cases.refinement` finds the refinement
sets in a case's records and calls these.

Numerical uncertainty (Roache 1997; Celik et al. 2008; ASME V&V 20-2009).  Solutions f1 (finest),
f2, f3 of one metric at refinement ratios r21 = h2/h1 and r32 = h3/h2 (h = l0 or dt):

* convergence ratio R = (f1 - f2)/(f2 - f3): 0 < R < 1 monotone, R < 0 oscillatory, R >= 1
  diverging;
* observed order p (monotone only): the root of
  p ln r21 = ln((f3 - f2)/(f2 - f1)) + ln((r21^p - 1)/(r32^p - 1)), which is
  ln((f3 - f2)/(f2 - f1)) / ln r when r21 = r32 = r;
* Richardson extrapolation f_ext = f1 + (f1 - f2)/(r21^p - 1);
* GCI_fine = Fs |(f1 - f2)/f1| / (r21^p - 1), Fs = 1.25 with three levels, 3 with two (and
  the theoretical order of the metric, which the caller states);
* u_num = GCI_fine |f1| = Fs |f1 - f_ext|, an interval of about 95 % coverage.  A coarser
  member of the set gets Fs |f - f_ext| (the same estimate carried to its own value).

Outside the monotone range there is no order and no GCI: the set is "oscillatory" or
"diverging" and the metric "not converged".

Validation uncertainty (V&V 20): E = S - D, u_val = sqrt(u_num^2 + u_D^2) (u_input is not
estimated: the inputs of the cases are exact or fixed); |E| <= u_val means the comparison
cannot tell the model error from the noise of the comparison; |E| > u_val means E estimates the
model error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from scipy.optimize import brentq

FS_THREE = 1.25  # safety factor with three or more levels (observed order)
FS_TWO = 3.0  # with two levels (theoretical order)

MONOTONE = "monotone"
OSCILLATORY = "oscillatory"
DIVERGING = "diverging"
TWO_LEVELS = "two levels"
UNCHANGED = "unchanged"
NO_ORDER = "two levels, no theoretical order"
INCOMPLETE = "incomplete"  # a run at a finer level diverged or failed (see refinement.py)

# convergence kinds that give a u_num
CONVERGED = (MONOTONE, TWO_LEVELS, UNCHANGED)


@dataclass(frozen=True)
class Convergence:
    """What a refinement sequence says about one metric (values and steps finest first)."""

    values: tuple[float, ...]
    steps: tuple[float, ...]
    kind: str
    ratio: float | None = None  # R (three levels)
    order: float | None = None  # observed (three levels) or the theoretical one (two)
    order_observed: bool = False
    extrapolated: float | None = None  # f_ext
    safety: float | None = None  # Fs
    u_num: float | None = None  # absolute, of the finest value

    @property
    def converged(self) -> bool:
        return self.kind in CONVERGED and self.u_num is not None

    @property
    def gci(self) -> float | None:
        """GCI_fine as a fraction of |f1| (None when f1 = 0 or not converged)."""
        if self.u_num is None or not self.values or self.values[0] == 0:
            return None
        return self.u_num / abs(self.values[0])

    def u_num_at(self, value: float) -> float | None:
        """u_num of a member of the set: Fs |value - f_ext| (None when not converged)."""
        if not self.converged or self.extrapolated is None or self.safety is None:
            return None
        return self.safety * abs(value - self.extrapolated)

    def describe(self) -> str:
        """One line: levels, kind, order, extrapolated value."""
        text = self.kind
        if self.ratio is not None:
            text += f", R = {self.ratio:.3g}"
        if self.order is not None and self.kind != UNCHANGED:
            text += f", {'observed' if self.order_observed else 'assumed'} order {self.order:.3g}"
        if self.extrapolated is not None:
            text += f", extrapolated {self.extrapolated:.4g}"
        return text


def convergence_ratio(f1: float, f2: float, f3: float) -> float:
    """R = (f1 - f2)/(f2 - f3) (inf when f2 = f3 != f1, nan when all equal)."""
    e21, e32 = f1 - f2, f2 - f3
    if e32 == 0:
        return math.nan if e21 == 0 else math.inf
    return e21 / e32


def observed_order(f1: float, f2: float, f3: float, r21: float, r32: float | None = None) -> float:
    """Observed order of a monotone sequence (finest first; r = coarser/finer step).

    Exact for f = f0 + C h^p.  With r21 = r32 the closed form; otherwise the root of Celik et
    al.'s (2008) equation.  NaN when the sequence is not monotone or has no positive order.
    """
    r32 = r21 if r32 is None else r32
    e21, e32 = f2 - f1, f3 - f2
    if e21 == 0 or e32 == 0 or (e32 / e21) <= 0:
        return math.nan
    q = math.log(e32 / e21)
    if math.isclose(r21, r32, rel_tol=1e-12):
        p = q / math.log(r21)
        return p if p > 0 else math.nan

    def g(p: float) -> float:
        return p * math.log(r21) + math.log((r32**p - 1.0) / (r21**p - 1.0)) - q

    lo, hi = 1e-9, 60.0
    if g(lo) * g(hi) > 0:
        return math.nan
    return float(brentq(g, lo, hi, xtol=1e-14, rtol=1e-14, maxiter=200))


def richardson(f1: float, f2: float, r21: float, order: float) -> float:
    """f_ext = f1 + (f1 - f2)/(r21^p - 1)."""
    return f1 + (f1 - f2) / (r21**order - 1.0)


def convergence(
    values: Sequence[float], steps: Sequence[float], order: float | None = None
) -> Convergence:
    """Convergence of a metric over a refinement sequence.

    ``values[k]`` is the metric at step ``steps[k]`` (any order; sorted here, finest = smallest
    step first).  Three or more levels: the three finest give R, the observed order, f_ext and
    u_num with Fs = 1.25.  Two levels: ``order`` is the theoretical order of the metric (without
    it no u_num), Fs = 3.  Equal values give u_num = 0 ("unchanged").
    """
    pairs = sorted((float(h), float(f)) for h, f in zip(steps, values, strict=True))
    if len({h for h, _ in pairs}) != len(pairs):
        raise ValueError(f"refinement steps must differ: {[h for h, _ in pairs]}")
    if any(not math.isfinite(f) for _, f in pairs):
        raise ValueError(f"refinement values must be finite: {[f for _, f in pairs]}")
    if len(pairs) < 2 or pairs[0][0] <= 0:
        raise ValueError("a refinement set needs two or more positive steps")
    h = tuple(p[0] for p in pairs)
    f = tuple(p[1] for p in pairs)
    if len(f) == 2:
        return _two_levels(f, h, order)
    f1, f2, f3 = f[:3]
    r21, r32 = h[1] / h[0], h[2] / h[1]
    ratio = convergence_ratio(f1, f2, f3)
    if f1 == f2:
        # no change between the two finest: converged to the precision of the metric
        return Convergence(f, h, UNCHANGED, ratio=ratio, extrapolated=f1, safety=FS_THREE,
                           u_num=0.0)
    if not math.isfinite(ratio) or ratio >= 1.0:
        return Convergence(f, h, DIVERGING, ratio=ratio)
    if ratio < 0:
        return Convergence(f, h, OSCILLATORY, ratio=ratio)
    p = observed_order(f1, f2, f3, r21, r32)
    if not math.isfinite(p):
        return Convergence(f, h, DIVERGING, ratio=ratio)
    ext = richardson(f1, f2, r21, p)
    return Convergence(f, h, MONOTONE, ratio=ratio, order=p, order_observed=True,
                       extrapolated=ext, safety=FS_THREE, u_num=FS_THREE * abs(f1 - ext))


def _two_levels(f: tuple[float, ...], h: tuple[float, ...], order: float | None) -> Convergence:
    f1, f2 = f[0], f[1]
    if f1 == f2:
        return Convergence(f, h, UNCHANGED, order=order, extrapolated=f1, safety=FS_TWO,
                           u_num=0.0)
    if order is None or order <= 0:
        return Convergence(f, h, NO_ORDER)
    ext = richardson(f1, f2, h[1] / h[0], order)
    return Convergence(f, h, TWO_LEVELS, order=order, extrapolated=ext, safety=FS_TWO,
                       u_num=FS_TWO * abs(f1 - ext))


def combine(parts: Sequence[float | None]) -> float | None:
    """Independent components (l0, dt) in quadrature; None when one is unknown."""
    if any(p is None for p in parts):
        return None
    return math.sqrt(sum(float(p) ** 2 for p in parts if p is not None))


# ---------------------------------------------------------------------- validation
AGREES = "agrees within u_val"
MODEL_ERROR = "model error"
NOT_CONVERGED = "not converged"


@dataclass(frozen=True)
class Validation:
    """E = S - D against u_val = sqrt(u_num^2 + u_D^2), and the verdict (V&V 20)."""

    simulated: float
    data: float
    u_num: float | None  # None: not converged (or not measured, see ``u_num_measured``)
    u_data: float
    u_num_measured: bool = True

    @property
    def error(self) -> float:
        return self.simulated - self.data

    @property
    def u_val(self) -> float | None:
        if self.u_num is None:
            return None if self.u_num_measured else self.u_data
        return math.hypot(self.u_num, self.u_data)

    @property
    def verdict(self) -> str:
        if self.u_num is None and self.u_num_measured:
            return NOT_CONVERGED
        u = self.u_val
        assert u is not None
        return AGREES if abs(self.error) <= u else MODEL_ERROR

    def describe(self, fmt: str = ".3g") -> str:
        u = self.u_val
        text = (f"E = {self.error:+{fmt}}, u_num = "
                + ("not converged" if self.u_num is None and self.u_num_measured else
                   "not measured" if self.u_num is None else f"{self.u_num:{fmt}}")
                + f", u_D = {self.u_data:{fmt}}")
        if u is not None:
            text += f", u_val = {u:{fmt}}"
        return text + f": {self.verdict}"


def validation(simulated: float, data: float, u_num: float | None, u_data: float, *,
               u_num_measured: bool = True) -> Validation:
    """The comparison of a simulated value S with data D (``u_num`` None: not converged, or
    with ``u_num_measured=False`` no refinement set, in which case u_val = u_D)."""
    if not (math.isfinite(simulated) and math.isfinite(data)) or u_data < 0:
        raise ValueError(f"validation needs finite S, D and u_D >= 0: {simulated}, {data}, "
                         f"{u_data}")
    return Validation(float(simulated), float(data), u_num, float(u_data), u_num_measured)
