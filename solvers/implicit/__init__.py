"""The semi-implicit MPS backend (registry name ``implicit``)."""

from .solver import ImplicitSolver

__all__ = ["ImplicitSolver"]
