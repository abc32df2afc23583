"""Weighting functions: values, derivatives, support, registry."""

from __future__ import annotations

import numpy as np
import pytest

from mpsbench.physics.weights import (
    SUPPORT_RTOL,
    WEIGHTS,
    WF1,
    WF2,
    WeightFunction,
    get_weight,
    within_support,
)
from mpsbench.registry import UnknownNameError

RE = 2.1


def test_wf1_values() -> None:
    wf = get_weight("wf1")
    r = np.array([0.5, 1.0, 1.4, 2.1])
    np.testing.assert_allclose(wf.w(r, RE), [3.2, 1.1, 0.5, 0.0], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(wf.dw(r, RE), -RE / r**2, rtol=1e-14)
    np.testing.assert_allclose(wf.d2w(r, RE), 2 * RE / r**3, rtol=1e-14)


def test_wf2_values() -> None:
    wf = get_weight("wf2")
    r = np.array([0.0, 0.7, 1.05, 2.1])
    np.testing.assert_allclose(wf.w(r, RE), [1.0, (2 / 3) ** 3, 0.125, 0.0], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(wf.dw(r, RE), -(3 / RE) * (1 - r / RE) ** 2, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(wf.d2w(r, RE), (6 / RE**2) * (1 - r / RE), rtol=1e-14, atol=1e-15)
    # finite at r = 0 (WF1 is not)
    assert wf.dw(0.0, RE) == pytest.approx(-3 / RE)


@pytest.mark.parametrize("name", ["wf1", "wf2"])
@pytest.mark.parametrize("re", [0.021, 2.1, 40.0])
def test_derivatives_match_central_differences(name: str, re: float) -> None:
    wf = get_weight(name)
    r = re * np.linspace(0.15, 0.9, 13)
    h = 1e-5 * re
    fd1 = (wf.w(r + h, re) - wf.w(r - h, re)) / (2 * h)
    fd2 = (wf.w(r + h, re) - 2 * wf.w(r, re) + wf.w(r - h, re)) / h**2
    np.testing.assert_allclose(wf.dw(r, re), fd1, rtol=1e-7)
    np.testing.assert_allclose(wf.d2w(r, re), fd2, rtol=1e-4)


@pytest.mark.parametrize("name", ["wf1", "wf2"])
def test_zero_outside_support(name: str) -> None:
    wf = get_weight(name)
    r = np.array([2.1000001, 2.5, 3.0, 100.0])
    for fn in (wf.w, wf.dw, wf.d2w):
        out = fn(r, RE)
        assert out.shape == r.shape
        assert np.all(out == 0.0)
    # and non-zero just inside
    assert wf.w(np.array([2.0]), RE)[0] > 0


def test_support_is_closed_under_rounding() -> None:
    """r_e reached through arithmetic (4 * 0.02 != 0.08 in binary) counts as r_e."""
    re = 0.08
    r = np.array([4 * 0.02, 0.02 * np.hypot(4.0, 0.0), re * (1 + 0.5 * SUPPORT_RTOL)])
    assert np.all(within_support(r, re))
    wf1 = get_weight("wf1")
    np.testing.assert_array_equal(wf1.dw(r, re), np.full(3, -1 / re))  # evaluated at r_e
    assert not within_support(re * (1 + 10 * SUPPORT_RTOL), re)


def test_scalar_and_shape_handling() -> None:
    wf = get_weight("wf2")
    out = wf.w(1.05, RE)
    assert np.ndim(out) == 0 and float(out) == pytest.approx(0.125)
    grid = np.full((3, 4), 1.05)
    assert wf.w(grid, RE).shape == (3, 4)
    assert wf.w([1, 2, 3], RE).dtype == np.float64  # integer input is fine


def test_registry_lookup() -> None:
    assert WEIGHTS.names() == ["wf1", "wf2"]
    assert isinstance(get_weight("wf1"), WF1)
    assert isinstance(get_weight("wf2"), WF2)
    inst = WF2()
    assert get_weight(inst) is inst
    assert "wf1" in WEIGHTS and "wf3" not in WEIGHTS
    assert WEIGHTS.entry("wf1").description.startswith("W = r_e/r - 1")


def test_unknown_name_lists_known_names() -> None:
    with pytest.raises(UnknownNameError) as info:
        get_weight("gaussian")
    msg = str(info.value)
    assert "'gaussian'" in msg and "wf1" in msg and "wf2" in msg
    assert isinstance(info.value, KeyError) and isinstance(info.value, ValueError)


def test_base_class_is_abstract() -> None:
    with pytest.raises(NotImplementedError):
        WeightFunction().w(np.array([1.0]), RE)


def test_new_weight_is_one_class_and_one_registration() -> None:
    """The README's plugin example, kept honest."""

    class Quadratic(WeightFunction):
        name = "test-quadratic"

        @staticmethod
        def w_inside(r, re):
            return (1 - r / re) ** 2

        @staticmethod
        def dw_inside(r, re):
            return -2 / re * (1 - r / re)

        @staticmethod
        def d2w_inside(r, re):
            return 2 / re**2

    WEIGHTS.register("test-quadratic", Quadratic(), origin="user")
    try:
        wf = get_weight("test-quadratic")
        assert wf.w(np.array([1.0, 3.0]), 2.0).tolist() == [0.25, 0.0]
    finally:
        WEIGHTS.unregister("test-quadratic")
    assert "test-quadratic" not in WEIGHTS
