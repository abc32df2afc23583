"""The hydrostatic case: a water column at rest under gravity (definition in :mod:`.case`; the
exact pressure in :mod:`.reference`)."""

from .case import CASE

__all__ = ["CASE"]
