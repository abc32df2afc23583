"""The Taylor-Green case: the decaying 2-D vortex on a periodic square (definition in
:mod:`.case`; the exact fields in :mod:`.reference`)."""

from .case import CASE

__all__ = ["CASE"]
