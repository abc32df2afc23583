"""Whole-number powers as products of multiplications, so that they round alike on every machine.

numpy picks the code of ``power``, ``exp`` and ``log`` for the processor when it is imported
(numpy 2.4 has AVX-512 versions of them that an AVX2 machine does not run), and the versions
differ in the last bit (tests/test_powers.py switches the dispatch off to show it).  A weakly
compressible run amplifies that bit: the reference backend's unstabilized water jet of the
smoke tier ended with a density drift maximum of 0.400 on one instance and 0.540 on another,
with the same code and numpy.  A product of IEEE multiplications rounds the same everywhere,
so the models write whole powers with :func:`whole_power` (or as ``t * t * t``), and the numba
backend compiles this same function, so both backends multiply in the same order.  Works on
floats and numpy arrays alike.
"""

from __future__ import annotations

from typing import Any

import numpy as np

MAX_WHOLE_EXPONENT = 16  # beyond this, x ** gamma (a rare case: Tait's gamma is 7, or 1)


def whole_exponent(gamma: float) -> int:
    """``gamma`` as an int when it is a whole number 1..16, else 0 (use ``x ** gamma`` then)."""
    return int(gamma) if gamma == np.floor(gamma) and 1.0 <= gamma <= MAX_WHOLE_EXPONENT else 0


def whole_power(x: Any, n: int) -> Any:
    """x**n for a whole n >= 1 by binary exponentiation: x^7 = (x * x^2) * x^4.

    ``x ** n`` on an array calls numpy's ``power``, whose rounding depends on the processor
    (see the module docstring); this does not.  It differs from a correctly rounded power by a
    few ulp for n = 7."""
    result = 1.0
    base = x
    e = n
    while e > 0:
        if e & 1:
            result = result * base
        e >>= 1
        if e > 0:
            base = base * base
    return result


def power(x: Any, gamma: float) -> Any:
    """x**gamma: :func:`whole_power` for a whole gamma 1..16, numpy's power otherwise."""
    n = whole_exponent(gamma)
    return whole_power(x, n) if n else x**gamma
