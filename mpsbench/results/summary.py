"""``summary.md``: the Markdown summary of a results folder (overview, then each case).

Text that comes from records, manifests and plugins is escaped (:mod:`.escape`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.results.case_report import Rendered, check_lines, markdown_table
from mpsbench.results.escape import md_escape, md_frame
from mpsbench.results.sections import CaseSection, header_lines, overview_rows, verdict


def render_summary(sections: list[CaseSection], manifest: dict[str, Any], out: Path) -> str:
    ok = all(s.passed for s in sections)
    n_pass = sum(1 for s in sections if s.passed)
    lines = [f"# mpsbench validation: {verdict(ok)} ({n_pass}/{len(sections)} cases pass)", ""]
    lines += [md_escape(line) for line in header_lines(manifest)] + [""]
    overview = pd.DataFrame(overview_rows(sections))
    lines += ["## Overview", "", _md(overview), ""]
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
    if r.checks:
        lines += ["Checks:", ""] + [md_escape(line) for line in check_lines(r.checks)] + [""]
    head = r.headline_table()
    if head is not None:
        lines += [f"Table **{head[0]}**:", "", markdown_table(head[1])]
    return lines


def _md(df: pd.DataFrame) -> str:
    return markdown_table(df) if df.empty else str(md_frame(df).to_markdown(index=False)) + "\n"


def _rel(path: Path, base: Path) -> str:
    try:
        return path.resolve().relative_to(base.resolve()).as_posix()
    except ValueError:
        return path.as_posix()
