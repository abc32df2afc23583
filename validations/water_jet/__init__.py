"""The water-jet case: a water jet on a flat plate against the free-streamline solution
(definition in :mod:`.case`)."""

from .case import CASE

__all__ = ["CASE"]
