"""Sliding walls (WallMotion(displace=False)): configuration, requirements, the scheme
skeleton's anchoring on both built-in explicit backends, and the conformance check catching a
backend that moves the lid or drops its velocity."""

from __future__ import annotations

import numpy as np
import pytest
from mpsbench.solvers.reference import ReferenceSolver

from mpsbench.errors import ConfigError
from mpsbench.physics.config import WallMotion
from mpsbench.run.protocol import Capabilities
from mpsbench.testing import problems
from mpsbench.testing.catalogue import all_checks

CHECK = next(c for c in all_checks() if c.name == "check_sliding_wall")


def test_displace_must_be_a_boolean() -> None:
    with pytest.raises((ConfigError, ValueError), match="displace"):
        WallMotion(1, (0.1, 0.0), displace="no")  # type: ignore[arg-type]
    assert WallMotion(1, (0.1, 0.0)).displace is True


def test_a_sliding_wall_is_a_requirement_outside_codes_do_not_meet() -> None:
    moving = problems.channel_problem(top_velocity=(0.01, 0.0))
    sliding = problems.channel_problem(top_velocity=(0.01, 0.0), sliding=True)
    assert "sliding-walls" not in moving.requirements()["boundaries"]
    assert {"moving-walls", "sliding-walls"} <= sliding.requirements()["boundaries"]
    # the protocol's default capabilities do not claim it: a plugin must say so
    assert any("sliding-walls" in g for g in Capabilities().gaps(sliding))
    assert not ReferenceSolver.capabilities.gaps(sliding)


@pytest.mark.parametrize("solver", ["reference", "numba", "implicit"])
def test_builtin_backends_pass_the_check(solver: str) -> None:
    CHECK(solver)


@pytest.mark.parametrize("solver", ["reference", "numba"])
def test_lid_stays_while_the_fluid_moves(solver: str) -> None:
    """Over 40 steps the lid's particles keep their positions bit for bit; without sliding the
    same lid moves by n dt U."""
    from mpsbench.run.runner import run

    for sliding in (True, False):
        problem = problems.channel_problem(top_velocity=(0.01, 0.0), sliding=sliding, nu=1e-4)
        lid = problem.particles.fields["wall_tag"] == 1
        res = run(solver, problem, max_steps=40)
        assert res.ok and res.final is not None
        d = np.abs(res.final.pos[lid] - problem.particles.pos[lid]).max()
        assert (d == 0.0) if sliding else (d > 1e-3 * problem.l0)


class LidMoves(ReferenceSolver):
    """Claims sliding walls but lets the predictor move them."""

    name = "lid-moves"

    def _hold_anchored(self) -> None:
        pass


class LidStops(ReferenceSolver):
    """Keeps the lid in place by giving it no velocity at all."""

    name = "lid-stops"

    def _hold_anchored(self) -> None:
        super()._hold_anchored()
        self.p.vel[self.p.fields["anchored"] > 0] = 0.0


@pytest.mark.parametrize(("mutant", "message"), [(LidMoves, "lid moved"),
                                                 (LidStops, "velocity changed")])
def test_the_check_catches_the_mutants(mutant: type, message: str) -> None:
    with pytest.raises(AssertionError, match=message):
        CHECK(mutant)
