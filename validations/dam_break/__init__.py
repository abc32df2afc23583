"""The dam-break case: the dam break against Martin & Moyce and Lobovsky et al.
(definition in :mod:`.case`)."""

from .case import CASE

__all__ = ["CASE"]
