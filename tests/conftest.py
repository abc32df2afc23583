"""Shared fixtures: strict floating point, lattices and jittered clouds."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
import pytest
from hypothesis import settings

from mpsbench.physics.operators import lattice_pairs
from mpsbench.physics.particles import Box, Particles, jitter

# Property tests run real numerics; the default 200 ms deadline is flaky on a loaded CI box.
settings.register_profile("mpsbench", deadline=None, print_blob=True)
settings.load_profile("mpsbench")


@pytest.fixture(autouse=True)
def strict_floats() -> Iterator[None]:
    """Every test runs with numpy floating-point errors raised, not warned."""
    old = np.seterr(all="raise")
    try:
        yield
    finally:
        np.seterr(**old)


@pytest.fixture(autouse=True)
def reference_by_default(request: pytest.FixtureRequest,
                         monkeypatch: pytest.MonkeyPatch) -> None:
    """``validate`` without ``--solver`` runs numba when it is installed; the tests written
    against the reference's numbers and folder names keep the reference (in-process runs only).
    A test marked ``numba_default`` sees the real default (tests/test_validate_all.py)."""
    if request.node.get_closest_marker("numba_default") is None:
        from mpsbench.commands import validate

        monkeypatch.setattr(validate, "default_solver", lambda: ("reference", ""))


@pytest.fixture
def jittered_periodic_cloud() -> Callable[..., tuple[np.ndarray, Box]]:
    """Factory: a fully periodic n_side^2 lattice with seeded uniform jitter (fraction of l0)."""

    def make(
        n_side: int = 16, l0: float = 1.0, amplitude: float = 0.1, seed: int = 7
    ) -> tuple[np.ndarray, Box]:
        pos, box = lattice_pairs(n_side, l0)
        if amplitude:
            p = Particles.from_positions(pos)
            jitter(p, amplitude * l0, seed)
            pos = box.wrap(p.pos)
        return pos, box

    return make
