"""Each compiled kernel in two builds: parallel (``prange`` over threads) and serial.

``@kernel`` compiles a function with ``parallel=True`` and attaches a serial build of the same
code as its ``.serial`` attribute (:func:`pick` chooses).  The solver runs the serial builds on
one thread: no threading-layer overhead for small problems, and no OpenMP in a process that was
forked from one that used it (GNU OpenMP cannot be used after such a fork: numba then ends the
process with "fork() called from a process already using GNU OpenMP").  Worker processes of a
study pool run on one thread, so they stay clear of that.

The serial twin is a copy of the function under the name ``<name>_serial``, so that the two
builds have their own entries in numba's on-disk cache.  Both compile lazily, on first use.
"""

from __future__ import annotations

import types
from typing import Any

from numba import njit


def kernel(fn: Any) -> Any:
    """``njit(cache=True, parallel=True)(fn)`` with a serial build as ``.serial``."""
    parallel: Any = njit(cache=True, parallel=True)(fn)
    twin = types.FunctionType(
        fn.__code__, fn.__globals__, fn.__name__ + "_serial", fn.__defaults__, fn.__closure__
    )
    twin.__qualname__ = fn.__qualname__ + "_serial"
    twin.__module__ = fn.__module__
    twin.__doc__ = fn.__doc__
    parallel.serial = njit(cache=True)(twin)
    return parallel


def pick(fn: Any, serial: bool) -> Any:
    """The serial build of a :func:`kernel` when ``serial``, else the parallel one."""
    return fn.serial if serial else fn
