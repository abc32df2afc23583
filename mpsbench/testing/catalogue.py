"""Every conformance check, in the order ``mpsbench check`` runs them: the protocol and
invariant checks (:mod:`.checks`), then the physics checks (:mod:`.physics_checks`)."""

from __future__ import annotations

from .checks import Check, api_checks
from .physics_checks import physics_checks


def all_checks() -> list[Check]:
    return api_checks() + physics_checks()
