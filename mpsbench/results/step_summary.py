"""The Markdown that ``validate`` and ``compare`` append to a CI job's summary page.

GitHub Actions renders the file named by ``$GITHUB_STEP_SUMMARY`` on the run's page; when the
variable is set, ``mpsbench validate`` appends :func:`validation_summary` and ``mpsbench
compare`` its comparison table (:func:`mpsbench.results.compare.render_markdown`).  Unset, nothing
is written.  The summary carries no links into the report folder (they would not resolve on the
run page; the folder is the uploaded artifact).  GitHub shows at most 1 MiB per step, so a longer
text is cut with a note.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.results.case_report import check_lines, claim_lines
from mpsbench.results.sections import CaseSection, exit_ok, header_lines, overview_rows, verdict

ENV = "GITHUB_STEP_SUMMARY"
LIMIT = 1024 * 1024  # bytes GitHub accepts per step
MAX_RUNS_LISTED = 20


def validation_summary(sections: list[CaseSection], manifest: dict[str, Any]) -> str:
    """Verdict, header, the overview table, then each case's failures and checks."""
    ok = exit_ok(sections, bool(manifest.get("strict_claims")))
    n_pass = sum(1 for s in sections if s.passed)
    what = f"{manifest.get('case', '?')}, tier {manifest.get('tier', '?')}"
    lines = [f"## mpsbench validate ({what}): {verdict(ok)} ({n_pass}/{len(sections)} cases pass)",
             "", *header_lines(manifest), ""]
    rows = overview_rows(sections)
    if rows:
        lines += [str(pd.DataFrame(rows).to_markdown(index=False)), ""]
    for sec in sections:
        lines += [f"### {sec.name}: {verdict(sec.passed)}", ""]
        if sec.error:
            lines += [f"**Error:** {sec.error}", ""]
        for s in sec.solvers:
            r = s.rendered
            head = f"**{s.solver}**: {len(r.records)} runs, {r.completed} completed"
            lines += [head + (f"; fails: {'; '.join(r.failures)}" if r.failures else "") + ".", ""]
            bad = [rec for rec in r.records if rec.get("status") != "completed"]
            if bad:
                lines += ["Runs that did not complete:", ""]
            for rec in bad[:MAX_RUNS_LISTED]:
                lines.append(f"- run `{rec.get('run_id')}`: {rec.get('status')}: "
                             f"{rec.get('reason', '')}")
            if len(bad) > MAX_RUNS_LISTED:
                lines.append(f"- ... and {len(bad) - MAX_RUNS_LISTED} more runs that did not "
                             "complete (see the report)")
            if bad:
                lines.append("")
            if r.gates:
                lines += ["Gates:", "", *check_lines(r.checks), ""]
            if r.claims:
                lines += ["Claims (they do not gate the verdict unless --strict-claims):", "",
                          *claim_lines(r.checks), ""]
    return "\n".join(lines).rstrip() + "\n"


def append_step_summary(markdown: str, environ: Mapping[str, str] | None = None) -> Path | None:
    """Append ``markdown`` to ``$GITHUB_STEP_SUMMARY`` when it is set; return the file or None.

    A file that cannot be written is reported on stderr and skipped: the summary is a courtesy,
    and the command's own outputs and exit status stand without it.
    """
    path = (os.environ if environ is None else environ).get(ENV)
    if not path:
        return None
    data = markdown.rstrip("\n").encode("utf-8")
    if len(data) > LIMIT - 200:
        data = data[: LIMIT - 200].decode("utf-8", "ignore").encode("utf-8")
        data += b"\n\n_(cut at GitHub's 1 MiB step-summary limit; the full text is in the report)_"
    try:
        with open(path, "ab") as fh:
            fh.write(data + b"\n\n")
    except OSError as exc:
        print(f"mpsbench: cannot append to {ENV} ({path}): {exc}", file=sys.stderr)
        return None
    return Path(path)
