"""``mpsbench bench``: particle-steps per second of solver backends, side by side.

Runs the benchmark dam break (:mod:`mpsbench.testing.bench`) at each ``--n`` on each ``--solver``
(and PySPH's WCSPH with ``--pysph``) in this process, interleaved block by block, and prints
the median and spread of each one's particle-steps/s with the ratio to the first solver
measured in the same rounds; ``--json`` prints the records with the environment instead.
``--save`` adds the run to the history, ``--compare`` holds it against a saved run
(:mod:`mpsbench.results.bench_history`).

Exit status: 0; 1 when ``--compare`` finds a slowdown; 2 for an unknown or unavailable solver,
a bad ``--n`` / ``--steps`` / ``--budget`` / ``--repeat`` / ``--threshold``, ``--pysph``
without PySPH, or ``--compare`` without a saved run to compare with.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mpsbench.errors import UsageError

ORDER = 35
# the defaults live with the code they describe; the help text quotes the same numbers
DEFAULT_SIZES = (10_000, 40_000)  # = mpsbench.testing.bench.DEFAULT_SIZES (test_bench_cli checks)
DEFAULT_BUDGET_S = 20.0  # = mpsbench.testing.bench.DEFAULT_BUDGET_S
DEFAULT_STEPS = 20  # = mpsbench.testing.bench.DEFAULT_STEPS
BLOCK_S = 0.25  # = mpsbench.testing.bench.BLOCK_S


def register(sub: Any) -> None:
    p = sub.add_parser(
        "bench",
        help="time solver backends on a WC-MPS dam break (particle-steps per second)",
        description="Time backends on the benchmark dam break (WF2, PGM1, xu-jin, r_e = 2.1/3.1 "
        "l0, stabilization, a sheared start so the neighbour list is rebuilt as in a real run). "
        "After a cold start (JIT) that is freed and a warm-up, the solvers take turns block by "
        "block (A B A B ...) until the time budget or --repeat rounds; the table gives the "
        "median particle-steps/s with its quartiles, and the median over rounds of the ratio "
        "to the first solver with its min-max. Exit status: 0; 1 --compare found a slowdown; "
        "2 usage error.",
    )
    p.add_argument("--solver", action="append", default=None, metavar="SPEC",
                   help="backend to time, NAME or NAME:key=value,... (repeatable; the first is "
                   "the one ratios are to; default: every available backend, reference first, "
                   "but the implicit one)")
    p.add_argument("--n", action="append", type=int, default=None, metavar="N",
                   help="approximate particle count (repeatable; default: "
                   + ", ".join(str(n) for n in DEFAULT_SIZES) + ")")
    p.add_argument("--steps", type=int, default=None,
                   help="consecutive steps per block (default: per size, enough for the fastest "
                   f"solver's block to last {BLOCK_S:g} s by its warm-up steps, at least "
                   f"{DEFAULT_STEPS}; shorter blocks scatter more)")
    p.add_argument("--budget", type=float, default=DEFAULT_BUDGET_S, metavar="SECONDS",
                   help="repeat rounds until the timed blocks of a size have taken this long in "
                   f"all (at least 5 rounds; default {DEFAULT_BUDGET_S:g})")
    p.add_argument("--repeat", type=int, default=None, metavar="K",
                   help="exactly K rounds per size (instead of --budget)")
    p.add_argument("--pysph", action="store_true",
                   help="also time PySPH's WCSPH (its dam_break_2d scheme) on the same particles "
                   "(needs PySPH)")
    p.add_argument("--pysph-threads", type=int, default=None, metavar="K",
                   help="OpenMP threads of PySPH (default: the CPUs available; 0: serial build)")
    p.add_argument("--json", action="store_true",
                   help="print the records and the environment as JSON")
    p.add_argument("--save", action="store_true",
                   help="add this run to the history in --storage")
    p.add_argument("--compare", nargs="?", const="latest", default=None, metavar="RUN",
                   help="compare with a saved run: a file, a run number, or (no value) the "
                   "latest saved on this machine; exit 1 on a slowdown")
    p.add_argument("--storage", default=None, metavar="DIR",
                   help="history folder (default .benchmarks, pytest-benchmark's too)")
    p.add_argument("--threshold", type=float, default=None, metavar="FRACTION",
                   help="--compare: a median this much lower (default 0.1) with interquartile "
                   "ranges apart is a slowdown")
    p.set_defaults(func=cmd_bench)


def _default_solvers() -> list[str]:
    """Every available backend that can run the bench's workload (an outside code without
    stabilization, such as PySPH or an external program, is timed with --pysph or by name)."""
    from mpsbench.run.protocol import SOLVERS, Capabilities
    from mpsbench.testing.problems import dam_break_problem

    workload = dam_break_problem(l0=0.05, stabilization=True)
    out = []
    for name in SOLVERS.names():
        try:
            cls = SOLVERS.get(name)
        except Exception:  # noqa: BLE001 - an unavailable backend is simply not timed
            continue
        if getattr(cls, "capabilities", Capabilities()).gaps(workload):
            continue
        # a backend may leave the default set (the semi-implicit one: a 40k step takes seconds,
        # far beyond the default budget); --solver still times it
        if getattr(cls, "bench_default", True):
            out.append(name)
    return sorted(out, key=lambda name: name != "reference")  # ratios to the reference


def _check_memory(n: int) -> None:
    """Refuse a size that cannot fit in this machine's memory (it would die of MemoryError
    after minutes of set-up); the workload's largest radius is r_e = 3.1 l0."""
    from mpsbench.results.guard import machine_memory
    from mpsbench.run.estimate import memory_bytes, pairs_for

    need, have = memory_bytes(n, pairs_for(n, 3.1)), machine_memory()
    if have is not None and need > have:
        raise UsageError(f"--n {n}: about {need / 2**30:.1f} GB for {n:,} particles, more than "
                         f"this machine's {have / 2**30:.1f} GB")


def _check(args: argparse.Namespace) -> None:
    from mpsbench.testing.bench import MIN_N

    for n in args.n or []:
        if n < MIN_N:
            raise UsageError(f"--n {n} is not allowed: an integer >= {MIN_N}")
        _check_memory(n)
    if args.steps is not None and args.steps < 1:
        raise UsageError(f"--steps {args.steps} is not allowed: an integer >= 1")
    if not args.budget > 0:
        raise UsageError(f"--budget {args.budget} is not allowed: a number of seconds > 0")
    if args.repeat is not None and args.repeat < 1:
        raise UsageError(f"--repeat {args.repeat} is not allowed: an integer >= 1")
    if args.threshold is not None and not 0 <= args.threshold < 1:
        raise UsageError(f"--threshold {args.threshold} is not allowed: a fraction in [0, 1)")
    if args.pysph_threads is not None and args.pysph_threads < 0:
        raise UsageError(f"--pysph-threads {args.pysph_threads} is not allowed: 0 (serial) "
                         "or more")
    if args.pysph_threads is not None and not args.pysph:
        raise UsageError("--pysph-threads goes with --pysph")


def _contenders(args: argparse.Namespace) -> list[Any]:
    from mpsbench.testing.bench import Contender, solver_contender

    # unknown (exit 2, "unknown solver ...") or unavailable backends fail here, before any run
    contenders = [solver_contender(name)
                  for name in dict.fromkeys(args.solver or _default_solvers())]
    if args.pysph:
        from mpsbench.testing.bench_pysph import NAME, PySPHWCSPH, pysph_missing

        missing = pysph_missing()
        if missing:
            raise UsageError(f"--pysph: {missing}")
        threads = args.pysph_threads
        contenders.append(Contender(NAME, lambda: PySPHWCSPH(threads), "pysph"))
    return contenders


def cmd_bench(args: argparse.Namespace) -> int:
    _check(args)
    from mpsbench.results import bench_history as history
    from mpsbench.results.provenance import code_commit
    from mpsbench.results.records import environment
    from mpsbench.testing.bench import format_table, run_bench

    storage = Path(args.storage) if args.storage else history.DEFAULT_STORAGE
    saved = None
    if args.compare is not None:  # before anything runs: a missing history is a usage error
        try:
            saved = history.load(None if args.compare == "latest" else args.compare, storage)
        except history.HistoryError as exc:
            raise UsageError(str(exc)) from None
    contenders = _contenders(args)
    sizes = args.n or list(DEFAULT_SIZES)

    def progress(text: str) -> None:
        if not args.json:
            print(text, file=sys.stderr, flush=True)

    records = run_bench(contenders, sizes, steps=args.steps, budget=args.budget,
                        repeat=args.repeat, progress=progress)
    for rec in records:
        rec.solver_commit = code_commit(rec.code_module) if rec.code_module else None
    doc = {
        "environment": environment([c.label for c in contenders if c.code_module != "pysph"]),
        "settings": {"sizes": sizes, "steps": args.steps, "budget_s": args.budget,
                     "repeat": args.repeat, "solvers": [c.label for c in contenders],
                     "command": " ".join(["mpsbench", *sys.argv[1:]])},
        "records": [r.as_dict() for r in records],
    }
    status = 0
    if args.json:
        json.dump(doc, sys.stdout, indent=2)
        print()
    else:
        print(format_table(records))
        print("Mpart-steps/s: median over blocks, wall clock, neighbour rebuilds included, "
              "[quartiles]; speed-up: median over rounds of the ratio to the first solver "
              "[min-max]; to t: the same for the wall time to reach the same simulated time; "
              "per CPU-s: process CPU time (all threads); load: 1-minute load average at the "
              "start and end of the size")
    if saved is not None:
        path, base = saved
        threshold = history.DEFAULT_THRESHOLD if args.threshold is None else args.threshold
        try:
            rows = history.compare(base, doc, threshold)
        except history.HistoryError as exc:
            raise UsageError(str(exc)) from None
        slow = [r for r in rows if r.slowdown]
        out = sys.stderr if args.json else sys.stdout
        print(f"\ncompared with {path} (load {_loads(base)} then, {_loads(doc)} now):", file=out)
        print(history.format_rows(rows), file=out)
        if slow:
            print(f"SLOWER: {len(slow)} figure(s) more than {threshold:.0%} below the saved run "
                  "with interquartile ranges apart", file=out)
            status = 1
        else:
            print(f"OK: no figure more than {threshold:.0%} below the saved run beyond the "
                  "spread", file=out)
    if args.save:
        path = history.save(doc, storage)
        print(f"saved: {path}", file=sys.stderr if args.json else sys.stdout)
    return status


def _loads(doc: dict[str, Any]) -> str:
    loads = [r.get("load_avg") for r in doc.get("records", []) if r.get("load_avg") is not None]
    return "-" if not loads else f"{min(loads):.1f}-{max(loads):.1f}"
