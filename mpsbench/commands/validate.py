"""``mpsbench validate CASE``: run a case's study at a tier and write its output folder."""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
from pathlib import Path
from typing import Any

from mpsbench.cases import CASES, TIERS, Case, get_case
from mpsbench.cli import UsageError
from mpsbench.protocol import SOLVERS
from mpsbench.reporting import check_lines, write_case_outputs
from mpsbench.study import plan, print_progress, run_tasks

ORDER = 30


def register(sub: Any) -> None:
    p = sub.add_parser(
        "validate",
        help="run a validation case (or 'all') and write results, tables, figures and a report",
        description="Run a validation case's parameter grid on one or more solvers.",
    )
    p.add_argument("case", help="case name (see 'mpsbench validate --list') or 'all'", nargs="?")
    p.add_argument("--list", action="store_true", help="list the registered cases and exit")
    p.add_argument("--solver", action="append", default=None, metavar="NAME",
                   help="solver backend (repeatable; default: reference)")
    p.add_argument("--tier", default="quick", choices=TIERS,
                   help="smoke (seconds, for CI), quick (default, minutes) or paper (full grid)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE[,VALUE...]",
                   help="override a parameter for every run; a comma list sweeps it")
    p.add_argument("--jobs", type=int, default=1, help="parallel worker processes (default 1)")
    p.add_argument("--out", default=None, help="output folder (default: reports/<case>-<tier>-<time>)")
    p.add_argument("--force", action="store_true", help="re-run runs whose record already exists")
    p.set_defaults(func=cmd_validate)


def parse_overrides(case: Case, items: list[str]) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--set {item!r}: expected KEY=VALUE")
        param = case.param(key.strip())
        out[param.name] = [param.parse(v) for v in value.split(",")]
    return out


def default_out(name: str, tier: str) -> Path:
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("reports") / f"{name}-{tier}-{stamp}"


def cmd_validate(args: argparse.Namespace) -> int:
    if args.list:
        for name in CASES.names():
            try:
                case = get_case(name)
                print(f"{name:<12} {case.title}")
            except Exception as exc:  # noqa: BLE001
                print(f"{name:<12} [unavailable] {exc}")
        return 0
    if not args.case:
        raise UsageError("give a case name or 'all' (see --list)")
    if args.jobs < 1:
        raise UsageError(f"--jobs = {args.jobs} is not allowed: an integer >= 1")
    solvers = args.solver or ["reference"]
    for s in solvers:
        SOLVERS.get(s)  # unknown or broken solver: usage error before any run
    names = CASES.names() if args.case == "all" else [args.case]
    cases = [get_case(n) for n in names]
    out = Path(args.out) if args.out else default_out(args.case, args.tier)
    failed = False
    for case in cases:
        overrides = parse_overrides(case, args.set) if args.case != "all" else {}
        tasks = plan(case, solvers, args.tier, overrides)
        case_out = out if args.case != "all" else out / case.name
        print(f"{case.name}: {len(tasks)} runs -> {case_out}", file=sys.stderr)
        records = run_tasks(tasks, case_out, jobs=args.jobs, force=args.force,
                            progress=print_progress())
        checks = write_case_outputs(case, records, case_out)
        for line in check_lines(checks):
            print(line)
        failed |= any(c.passed is False for c in checks)
        print(f"report: {os.path.join(str(case_out), 'report.md')}")
    return 1 if failed else 0
