"""The lid-driven cavity case (definition in :mod:`.case`); Ghia, Ghia & Shin's (1982)
centreline velocities load, checked, from :mod:`.reference`."""

from .case import CASE

__all__ = ["CASE"]
