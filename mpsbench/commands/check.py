"""``mpsbench check NAME``: run the conformance kit (:mod:`mpsbench.testing`) on a solver.

One line per check (PASS / FAIL reason / SKIP reason / XFAIL reason / XPASS), then a summary.
With ``--against OTHER``, also the same short problems on both solvers
(:mod:`mpsbench.testing.agreement`): one line per problem with the largest differences.
Exit status: 0 when no check failed (and every problem agrees within ``--tolerance``), 1 when
one did, 2 for an unknown solver name.
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
    p.add_argument("--against", metavar="SPEC", default=None,
                   help="also run the kit's short problems on this solver (e.g. reference) and "
                   "report the largest differences, particle by particle")
    p.add_argument("--tolerance", type=float, default=None, metavar="X",
                   help="with --against: the largest relative difference that agrees "
                   "(default 1e-6)")
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
    against = None
    if args.against is not None:
        if args.against.partition(":")[0] not in SOLVERS:
            raise UsageError(f"--against: unknown solver {args.against!r}; known solvers: "
                             f"{', '.join(SOLVERS.names())}")
        against = solver_spec(args.against).text
    elif args.tolerance is not None:
        raise UsageError("--tolerance goes with --against")
    if args.tolerance is not None and not args.tolerance >= 0:
        raise UsageError(f"--tolerance {args.tolerance!r} is not allowed: a number >= 0")

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
    if not args.json:
        total = sum(r.seconds for r in results)
        summary = ", ".join(f"{v} {k}" for k, v in counts.items() if v)
        print(f"{name}: {summary} in {total:.2f} s")
    agreement = None
    if against is not None:
        agreement = _agreement(name, against, args)
        failed |= not agreement["ok"]
    if args.json:
        out: dict[str, Any] = {
            "solver": name,
            "ok": not failed,
            "counts": counts,
            "results": [r.as_dict() for r in results],
        }
        if agreement is not None:
            out["against"] = agreement
        json.dump(out, sys.stdout, indent=2, default=str)
        print()
    return 1 if failed else 0


def _agreement(name: str, against: str, args: argparse.Namespace) -> dict[str, Any]:
    import math

    from mpsbench.testing.agreement import TOLERANCE, Difference, compare_solvers

    tol = TOLERANCE if args.tolerance is None else args.tolerance

    def show(d: Difference) -> None:
        if args.json:
            return
        verdict = {True: "AGREE", False: "DIFFER", None: "SKIP"}[d.agrees(tol)]
        if d.skipped:
            print(f"{verdict:<6} {d.problem}: {d.skipped}", flush=True)
            return
        extra = f" ({d.note})" if d.note else ""
        print(f"{verdict:<6} {d.problem}: {d.steps} steps, position {d.position:.3g} l0, "
              f"velocity {d.velocity:.3g}, pressure {d.pressure:.3g}{extra}", flush=True)

    if not args.json:
        print(f"{name} against {against} (largest differences after the same fixed steps; "
              f"relative, tolerance {tol:g}):")
    diffs = compare_solvers(name, against, progress=show)
    bad = [d for d in diffs if d.agrees(tol) is False]
    compared = [d for d in diffs if not d.skipped]
    worst = max((d.worst() for d in compared), default=math.nan)
    if not args.json:
        print(f"{name} against {against}: {len(compared) - len(bad)} of {len(compared)} "
              f"problems agree within {tol:g} (largest difference {worst:.3g}); "
              f"{len(diffs) - len(compared)} not comparable")
    return {"against": against, "tolerance": tol, "ok": not bad,
            "problems": [d.as_dict() for d in diffs]}
