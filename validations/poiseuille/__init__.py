"""The poiseuille case: start-up plane Poiseuille flow driven by a body force (Morris et al.
1997), definition in :mod:`.case`, series solution in :mod:`.reference`."""

from .case import CASE

__all__ = ["CASE"]
