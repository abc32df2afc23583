"""The diffusion case: 2-D diffusion against the analytical decay (definition in :mod:`.case`)."""

from .case import CASE

__all__ = ["CASE"]
