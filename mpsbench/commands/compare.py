"""``mpsbench compare BASELINE CURRENT``: hold a run's metrics against a baseline run.

Prints what got better, worse, appeared or vanished and writes the same as Markdown (for a pull
request).  Exit status: 0 no regression, 1 a regression beyond a metric's tolerance, 2 a baseline
or current set that cannot be read or has no record in common with the other.

For CI: ``--json`` prints the comparison as JSON instead (:mod:`mpsbench.results.compare_json`),
and with ``$GITHUB_STEP_SUMMARY`` set the Markdown is appended to the job summary.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path
from typing import Any

from mpsbench.errors import UsageError

ORDER = 40


def register(sub: Any) -> None:
    p = sub.add_parser(
        "compare",
        help="compare a run's metrics against a baseline run; exit 1 on a regression",
        description="Match the records of CURRENT to those of BASELINE by case, solver and "
        "parameters and hold every metric against its tolerance (declared by the case; error-like "
        "metrics: lower is better, rtol 0.05; timings are shown, never a regression). "
        "BASELINE and CURRENT are results folders or results.json / results.csv files. "
        "Exit status: 0 no regression, 1 regression, 2 unreadable or mismatched input.",
    )
    p.add_argument("baseline", help="baseline results folder or results.json / results.csv")
    p.add_argument("current", help="current results folder or results.json / results.csv")
    p.add_argument("--rtol", type=float, default=None,
                   help="relative tolerance for every gated metric (overrides the cases' own)")
    p.add_argument("--atol", type=float, default=None,
                   help="absolute tolerance added to every metric's (default 1e-12)")
    p.add_argument("--markdown", default=None, metavar="PATH",
                   help="where to write the Markdown table (default: compare.md in CURRENT's "
                   "folder; '-' to skip)")
    p.add_argument("--json", action="store_true",
                   help="print the comparison as JSON (schema mpsbench.compare/1, docs/ci.md) on "
                   "stdout; the text report goes to stderr")
    p.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:
    if not args.json:
        return _compare(args)[0]
    # stdout carries the JSON document only, so it can be redirected to a file
    with contextlib.redirect_stdout(sys.stderr):
        status, doc = _compare(args)
    print(json.dumps(doc, indent=1))
    return status


def _compare(args: argparse.Namespace) -> tuple[int, dict[str, Any]]:
    """Compare, print the text report, write the Markdown; return (exit status, JSON document)."""
    # imported here, not at the top: pandas would slow down 'mpsbench --help'
    from mpsbench.results.compare import (
        CompareError,
        changes_frame,
        compare,
        fmt_value,
        load_results,
        render_markdown,
        summary_line,
    )
    from mpsbench.results.compare_json import comparison_to_json
    from mpsbench.results.records import atomic_write_text
    from mpsbench.results.step_summary import append_step_summary

    for name in ("rtol", "atol"):
        value = getattr(args, name)
        if value is not None and not value >= 0:
            raise UsageError(f"--{name} = {value} is not allowed: a number >= 0")
    try:
        base = load_results(args.baseline)
        cur = load_results(args.current)
        result = compare(base, cur, rtol=args.rtol, atol=args.atol)
    except CompareError as exc:
        raise UsageError(str(exc)) from None
    print(f"baseline: {args.baseline}\ncurrent:  {args.current}")
    print(summary_line(result))
    df = changes_frame(result)
    if not df.empty:
        print()
        print(df.to_markdown(index=False))
    if not result.timing.empty:
        print("\ntiming (informational):")
        print(result.timing.to_markdown(index=False, floatfmt=".4g"))
    md = render_markdown(result, args.baseline, args.current, (base[0], cur[0]))
    append_step_summary(md)
    doc = comparison_to_json(result, args.baseline, args.current, meta=(base[0], cur[0]),
                             rtol=args.rtol, atol=args.atol)
    if args.markdown != "-":
        cur_path = Path(args.current)
        target = Path(args.markdown) if args.markdown else (
            (cur_path if cur_path.is_dir() else cur_path.parent) / "compare.md")
        try:
            atomic_write_text(target, md)
            print(f"\nmarkdown: {target}")
        except OSError as exc:
            raise UsageError(f"--markdown {target}: cannot write: {exc.strerror or exc}"
                             ) from None
    if result.regressions:
        print(f"\nREGRESSION: {len(result.regressions)} beyond tolerance in "
              f"{len({c.record for c in result.regressions})} record(s):")
        for ch in result.regressions:
            rel = f", {ch.relative:+.1%}" if ch.relative is not None else ""
            note = f"; {ch.note}" if ch.note else ""
            values = f"{fmt_value(ch.baseline)} -> {fmt_value(ch.current)}"
            print(f"  {ch.record}: {ch.metric} {values}{rel} (rule {ch.rule}{note})")
        return 1, doc
    print("\nOK: no regression beyond tolerance")
    return 0, doc
