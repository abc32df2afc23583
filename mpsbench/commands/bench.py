"""``mpsbench bench``: particle-steps per second of solver backends, side by side.

Runs the benchmark dam break (:mod:`mpsbench.testing.bench`) at each ``--n`` on each ``--solver``
and on the reference backend, in this process, and prints a table with the speed-up over the
reference measured in the same run; ``--json`` prints the records instead.  Exit status: 0, or 2
for an unknown or unavailable solver, a bad option or a bad ``--n`` / ``--steps``.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

ORDER = 35
DEFAULT_SIZES = (10_000, 40_000)


def register(sub: Any) -> None:
    p = sub.add_parser(
        "bench",
        help="time solver backends on a WC-MPS dam break (particle-steps per second)",
        description="Time backends on the benchmark dam break (WF2, PGM1, xu-jin, r_e = 2.1/3.1 "
        "l0, stabilization, a sheared start so the neighbour list is rebuilt as in a real run): "
        "wall and CPU time per step with rebuilds included, one rebuild alone, the JIT compile "
        "cost of the first call, and the speed-up over the reference backend measured in the "
        "same run.",
    )
    p.add_argument("--solver", action="append", default=None, metavar="SPEC",
                   help="backend to time, NAME or NAME:key=value,... (repeatable; default: every "
                   "available backend); the reference backend is always timed too")
    p.add_argument("--n", action="append", type=int, default=None, metavar="N",
                   help="approximate particle count (repeatable; default: "
                   + ", ".join(str(n) for n in DEFAULT_SIZES) + ")")
    p.add_argument("--steps", type=int, default=20,
                   help="consecutive steps timed per backend and size (default 20)")
    p.add_argument("--json", action="store_true", help="print the records as a JSON list")
    p.set_defaults(func=cmd_bench)


def _default_solvers() -> list[str]:
    from mpsbench.run.protocol import SOLVERS

    out = []
    for name in SOLVERS.names():
        try:
            SOLVERS.get(name)
        except Exception:  # noqa: BLE001 - an unavailable backend is simply not timed
            continue
        out.append(name)
    return out


def cmd_bench(args: argparse.Namespace) -> int:
    from mpsbench.errors import UsageError
    from mpsbench.run.protocol import SOLVERS
    from mpsbench.run.specs import solver_spec
    from mpsbench.testing.bench import MIN_N, format_table, run_bench

    sizes = args.n or list(DEFAULT_SIZES)
    for n in sizes:
        if n < MIN_N:
            raise UsageError(f"--n {n} is not allowed: an integer >= {MIN_N}")
    if args.steps < 1:
        raise UsageError(f"--steps {args.steps} is not allowed: an integer >= 1")
    solvers = args.solver or _default_solvers()
    for spec in solvers:
        name = spec.partition(":")[0]
        if name not in SOLVERS:
            raise UsageError(
                f"unknown solver {name!r}; known solvers: {', '.join(SOLVERS.names())}"
            )
        solver_spec(spec)  # unavailable: PluginLoadError; bad option: ConfigError (exit 2)

    def progress(text: str) -> None:
        if not args.json:
            print(text, file=sys.stderr, flush=True)

    records = run_bench(solvers, sizes, steps=args.steps, progress=progress)
    if args.json:
        json.dump([r.as_dict() for r in records], sys.stdout, indent=2)
        print()
    else:
        print(format_table(records))
        print("step ms and Mpart-steps/s: wall clock, neighbour rebuilds included; CPU ms: "
              "process CPU time per step (all threads); load: 1-minute load average")
    return 0
