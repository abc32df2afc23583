"""How the backend compiles: kernels in two builds, kernel factories per model, a disk cache whose
key is what the code depends on.

``@kernel`` compiles a function with ``parallel=True`` and attaches a serial build of the same
code as its ``.serial`` attribute (:func:`pick` chooses).  The solver runs the serial builds on
one thread: no threading-layer overhead for small problems, and no OpenMP in a process that was
forked from one that used it (GNU OpenMP cannot be used after such a fork: numba then ends the
process with "fork() called from a process already using GNU OpenMP").  Worker processes of a
study pool run on one thread, so they stay clear of that.  The serial twin is a copy of the
function under the name ``<name>_serial``, so the two builds have their own cache entries.  Both
compile lazily, on first use.

``@factory`` makes a kernel factory: a function of compiled models (:mod:`.formulas`) that
returns a Python function closing over the models' compiled formulas; the factory compiles it
with ``@kernel`` once per distinct models (memoised), so a kernel is built only for the models a
run uses and calls their formulas directly (numba inlines them).  No model is named in a kernel.

The disk cache (``__pycache__`` next to the sources, or ``NUMBA_CACHE_DIR``): numba's own key is
the function's bytecode and, for a closure, a pickle of the closure cells, and a pickled
dispatcher carries a per-process random id, so closures over compiled functions would never
hit the cache; numba also misses edits to the functions a kernel calls when they live in another
file.  :class:`_FingerprintCache` keys each entry by :func:`fingerprint` instead: the bytecode and
constants of the kernel, of its closure cells and of every function or dispatcher it names,
recursively (a plugin's formula included).  Any edit to any of them compiles anew.
"""

from __future__ import annotations

import hashlib
import sys
import time
import types
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from numba import njit
from numba.core import event
from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher

_CACHE_VERSION = "mpsbench-kernels-2"

FLAGS: dict[str, Any] = {
    "fastmath": {"arcp", "contract", "nsz"},
    "error_model": "numpy",
}
"""The floating-point contract of every model kernel: ``contract`` fuses multiply-adds,
``arcp`` turns a division by a loop invariant (``r / re``) into a multiplication by its
reciprocal; ``error_model="numpy"`` drops the zero-division checks that keep a loop scalar (a
coincident pair's 1/r is inf, and the closed support selects 0.0 for it).  NaN and inf keep
their meaning (no ``nnan``/``ninf``): the health checks, the free-surface test and the rebuild
test rely on them.  Results differ from strict IEEE order in the last bits; the serial and the
parallel build of a kernel compile the same loop and agree bit for bit
(tests/test_numba_agreement.py holds 1 against 2 threads).

Without ``reassoc`` a neighbour sum keeps its order, so its loop stays scalar: each neighbour's
coordinates are two plain loads.  :data:`VECTOR_FLAGS` adds ``reassoc``: LLVM then splits the
sums into vector lanes and loads the neighbours with gather instructions.  The solver builds
with :data:`VECTOR_FLAGS` unless its option ``vectorize`` is false (:func:`set_vectorized`).
Whether the vector loops pay depends on the processor's gathers: an earlier machine of this
project measured them 1.3-1.6x faster, the machine of 2026-12-07 0.65-0.74x the scalar ones
(docs/performance.md); ``mpsbench bench --solver numba --solver numba:vectorize=false``
measures it on yours."""

VECTOR_FLAGS: dict[str, Any] = {
    "fastmath": FLAGS["fastmath"] | {"reassoc"},
    "error_model": "numpy",
}
""":data:`FLAGS` with ``reassoc``: the model kernels' neighbour sums vectorise (gathers).

Only the model kernels (:func:`factory`) take these flags.  The neighbour-list build, the
geometry and the other helpers (:func:`kernel`, :func:`compiled` used directly) compile with
:data:`STRICT`: a pair on the edge of the cut-off is in or out of the list exactly as in the
reference's pair search, and a separation is the same bits as ``Box.minimum_image``."""

STRICT: dict[str, Any] = {"error_model": "numpy"}


def kernel(fn: Any, fast: bool = False, vector: bool = False) -> Any:
    """``njit(parallel=True)(fn)``, disk-cached, with a serial build as ``.serial``; compiled
    with :data:`FLAGS` when ``fast`` (:data:`VECTOR_FLAGS` when ``vector`` too), else
    :data:`STRICT`."""
    flags = (VECTOR_FLAGS if vector else FLAGS) if fast else STRICT
    parallel: Any = cached(njit(parallel=True, **flags)(fn))
    twin = types.FunctionType(
        fn.__code__, fn.__globals__, fn.__name__ + "_serial", fn.__defaults__, fn.__closure__
    )
    twin.__qualname__ = fn.__qualname__ + "_serial"
    twin.__module__ = fn.__module__
    twin.__doc__ = fn.__doc__
    parallel.serial = cached(njit(**flags)(twin))
    return parallel


def compiled(fn: Any) -> Any:
    """``njit(fn)``, disk-cached (a helper that is not a kernel: no parallel build)."""
    return cached(njit(**STRICT)(fn))


def pick(fn: Any, serial: bool) -> Any:
    """The serial build of a :func:`kernel` when ``serial``, else the parallel one."""
    return fn.serial if serial else fn


_vector = False  # the flags factories build with now (:func:`set_vectorized`; the solver sets them)


def set_vectorized(on: bool) -> bool:
    """Make :func:`factory` kernels the builds with :data:`VECTOR_FLAGS` (``on``) or
    :data:`FLAGS` from now on; returns the setting before (for the caller to restore)."""
    global _vector
    before, _vector = _vector, bool(on)
    return before


@contextmanager
def vectorized(on: bool) -> Iterator[None]:
    """Inside the block, :func:`factory` kernels are the builds with :data:`VECTOR_FLAGS`
    (``on``) or :data:`FLAGS`; the caller's setting is restored after it."""
    before = set_vectorized(on)
    try:
        yield
    finally:
        set_vectorized(before)


def factory(build: Callable[..., Any]) -> Callable[..., Any]:
    """A memoised kernel factory: ``build(*models)`` returns the Python function of a kernel
    (closing over compiled formulas); the result is ``kernel(...)`` of it, once per arguments
    and flag set (:func:`set_vectorized`)."""
    made: dict[tuple[Any, ...], Any] = {}

    def get(*models: Any) -> Any:
        key = (*models, _vector)
        if key not in made:
            made[key] = kernel(build(*models), fast=True, vector=_vector)
        return made[key]

    get.__name__ = build.__name__
    get.__qualname__ = build.__qualname__
    get.__doc__ = build.__doc__
    get.__wrapped__ = build  # type: ignore[attr-defined]
    return get


# --------------------------------------------------------------------------- compile time


class CompileWatch(event.Listener):
    """Counts and times numba's compilations while installed (:func:`watch_compiles`).  A
    kernel loaded from the disk cache is not a compilation; the functions a kernel calls are
    compiled inside its compilation (nested events) and counted with it."""

    def __init__(self) -> None:
        self.kernels = 0
        self.seconds = 0.0
        self.each: dict[str, float] = {}  # kernel name -> seconds
        self._depth = 0
        self._t0 = 0.0

    def on_start(self, ev: Any) -> None:
        if self._depth == 0:
            if self.kernels == 0:
                announce()
            self._t0 = time.perf_counter()
        self._depth += 1

    def on_end(self, ev: Any) -> None:
        self._depth -= 1
        if self._depth == 0:
            took = time.perf_counter() - self._t0
            self.kernels += 1
            self.seconds += took
            disp = (ev.data or {}).get("dispatcher")
            name = getattr(getattr(disp, "py_func", None), "__qualname__", "?")
            self.each[name] = self.each.get(name, 0.0) + took


_announced = False


def announce() -> None:
    """Say, once per process, that kernels are being compiled (a cold cache: several seconds)."""
    global _announced
    if not _announced:
        _announced = True
        print("numba: compiling the kernels this run needs (first use of these models; later "
              "runs load them from the disk cache) ...", file=sys.stderr, flush=True)


_reported = False


def report(kernels: int, seconds: float) -> None:
    """After the announcement: how many kernels took how long (once per process)."""
    global _reported
    if _announced and not _reported and kernels:
        _reported = True
        print(f"numba: compiled {kernels} kernels in {seconds:.1f} s", file=sys.stderr,
              flush=True)


@contextmanager
def watch_compiles() -> Iterator[CompileWatch]:
    """Count and time the compilations inside the block."""
    watch = CompileWatch()
    with event.install_listener("numba:compile", watch):
        yield watch


# --------------------------------------------------------------------------- the disk cache


class _FingerprintCache(FunctionCache):
    """numba's function cache with :func:`fingerprint` as the index key (module docstring)."""

    def __init__(self, py_func: Any, options: str = "") -> None:
        super().__init__(py_func)
        self._digest: str | None = None
        self._options = options  # the dispatcher's own flags (fastmath or strict) are in the key

    def _index_key(self, sig: Any, codegen: Any) -> Any:
        if self._digest is None:
            self._digest = fingerprint(self._py_func)
        return (sig, codegen.magic_tuple(), (_CACHE_VERSION, self._options, self._digest))


def cached(disp: Any) -> Any:
    """Turn on the fingerprint-keyed disk cache of a dispatcher (none where numba has no place
    for it, e.g. a function defined outside a source file)."""
    try:
        disp._cache = _FingerprintCache(disp.py_func, _options(disp))
    except RuntimeError:  # "cannot cache function ...: no locator available"
        pass
    return disp


def _options(disp: Dispatcher) -> str:
    """The target options of a dispatcher in a fixed order (sets sorted: their repr follows the
    per-process hash seed)."""
    return repr([(k, sorted(v) if isinstance(v, (set, frozenset)) else v)
                 for k, v in sorted(disp.targetoptions.items())])


def fingerprint(fn: Any) -> str:
    """A digest of everything the compiled code of ``fn`` depends on (module docstring)."""
    parts: list[str] = []
    _describe(fn, set(), parts)
    return hashlib.sha256("\x00".join(parts).encode()).hexdigest()


_PLAIN = (bool, int, float, complex, str, bytes, type(None))


def _describe(obj: Any, seen: set[int], out: list[str]) -> None:
    if isinstance(obj, Dispatcher):
        out.append(f"dispatcher {_options(obj)}")
        obj = obj.py_func
    if isinstance(obj, types.FunctionType):
        if id(obj) in seen:
            out.append(f"again {obj.__module__}.{obj.__qualname__}")
            return
        seen.add(id(obj))
        out.append(f"function {obj.__module__}.{obj.__qualname__}")
        names = _code(obj.__code__, out)
        for cell in obj.__closure__ or ():
            _describe(cell.cell_contents, seen, out)
        for name in sorted(names):
            if name in obj.__globals__:
                out.append(f"global {name}")
                _describe(obj.__globals__[name], seen, out)
    elif isinstance(obj, _PLAIN):
        out.append(repr(obj))
    elif isinstance(obj, (tuple, list)):
        out.append(f"{type(obj).__name__} {len(obj)}")
        for item in obj:
            _describe(item, seen, out)
    elif isinstance(obj, np.ndarray):
        out.append(f"array {obj.dtype} {obj.shape} {hashlib.sha256(obj.tobytes()).hexdigest()}")
    elif isinstance(obj, types.ModuleType):
        out.append(f"module {obj.__name__}")
    else:  # classes, ufuncs, numba types: their identity
        out.append(f"object {type(obj).__module__}.{type(obj).__qualname__} "
                   f"{getattr(obj, '__qualname__', getattr(obj, '__name__', ''))}")


def _code(code: types.CodeType, out: list[str]) -> set[str]:
    """Describe a code object; return the global (and attribute) names it uses."""
    out.append(code.co_code.hex())
    out.append(repr((code.co_names, code.co_varnames, code.co_freevars)))
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code(const, out)
        else:
            out.append(repr(const))
    return names
