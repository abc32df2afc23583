"""``mpsbench bench``: particle-steps per second of solver backends, side by side.

Runs the benchmark dam break (:mod:`mpsbench.run.bench`) at each ``--n`` on each ``--solver`` and on
the reference backend, in this process, and prints a table with the speed-up over the reference
measured in the same run; ``--json`` prints the records instead.  Exit status: 0, or 2 for an
unknown or unavailable solver or a bad ``--n`` / ``--steps``.
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
    p.add_argument("--solver", action="append", default=None, metavar="NAME",
                   help="backend to time (repeatable; default: every available backend); the "
                   "reference backend is always timed too")
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


def _check_memory(n: int) -> None:
    """Refuse a size that cannot fit in this machine's memory (it would die of MemoryError
    after minutes of set-up); the workload's largest radius is r_e = 3.1 l0."""
    from mpsbench.errors import UsageError
    from mpsbench.results.guard import machine_memory
    from mpsbench.run.estimate import memory_bytes, pairs_for

    need, have = memory_bytes(n, pairs_for(n, 3.1)), machine_memory()
    if have is not None and need > have:
        raise UsageError(f"--n {n}: about {need / 2**30:.1f} GB for {n:,} particles, more than "
                         f"this machine's {have / 2**30:.1f} GB")


def cmd_bench(args: argparse.Namespace) -> int:
    from mpsbench.errors import UsageError
    from mpsbench.run.bench import MIN_N, format_table, run_bench
    from mpsbench.run.protocol import SOLVERS

    sizes = args.n or list(DEFAULT_SIZES)
    for n in sizes:
        if n < MIN_N:
            raise UsageError(f"--n {n} is not allowed: an integer >= {MIN_N}")
        _check_memory(n)
    if args.steps < 1:
        raise UsageError(f"--steps {args.steps} is not allowed: an integer >= 1")
    solvers = args.solver or _default_solvers()
    for name in solvers:
        if name not in SOLVERS:
            raise UsageError(
                f"unknown solver {name!r}; known solvers: {', '.join(SOLVERS.names())}"
            )
        SOLVERS.get(name)  # unavailable: PluginLoadError, exit 2 with the reason

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
