"""``mpsbench report DIR``: re-render a results folder without re-running anything.

Reads the stored records (``<case>/runs/*.json``) and re-writes every case's tables, figures,
checks and report with the case's current code (so a plotting fix needs no new runs), then the
top-level results, summary.md, index.html and figures/.  A case whose code is unavailable (or
with ``--from-files``) is shown from the files an earlier render left.  Works on a folder from
``mpsbench validate all`` and on a single case folder from ``mpsbench validate CASE``.
Every input is read before anything is written, and a record, manifest or stored checks file
that is unreadable, truncated or not allowed stops the command (exit 2, naming the file): no
record is dropped from a report without a word.  The folder is locked while it is written
(:mod:`mpsbench.results.lock`).
Exit status: 0 rendered, 2 DIR is not a results folder, holds a broken file or is in use.  With
``--strict-claims`` the exit status is the verdict, as ``mpsbench validate --strict-claims``
would give it: 1 when a gate fails or a claim of the paper is refuted.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mpsbench.commands.validate import MAX_AUTO_JOBS, auto_jobs  # validate's default
from mpsbench.errors import UsageError

# pandas and the cases are imported inside the functions: 'mpsbench --help' stays fast
if TYPE_CHECKING:
    from mpsbench.cases import Case
    from mpsbench.results.sections import CaseSection

ORDER = 35


def register(sub: Any) -> None:
    p = sub.add_parser(
        "report",
        help="re-render summary.md and index.html of a results folder (no runs)",
        description="Re-render a results folder from its stored records: case tables, figures "
        "and reports, results.csv/json, summary.md, index.html. Nothing is re-run.",
    )
    p.add_argument("dir", help="a folder written by 'mpsbench validate'")
    p.add_argument("--from-files", action="store_true",
                   help="do not call the cases' table/figure code; reuse the files on disk")
    p.add_argument("--strict-claims", action="store_true",
                   help="exit 1 when a gate fails or a claim of the paper is refuted")
    p.add_argument("--jobs", type=int, default=None,
                   help="processes rendering the cases side by side (default: the number of "
                   f"CPUs, at most {MAX_AUTO_JOBS}; 1: one after the other)")
    p.set_defaults(func=cmd_report)


def cmd_report(args: argparse.Namespace) -> int:
    from mpsbench.results.lock import folder_lock

    out = Path(args.dir)
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs} is not allowed: an integer >= 1")
    if not out.is_dir():
        raise UsageError(f"{out}: no such folder")
    with folder_lock(out, f"mpsbench report {out}", option="DIR"):
        return _report(args, out)


def _report(args: argparse.Namespace, out: Path) -> int:
    from mpsbench.cases import get_case
    from mpsbench.results.folder import case_folders, read_manifest, write_top_level
    from mpsbench.results.render_pool import render_cases
    from mpsbench.results.sections import (
        CaseSection,
        case_from_disk,
        claim_counts,
        in_solver_order,
        verdict,
    )

    manifest = read_manifest(out)
    found = case_folders(out)
    if not found:
        raise UsageError(f"{out}: not a results folder (no runs/ in it or in a case sub-folder); "
                         "write one with 'mpsbench validate'")
    single = found[0][1].resolve() == out.resolve()
    sections: dict[str, CaseSection] = {}
    params: list[str] = []
    to_render: list[tuple[str, Case, Path, list[dict[str, Any]]]] = []
    for name, folder, records in found:  # read every stored file before writing any
        records = in_solver_order(records, manifest.get("solvers"))
        case: Case | None = None
        why = "--from-files"
        if not args.from_files:
            try:
                case = get_case(name)
            except Exception as exc:  # noqa: BLE001 - shown from files instead
                why = f"case {name!r} is unavailable: {exc}"
                print(f"{name}: {why}; using the files on disk", file=sys.stderr)
        if case is not None:
            to_render.append((name, case, folder, records))
            sections[name] = CaseSection(name)  # keeps the order
            params += [p.name for p in case.params]
        else:
            sections[name] = case_from_disk(name, records, folder, why)
    rendered = render_cases([(case, records, folder) for _, case, folder, records in to_render],
                            auto_jobs(args.jobs))
    for (name, *_), section in zip(to_render, rendered, strict=True):
        sections[name] = section
    # cases that could not run at all are known only from the manifest
    for entry in manifest.get("cases", []):
        name = str(entry.get("name", ""))
        if name and name not in sections and entry.get("error"):
            sections[name] = CaseSection(name, name, error=str(entry["error"]))
    order = [str(e.get("name")) for e in manifest.get("cases", []) if e.get("name") in sections]
    ordered = [sections[n] for n in order] + [s for n, s in sections.items() if n not in order]
    _fill_manifest(manifest, ordered)
    manifest["strict_claims"] = bool(args.strict_claims)
    ok = write_top_level(out, ordered, manifest, params, write_results=not single)
    for sec in ordered:
        print(f"{verdict(sec.passed)} {sec.name}" + (f": {sec.error}" if sec.error else ""))
    claims = [c for s in ordered for so in s.solvers for c in so.rendered.claims]
    counts = f"; claims: {claim_counts(claims)}" if claims else ""
    strict = " (--strict-claims: a refuted claim fails)" if args.strict_claims else ""
    print(f"{verdict(ok)}: {sum(s.passed for s in ordered)}/{len(ordered)} cases pass their "
          f"gates{counts}{strict}")
    for c in (c for s in ordered for c in s.refuted):
        print(f"  refuted {c.claim}: {c.name}")
    print(f"summary: {out / 'summary.md'}")
    print(f"index:   {out / 'index.html'}")
    return 1 if args.strict_claims and not ok else 0


def _fill_manifest(manifest: dict[str, Any], sections: list[CaseSection]) -> None:
    """A folder without manifest.json (or an old one): take tier, solvers, env from the records."""
    from mpsbench.results.records import ENV_COLUMNS
    from mpsbench.results.sections import solver_order

    records = [r for s in sections for r in s.records]
    if not records:
        return
    manifest.setdefault("tier", ", ".join(sorted({str(r.get("tier")) for r in records})))
    manifest.setdefault("solvers", solver_order(records))
    manifest.setdefault("environment", {k: records[0].get(k) for k in ENV_COLUMNS})
