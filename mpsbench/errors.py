"""The project's own error types.

Every error that a user's input can cause derives from :class:`MpsbenchError`; the command line
reports these in one line with exit status 2, without a traceback.
"""

from __future__ import annotations


class MpsbenchError(Exception):
    """Base class of the errors that bad input (arguments, files, configuration) raises."""


class ConfigError(MpsbenchError, ValueError):
    """A configuration value is not allowed; the message names field, value and what is allowed."""


class UsageError(MpsbenchError):
    """Bad input from the user: reported in one line, exit status 2."""
