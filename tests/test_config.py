"""Configuration dataclasses: a bad value fails naming the field, the value and what is allowed."""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np
import pytest

from mpsbench.physics.config import (
    ConfigError,
    DiffusionPhysics,
    FlowPhysics,
    Inflow,
    Models,
    Region,
    TimeStepping,
    WallMotion,
    replace_validated,
)


def expect_error(cls: type, field: str, value: Any, allowed: str, **other: Any) -> None:
    with pytest.raises(ConfigError) as info:
        cls(**{field: value}, **other)
    msg = str(info.value)
    assert f"{cls.__name__}.{field}" in msg, msg
    assert repr(value) in msg, msg
    assert re.search(allowed, msg), msg


def test_defaults_are_valid_and_frozen() -> None:
    for obj in (Models(), DiffusionPhysics(), FlowPhysics(), TimeStepping()):
        with pytest.raises(dataclasses.FrozenInstanceError):
            obj.__setattr__(dataclasses.fields(obj)[0].name, None)
    assert Models().re_lap_ratio == 2.1
    assert Models(re_ratio_laplacian=3.1).re_lap_ratio == 3.1
    assert isinstance(ConfigError("x"), ValueError)


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("weight", "wf3", r"one of 'wf1', 'wf2'"),
        ("weight", None, r"'wf1'"),
        ("weight", ["wf1"], r"'wf1'"),
        ("laplacian", "lm9", r"'khayyer-gotoh', 'koshizuka-oka', 'xu-jin', 'xu-jin-analytic'"),
        ("gradient", "pgm4", r"'pgm1', 'pgm2', 'pgm3'"),
        ("re_ratio", 0.5, r"a number in \[1.0, 10.0\]"),
        ("re_ratio", float("nan"), r"a number in"),
        ("re_ratio", "2.1", r"a number in"),
        ("re_ratio", True, r"a number in"),
        ("re_ratio_laplacian", 11.0, r"a number in \[1.0, 10.0\]"),
        ("n0_from", "jittered", r"'initial', 'lattice'"),
        ("gradient_correction", "yes", r"True or False"),
    ],
)
def test_models_rejects(field: str, value: Any, allowed: str) -> None:
    expect_error(Models, field, value, allowed)


def test_models_gradient_correction_only_with_xu_jin() -> None:
    expect_error(
        Models,
        "gradient_correction",
        True,
        "only with laplacian 'xu-jin'",
        laplacian="koshizuka-oka",
    )
    assert Models(laplacian="xu-jin", gradient_correction=True).gradient_correction


def test_models_accepts_numpy_numbers() -> None:
    # Any: deliberately not the annotated float, the checks accept numpy integers too
    four: Any = np.int64(4)
    assert Models(re_ratio=np.float64(3.1), re_ratio_laplacian=four).re_lap_ratio == 4


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("kappa", 0.0, r"a finite number > 0"),
        ("kappa", -1.0, r"> 0"),
        ("kappa", float("inf"), r"finite"),
        ("field_name", "", r"a non-empty string"),
        ("field_name", 3, r"a non-empty string"),
    ],
)
def test_diffusion_rejects(field: str, value: Any, allowed: str) -> None:
    expect_error(DiffusionPhysics, field, value, allowed)


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("rho0", 0.0, r"a finite number > 0"),
        ("nu", -1e-6, r"a finite number >= 0"),
        ("c0", float("nan"), r"> 0"),
        ("gravity", (0.0,), r"a pair of finite numbers \(x, y\) in m/s\^2"),
        ("gravity", (0.0, float("inf")), r"pair of finite numbers"),
        ("gravity", "down", r"pair of finite numbers"),
        ("gravity", ("0", "-9.81"), r"pair of finite numbers"),
        ("eos", "ideal-gas", r"one of 'tait', 'linear'"),
        ("gamma", 0, r"> 0"),
        ("surface_beta", 1.2, r"a number in \[0.5, 1.0\]"),
        ("collision_distance", -0.1, r"\[0.0, 1.0\]"),
        ("restitution", 2.0, r"\[0.0, 1.0\]"),
        ("alpha_s", 1.5, r"\[0.0, 1.0\]"),
        ("wall_velocity", "slip", r"one of 'prescribed', 'mirror'"),
        ("stabilization_rate", "time", r"one of 'step', 'acoustic'"),
        ("collision", "on", r"True or False"),
        ("stabilization", 1, r"True or False"),
        ("stabilization_walls", None, r"True or False"),
        ("clip_negative_pressure", "no", r"True or False"),
        ("shifting", "yes", r"True or False"),
        ("shifting_coefficient", -1.0, r"\[0.0, 10.0\]"),
        ("shifting_coefficient", float("nan"), r"\[0.0, 10.0\]"),
    ],
)
def test_flow_physics_rejects(field: str, value: Any, allowed: str) -> None:
    expect_error(FlowPhysics, field, value, allowed)


def test_flow_physics_accepts() -> None:
    # Any: deliberately not the annotated tuple and bool, the checks accept a list and numpy bool
    gravity: Any = [0, -9.81]
    stabilization: Any = np.bool_(True)
    ph = FlowPhysics(nu=0.0, gravity=gravity, stabilization=stabilization, eos="linear")
    assert ph.kind == "flow" and DiffusionPhysics().kind == "diffusion"


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("dt", 0.0, r"> 0"),
        ("dt", -1e-4, r"> 0"),
        ("cfl", 0.0, r"a number in \[1e-06, 1.0\]"),
        ("cfl", 1.5, r"\[1e-06, 1.0\]"),
        ("c_nu", "0.5", r"\[1e-06, 1.0\]"),
    ],
)
def test_time_stepping_rejects(field: str, value: Any, allowed: str) -> None:
    expect_error(TimeStepping, field, value, allowed)


INFLOW = {"start": (0.0, 0.0), "end": (0.0, 1.0), "velocity": (1.0, 0.0)}


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("layers", 0, r"an integer >= 1"),
        ("layers", 2.5, r"an integer >= 1"),
        ("velocity", (0.0, 0.0), r"a non-zero pair of finite numbers \(x, y\) in m/s"),
        ("start", (0.0,), r"in m"),
        ("end", (0.0, 0.0), r"a point different from start"),
    ],
)
def test_inflow_rejects(field: str, value: Any, allowed: str) -> None:
    other = {k: v for k, v in INFLOW.items() if k != field}
    expect_error(Inflow, field, value, allowed, **other)


def test_region_and_wall_motion() -> None:
    assert Region((0.0, 0.0), (1.0, 1.0)).hi == (1.0, 1.0)
    expect_error(Region, "hi", (1.0, 0.0), r"greater than lo = \(0.0, 0.0\)", lo=(0.0, 0.0))
    expect_error(Region, "lo", "origin", r"pair of finite numbers", hi=(1.0, 1.0))
    assert WallMotion(2, (1.25e-5, 0.0)).tag == 2
    expect_error(WallMotion, "tag", "top", r"an integer", velocity=(0.0, 0.0))
    expect_error(WallMotion, "velocity", (1.0, None), r"pair of finite numbers", tag=1)


def test_replace_validated() -> None:
    m = replace_validated(Models(), laplacian="koshizuka-oka")
    assert m.laplacian == "koshizuka-oka"
    with pytest.raises(ConfigError, match="Models has no field.s. lapl; known: .*laplacian"):
        replace_validated(Models(), lapl="x")
    with pytest.raises(ConfigError, match=r"Models.re_ratio = 0.1"):
        replace_validated(Models(), re_ratio=0.1)
