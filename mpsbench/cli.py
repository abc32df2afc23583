"""The ``mpsbench`` command line.

Each sub-command lives in its own module under :mod:`mpsbench.commands` and defines
``register(subparsers)`` (which adds its parser and sets ``func``) and an ``ORDER`` for the help.
Modules are discovered, so adding a command touches no central list.

Exit status: 0 success, 1 a check/validation failed, 2 usage error (bad arguments or input).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

import mpsbench
from mpsbench import commands
from mpsbench.errors import MpsbenchError
from mpsbench.registry import PluginLoadError, UnknownNameError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mpsbench",
        description="Validate and benchmark MPS / WC-MPS particle solvers.",
    )
    parser.add_argument("--version", action="version", version=f"mpsbench {mpsbench.__version__}")
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
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (MpsbenchError, UnknownNameError, PluginLoadError, FileNotFoundError) as exc:
        print(f"mpsbench {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
