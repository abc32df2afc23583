"""``summary.md``: the Markdown summary of a results folder: the claims table first (the
paper's statements with verdict, rule and evidence), then the gates overview, then each case.

Text that comes from records, manifests and plugins is escaped (:mod:`.escape`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.results.case_report import Rendered, check_lines, markdown_table
from mpsbench.results.escape import md_cell, md_escape, md_frame
from mpsbench.results.sections import (
    CaseSection,
    claim_counts,
    claim_rows,
    exit_ok,
    header_lines,
    overview_rows,
    verdict,
)

CLAIMS_INTRO = (
    "The paper's statements tested as hypotheses (docs/method.md section 8): each with the rule "
    "that decided it and the numbers (u_num: numerical uncertainty, u_val: validation "
    "uncertainty, docs/method.md section 9). A refuted claim is a finding: it does not change "
    "the exit status unless `--strict-claims` is given.")
GATES_INTRO = (
    "Gates decide the exit status: analytic references reproduced by the recommended "
    "configuration, the harness's own oracles, convergence where theory predicts it.")


def render_summary(sections: list[CaseSection], manifest: dict[str, Any], out: Path) -> str:
    strict = bool(manifest.get("strict_claims"))
    ok = exit_ok(sections, strict)
    n_pass = sum(1 for s in sections if s.passed)
    claims = [c for sec in sections for s in sec.solvers for c in s.rendered.claims]
    head = f"# mpsbench validation: {verdict(ok)} ({n_pass}/{len(sections)} cases pass)"
    if claims:
        head += f"; claims: {claim_counts(claims)}"
        if strict:
            head += " (--strict-claims: a refuted claim fails the run)"
    lines = [head, ""]
    lines += [md_escape(line) for line in header_lines(manifest)] + [""]
    rows = claim_rows(sections)
    if rows:
        lines += ["## Claims", "", CLAIMS_INTRO, "", *_compact_table(rows), ""]
    overview = pd.DataFrame(overview_rows(sections))
    lines += ["## Gates", "", GATES_INTRO, "", _md(overview), ""]
    for sec in sections:
        lines += [f"## {md_escape(sec.title or sec.name)} (`{sec.name}`): {verdict(sec.passed)}",
                  ""]
        if sec.error:
            lines += [f"**Error:** {md_escape(sec.error)}", ""]
        several = len(sec.solvers) > 1
        for s in sec.solvers:
            r = s.rendered
            if several:
                lines += [f"### solver {s.solver} {md_escape(s.version)}: {verdict(r.passed)}", ""]
            else:
                lines += [f"Solver {md_escape(' '.join(filter(None, (s.solver, s.version))))}: "
                          f"{len(r.records)} runs, {r.completed} completed.", ""]
            lines += _rendered_lines(r, out)
        if sec.by_solver is not None and not sec.by_solver.empty:
            lines += ["### all solvers: metrics side by side", "", markdown_table(sec.by_solver)]
        if sec.cross_code is not None and not sec.cross_code.empty:
            lines += ["### cross-code: MPS backends and outside codes", "",
                      md_escape(sec.cross_code_caption), "", _md(sec.cross_code)]
        if sec.folder is not None and (sec.folder / "report.md").exists():
            rel = _rel(sec.folder / "report.md", out)
            lines += [f"Full report: [{rel}]({rel})", ""]
    return "\n".join(lines).rstrip() + "\n"


def _rendered_lines(r: Rendered, out: Path) -> list[str]:
    lines: list[str] = []
    if r.failures:
        lines += [md_escape("Fails: " + "; ".join(r.failures) + "."), ""]
    if r.note:
        lines += [md_escape(r.note[0].upper() + r.note[1:] + "."), ""]
    if r.findings.strip():
        lines += [md_escape(r.findings.strip()), ""]
    if r.gates:
        lines += ["Gates:", ""] + [md_escape(line) for line in check_lines(r.checks)] + [""]
    if r.claims:
        ids = ", ".join(dict.fromkeys(c.claim for c in r.claims))
        lines += [md_escape(f"Claims {ids}: {claim_counts(r.claims)} (table at the top)."), ""]
    head = r.headline_table()
    if head is not None:
        lines += [f"Table **{head[0]}**:", "", markdown_table(head[1])]
    return lines


def _cell(value: Any) -> str:
    """A table cell that cannot break the Markdown table: escaped (:func:`md_cell`, pipes
    too) and on one line."""
    return " ".join(str(md_cell(str(value))).split())


def _compact_table(rows: list[dict[str, Any]]) -> list[str]:
    """A pipe table without column padding (the claims' rules and evidence are long)."""
    cols = list(rows[0])
    out = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    out += ["| " + " | ".join(_cell(r.get(c, "")) for c in cols) + " |" for r in rows]
    return out


def _md(df: pd.DataFrame) -> str:
    return markdown_table(df) if df.empty else str(md_frame(df).to_markdown(index=False)) + "\n"


def _rel(path: Path, base: Path) -> str:
    try:
        return path.resolve().relative_to(base.resolve()).as_posix()
    except ValueError:
        return path.as_posix()
