"""The reference backend (registry name ``reference``)."""

from .solver import ReferenceSolver

__all__ = ["ReferenceSolver"]
