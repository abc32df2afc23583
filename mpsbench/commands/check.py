"""``mpsbench check NAME``: run the conformance kit (:mod:`mpsbench.testing`) on a solver.

One line per check (PASS / FAIL reason / SKIP reason / XFAIL reason / XPASS), then a summary.
Exit status: 0 when no check failed, 1 when one did, 2 for an unknown solver name.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

ORDER = 30


def register(sub: Any) -> None:
    p = sub.add_parser(
        "check",
        help="run the conformance checks on a solver backend",
        description="Run the conformance kit on a registered solver backend (see "
        "'mpsbench solvers'): API shape, declared capabilities, determinism, conservation, "
        "divergence reporting.",
    )
    p.add_argument("solver", metavar="SPEC",
                   help="registered solver name, e.g. reference, or NAME:key=value,... with "
                   "options, e.g. numba:threads=1")
    p.add_argument("--json", action="store_true", help="print JSON instead of lines")
    p.add_argument(
        "-k",
        dest="select",
        action="append",
        metavar="TEXT",
        help="only the check named TEXT, or checks whose name contains TEXT (repeatable)",
    )
    p.set_defaults(func=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    from mpsbench.errors import UsageError
    from mpsbench.run.protocol import SOLVERS
    from mpsbench.run.specs import solver_spec
    from mpsbench.testing import ConformanceResult, check_solver, select_checks

    spec = args.solver
    if spec.partition(":")[0] not in SOLVERS:
        raise UsageError(
            f"unknown solver {spec!r}; known solvers: {', '.join(SOLVERS.names()) or '(none)'}"
        )
    # an unavailable backend (PluginLoadError) or a bad option (ConfigError): exit 2
    name = solver_spec(spec).text
    if args.select and not select_checks(args.select):
        raise UsageError(f"no check name contains {' or '.join(map(repr, args.select))}")

    def show(r: ConformanceResult) -> None:
        label = r.outcome.upper()
        text = f"{label:<5} {r.check}"
        if r.reason:
            text += f": {r.reason}"
        print(text, flush=True)

    results = check_solver(
        name, checks=args.select, on_fail="return", callback=None if args.json else show
    )
    counts = {
        k: sum(r.outcome == k for r in results) for k in ("pass", "fail", "skip", "xfail", "xpass")
    }
    failed = counts["fail"] > 0
    if args.json:
        json.dump(
            {
                "solver": name,
                "ok": not failed,
                "counts": counts,
                "results": [r.as_dict() for r in results],
            },
            sys.stdout,
            indent=2,
        )
        print()
    else:
        total = sum(r.seconds for r in results)
        summary = ", ".join(f"{v} {k}" for k, v in counts.items() if v)
        print(f"{name}: {summary} in {total:.2f} s")
    return 1 if failed else 0
