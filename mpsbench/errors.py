"""The project's own error types, and where an unexpected exception came from.

Every error that a user's input (arguments, files, configuration) or the environment (an output
folder that cannot be written, too little memory) can cause derives from :class:`MpsbenchError`;
the command line reports these in one line with exit status 2, without a traceback (``--debug``
shows it).  The registries', the baseline comparison's, the study files', the data files' and
the executors' errors derive from it too.
"""

from __future__ import annotations

import os
import sys
import traceback


class MpsbenchError(Exception):
    """Base class of the errors that bad input (arguments, files, configuration) raises."""


class ConfigError(MpsbenchError, ValueError):
    """A configuration value is not allowed; the message names field, value and what is allowed."""


class UsageError(MpsbenchError):
    """Bad input from the user: reported in one line, exit status 2."""


class InputFileError(MpsbenchError, ValueError):
    """A file the command reads (a run record, a results table, a report file) is unreadable,
    truncated, or holds values that are not allowed; the message names the file and record."""


def where(exc: BaseException) -> str:
    """`` (at mpsbench/validations/diffusion/case.py:132)`` for the frame that raised ``exc``.

    The file is named by its module (``package/module.py``), not by where it is installed, so
    records and reports made on different machines read the same and leak no install paths.
    Empty when the exception carries no traceback.
    """
    tb = traceback.extract_tb(exc.__traceback__)
    if not tb:
        return ""
    frame = tb[-1]
    return f" (at {module_path(frame.filename)}:{frame.lineno})"


def module_path(filename: str) -> str:
    """``filename`` as ``package/sub/module.py`` of the imported module that lives there; the
    bare file name when no imported module does (a script, generated code)."""
    target = _real(filename)
    for name, module in list(sys.modules.items()):
        path = getattr(module, "__file__", None)
        if path and _real(path) == target:
            tail = "/__init__.py" if os.path.basename(path).startswith("__init__.") else ".py"
            return name.replace(".", "/") + tail
    return os.path.basename(filename)


def _real(path: str) -> str:
    try:
        return os.path.realpath(path)
    except (OSError, ValueError):
        return path
