"""The PySPH backends (``pysph-wcsph``, ``pysph-edac``; the ``pysph`` extra) through the
harness's cases, against the exact Couette solution and Martin & Moyce's dam break, with the
capability refusals and the crash guard.

Marked ``pysph`` and skipped with the reason where PySPH is not installed
(``pip install ".[pysph]"``).  The first use of each scheme compiles PySPH's generated code
(1-4 minutes; cached in ~/.pysph), so the tests reuse few configurations.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from mpsbench.physics.config import FlowPhysics
from mpsbench.run.protocol import Status
from mpsbench.run.runner import run
from mpsbench.testing.problems import periodic_flow_problem

pytestmark = [
    pytest.mark.pysph,
    pytest.mark.skipif(importlib.util.find_spec("pysph") is None,
                       reason='PySPH is not installed (pip install ".[pysph]")'),
]


def couette(solver: str, **params: object) -> dict[str, float]:
    from mpsbench.validations.couette.case import CASE

    out = CASE.execute({**CASE.defaults(), "l0": 5e-5, "steady": False, **params}, solver)
    assert out.results[0].status == Status.COMPLETED, out.results[0].reason
    return out.metrics


def test_wcsph_couette_on_plate() -> None:
    """WCSPH's no-slip point sits on the first wall row (the case's default layout): ~1.8 % at
    L/20 (PySPH's Morris viscosity; the offset layout gives ~7 %)."""
    m = couette("pysph-wcsph")
    assert 0.005 < m["l2_error"] < 0.03, m["l2_error"]


def test_edac_couette_offset_and_drift() -> None:
    """EDAC's (Adami) no-slip point sits half a spacing outside the last fluid row: the offset
    layout gives ~0.4 % at L/20; with every particle crossing the periodic edges (drift) the
    error is the same (PySPH's DomainManager wraps them)."""
    from mpsbench.validations.couette.case import SMOKE_DRIFT

    still = couette("pysph-edac", wall_row="offset")
    moving = couette("pysph-edac", wall_row="offset", drift=SMOKE_DRIFT)
    assert still["l2_error"] < 0.01, still["l2_error"]
    assert abs(moving["l2_error"] - still["l2_error"]) < 0.05 * still["l2_error"]


@pytest.mark.parametrize("solver", ["pysph-wcsph", "pysph-edac"])
def test_dam_break_front_against_martin_moyce(solver: str) -> None:
    from mpsbench.validations.dam_break.case import CASE, resolve

    # the variant sets the Laplacian and the stabilization (off for wc-mps), as a sweep does
    params = resolve({**CASE.defaults(), "geometry": "koshizuka-oka", "variant": "wc-mps",
                      "l0": 0.0146}, set())
    out = CASE.execute(params, solver)
    assert out.results[0].status == Status.COMPLETED, out.results[0].reason
    # SPH runs ahead of the experiment (no gate), as the MPS backends do; a wrong gravity or
    # a missing wall would put it far outside
    assert 0.0 < out.metrics["front_mean_offset"] < 0.5
    assert out.metrics["front_rms_error"] < 0.5


@pytest.mark.parametrize("solver", ["pysph-wcsph", "pysph-edac"])
def test_what_pysph_lacks_is_unsupported_with_the_reason(solver: str) -> None:
    from mpsbench.validations.dam_break.case import CASE

    params = {**CASE.defaults(), "geometry": "koshizuka-oka", "variant": "iwc-mps",
              "l0": 0.0146}
    out = CASE.execute(params, solver)
    assert out.results[0].status == Status.UNSUPPORTED
    assert "feature 'stabilization' not supported" in out.results[0].reason


def test_guard_stops_a_runaway_particle_before_pysph_sees_it() -> None:
    """A fluid particle faster than c0 is caught inside the step (the post-stage guard), so
    PySPH's neighbour search never bins a runaway or NaN position (its segfault)."""
    problem = periodic_flow_problem(n_side=8)
    assert isinstance(problem.physics, FlowPhysics)
    fluid = np.flatnonzero(problem.particles.kind == 0)
    problem.particles.vel[fluid[0]] = (3.0 * problem.physics.c0, 0.0)
    res = run("pysph-wcsph", problem, max_steps=3)
    assert res.status == Status.DIVERGED
    assert "PySPH: fluid speed" in res.reason and "stage 1" in res.reason
