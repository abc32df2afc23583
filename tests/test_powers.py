"""Whole powers as products (mpsbench.physics.powers): accuracy, the numba build's bits, and a
reference run whose bits do not depend on the processor code numpy dispatches to.

The processor test guards against what the smoke gate met: with numpy's ``power`` in the equation of
state, the smoke tier's unstabilized water jet ended with a density drift maximum of 0.400 with
numpy's AVX-512 code and 0.540 with its AVX2 code, on one machine.
"""

from __future__ import annotations

import os
import subprocess
import sys
from fractions import Fraction

import numpy as np
import pytest

from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind
from mpsbench.physics.powers import power, whole_exponent, whole_power
from mpsbench.physics.weights import WF1, WF2
from mpsbench.run.scheme import EquationOfState

ULP = float(np.finfo(float).eps)


def test_whole_exponent_accepts_only_whole_numbers_one_to_sixteen() -> None:
    assert [whole_exponent(g) for g in (1.0, 7.0, 16.0)] == [1, 7, 16]
    assert [whole_exponent(g) for g in (0.0, 7.5, 17.0, -2.0, 1.4)] == [0, 0, 0, 0, 0]


@pytest.mark.parametrize("n", range(1, 17))
def test_whole_power_is_within_a_few_ulp_of_the_exact_power(n: int) -> None:
    xs = np.random.default_rng(n).uniform(0.5, 1.5, 200)
    got = whole_power(xs, n)
    exact = np.array([float(Fraction(float(x)) ** n) for x in xs])
    # each multiplication adds a relative error <= ulp/2 to the sum of its factors' errors, so
    # x^n carries at most (n - 1) ulp/2 (x^16 by squaring: 15 of them); the exact power rounded
    # to a float adds ulp/2, the ratio's division ulp
    assert np.max(np.abs(got / exact - 1.0)) <= (n / 2 + 1) * ULP
    # scalars and arrays give the same bits
    assert whole_power(float(xs[3]), n) == got[3]


def test_whole_power_of_seven_multiplies_in_the_stated_order() -> None:
    x = np.random.default_rng(7).uniform(0.9, 1.1, 500)
    x2 = x * x
    assert np.array_equal(whole_power(x, 7), (x * x2) * (x2 * x2))
    assert np.array_equal(whole_power(x, 2), x * x)


def test_power_falls_back_to_numpy_for_a_fractional_exponent() -> None:
    x = np.array([0.5, 1.0, 2.0])
    assert np.array_equal(power(x, 1.4), x**1.4)
    assert np.array_equal(power(x, 7.0), whole_power(x, 7))


def test_tait_pressure_uses_the_products() -> None:
    ph = FlowPhysics(c0=20.0)
    eos = EquationOfState.of(ph, n0=5.0)
    n = np.random.default_rng(3).uniform(4.9, 5.2, 300)
    kind = np.full(n.shape, Kind.FLUID)
    pres, surface = eos.pressure(n, kind)
    expected = np.maximum(eos.prefactor * (whole_power(n / 5.0, 7) - 1.0), 0.0)
    expected[surface] = 0.0
    assert ph.gamma == 7.0
    assert np.array_equal(pres, expected)


def test_weights_write_their_cubes_as_products() -> None:
    r = np.random.default_rng(5).uniform(0.1, 2.0, 300)
    t = 1.0 - r / 2.1
    assert np.array_equal(WF2.w_inside(r, 2.1), t * t * t)
    assert np.array_equal(WF1.d2w_inside(r, 2.1), 2.0 * 2.1 / (r * r * r))


def test_the_numba_equation_of_state_has_the_same_bits() -> None:
    pytest.importorskip("numba", reason="the numba backend is the [fast] extra")
    from mpsbench.solvers.numba_backend.steps import integer_gamma
    from mpsbench.solvers.numba_backend.steps import power as numba_power

    xs = np.random.default_rng(11).uniform(0.8, 1.2, 100)
    for gamma in (7.0, 3.0, 1.0, 7.5):
        igamma = integer_gamma(gamma)
        assert igamma == whole_exponent(gamma)
        got = np.array([numba_power(float(x), gamma, igamma) for x in xs])
        if igamma:
            assert np.array_equal(got, power(xs, gamma)), gamma
        else:
            np.testing.assert_allclose(got, power(xs, gamma), rtol=4 * ULP)


def _dispatched_features() -> list[str]:
    """The SIMD targets numpy found on this processor and may dispatch to, above its baseline."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # pragma: no cover - numpy < 2 names the module numpy.core
        return []
    return [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]


# a dam break (Tait's power, WF2's cube) and a Couette channel with mirrored wall velocities
# (the least-squares fit of boundaries.py: numpy's batched det and solve, through OpenBLAS)
_RUN = """
import hashlib, numpy as np
from mpsbench.run.runner import run
from mpsbench.testing import problems
for problem in (problems.dam_break_problem(stabilization=False),
                problems.channel_problem(top_velocity=(0.01, 0.0), wall_velocity="mirror")):
    result = run("reference", problem, max_steps=60)
    f = result.final
    print(result.status.value, hashlib.sha256(f.pos.tobytes() + f.vel.tobytes()
          + f.pressure.tobytes()).hexdigest())
"""


def test_a_reference_run_has_the_same_bits_with_numpys_simd_dispatch_off() -> None:
    found = _dispatched_features()
    if not found:
        pytest.skip("numpy dispatches to no SIMD target above its baseline on this processor")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NPY_", "OPENBLAS_"))}
    off = {"NPY_DISABLE_CPU_FEATURES": " ".join(found)}
    if "X86_V3" in found:  # AVX2 and FMA: OpenBLAS's Haswell kernels run here too
        off["OPENBLAS_CORETYPE"] = "Haswell"
    runs = []
    for extra in ({}, off):
        out = subprocess.run(
            [sys.executable, "-c", _RUN], env={**env, **extra},
            capture_output=True, text=True, timeout=300, check=False,
        )
        assert out.returncode == 0, out.stderr[-2000:]
        runs.append(out.stdout.split())
    assert runs[0][0::2] == ["completed", "completed"], runs[0]
    assert runs[0] == runs[1], f"the runs' states depend on the dispatch ({off})"
