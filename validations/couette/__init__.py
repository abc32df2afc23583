"""The couette case: start-up Couette flow against the series solution (definition
in :mod:`.case`)."""

from .case import CASE

__all__ = ["CASE"]
