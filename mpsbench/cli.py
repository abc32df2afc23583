"""The ``mpsbench`` command line.

Each sub-command lives in its own module under :mod:`mpsbench.commands` and defines
``register(subparsers)`` (which adds its parser and sets ``func``) and an ``ORDER`` for the help.
Modules are discovered, so adding a command touches no central list.

Exit status: 0 success, 1 a check/validation failed, 2 an error of input or environment (bad
arguments, a file that cannot be read or is not allowed, an output folder that cannot be written
or is in use, too little memory), 3 an internal error (a bug).  Errors are one line on stderr;
the global ``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

import mpsbench
from mpsbench import commands
from mpsbench.errors import MpsbenchError, where


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mpsbench",
        description="Validate and benchmark MPS / WC-MPS particle solvers.",
    )
    parser.add_argument("--version", action="version", version=f"mpsbench {mpsbench.__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an error instead of its one-line message")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = []
    for info in pkgutil.iter_modules(commands.__path__):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(module, "register"):
            modules.append(module)
    for module in sorted(modules, key=lambda m: (getattr(m, "ORDER", 100), m.__name__)):
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    # --debug is global but accepted anywhere on the line (before a '--')
    cut = argv.index("--") if "--" in argv else len(argv)
    debug = "--debug" in argv[:cut]
    argv = [a for a in argv[:cut] if a != "--debug"] + argv[cut:]
    args = parser.parse_args(argv)
    args.debug = debug
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - every error is one line unless --debug
        if args.debug:
            raise
        status, text = describe(exc)
        if not isinstance(exc, MpsbenchError):  # (a study file's problems are one per line)
            text = " ".join(text.split())
        print(f"mpsbench {args.command}: error: {text}", file=sys.stderr)
        return status


def describe(exc: BaseException) -> tuple[int, str]:
    """Exit status and one-line message for an error that ended a command."""
    if isinstance(exc, MpsbenchError):
        return 2, str(exc)
    if isinstance(exc, MemoryError):
        return 2, ("out of memory" + (f": {exc}" if str(exc) else "")
                   + "; use a coarser spacing or fewer --jobs")
    if isinstance(exc, UnicodeError):
        return 2, f"not valid text: {exc}"
    if isinstance(exc, OSError):
        name = f" {exc.filename}" if exc.filename else ""
        return 2, f"cannot access{name}: {exc.strerror or exc}"
    return 3, (f"internal error: {type(exc).__name__}: {exc}{where(exc)}; run with --debug for "
               "the traceback")


if __name__ == "__main__":
    sys.exit(main())
