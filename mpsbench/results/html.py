"""``index.html``: one self-contained page for a results folder.

Figures are embedded as base64 PNG data URIs, tables are pandas HTML, the style sheet is inline;
the page loads nothing from the network and opens from a file:// URL or an e-mail attachment.
Sections: the claims table (the paper's statements: verdict, rule, evidence), the gates
overview, then one per case and, inside it, one per solver (plus a cross-solver one when
several solvers ran).
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.cases import CaseCheck
from mpsbench.results.case_report import Rendered
from mpsbench.results.escape import safe_href
from mpsbench.results.sections import (
    CaseSection,
    claim_counts,
    claim_rows,
    exit_ok,
    header_lines,
    overview_rows,
    verdict,
)
from mpsbench.results.summary import CLAIMS_INTRO, GATES_INTRO

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#1b1f24;
 background:#fafbfc;line-height:1.45}
main{max-width:1200px;margin:0 auto;padding:1.2em 2em 4em}
h1{margin:.3em 0}h2{border-bottom:2px solid #d0d7de;padding-bottom:.2em;margin-top:2em}
h3{margin-top:1.6em}section.solver{border-left:4px solid #d0d7de;padding-left:1em;margin:1em 0}
nav{background:#fff;border:1px solid #d0d7de;border-radius:6px;padding:.6em 1em;margin:1em 0}
nav a{margin-right:1em}nav ul{margin:.2em 0;padding-left:1.2em}
.pass{color:#fff;background:#1a7f37;border-radius:4px;padding:0 .4em;font-weight:600}
.fail{color:#fff;background:#cf222e;border-radius:4px;padding:0 .4em;font-weight:600}
.na{color:#fff;background:#6e7781;border-radius:4px;padding:0 .4em;font-weight:600}
.error{background:#ffebe9;border:1px solid #cf222e;border-radius:6px;padding:.5em 1em}
.meta{color:#57606a}.scroll{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;font-size:.85em;margin:.5em 0 1em;background:#fff}
th,td{border:1px solid #d0d7de;padding:.2em .5em;text-align:right}
th{background:#f0f3f6}td:first-child,th:first-child{text-align:left}
figure{display:inline-block;margin:.5em 1em 1em 0;vertical-align:top;background:#fff;
 border:1px solid #d0d7de;border-radius:6px;padding:.4em;max-width:100%}
figure img{max-width:100%;height:auto;display:block}
figcaption{font-size:.85em;color:#57606a;text-align:center}
code{background:#eff1f3;border-radius:3px;padding:0 .25em;font-size:.9em}
ul.checks{list-style:none;padding-left:0}ul.checks li{margin:.2em 0}
table.claims td{text-align:left;vertical-align:top}
"""


def esc(text: Any) -> str:
    return html.escape(str(text), quote=True)


def badge(state: bool | None) -> str:
    if state is None:
        return '<span class="na">n/a</span>'
    return f'<span class="{"pass" if state else "fail"}">{verdict(state)}</span>'


def claim_badge(text: str) -> str:
    """A claim's verdict: supported (green), refuted (red), inconclusive (grey)."""
    cls = {"supported": "pass", "refuted": "fail"}.get(text, "na")
    return f'<span class="{cls}">{esc(text)}</span>'


def check_badge(check: CaseCheck) -> str:
    return claim_badge(check.verdict) if check.is_claim else badge(check.passed)


def claims_html(sections: list[CaseSection]) -> list[str]:
    """The claims table: one row per claim tested, the verdict as a badge."""
    rows = claim_rows(sections)
    if not rows:
        return []
    cols = list(rows[0])
    head = "".join(f"<th>{esc(c)}</th>" for c in cols)
    body = []
    for row in rows:
        cells = "".join(
            f"<td>{claim_badge(str(row[c])) if c == 'verdict' else _inline(str(row[c]))}</td>"
            for c in cols)
        body.append(f"<tr>{cells}</tr>")
    return ['<h2 id="claims">Claims</h2>', f"<p>{_inline(CLAIMS_INTRO)}</p>",
            f'<div class="scroll"><table class="claims"><tr>{head}</tr>{"".join(body)}'
            "</table></div>"]


def _inline(text: str) -> str:
    """Escape, then Markdown's inline code, bold, emphasis and links.

    Only http(s), relative and ``#`` link targets become links (:func:`safe_href`); any other
    (``javascript:``, ``data:``, ...) stays text, since findings, check details and manifest
    fields can carry text from records and plugins.
    """
    out = esc(text)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", out)
    out = re.sub(r"(?<![\w*])\*([^*\s][^*]*)\*(?![\w*])", r"<em>\1</em>", out)
    out = re.sub(r"(?<!\w)_([^_\s][^_]*)_(?!\w)", r"<em>\1</em>", out)
    return re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", _link, out)


def _link(m: re.Match[str]) -> str:
    """A Markdown link (text and target already escaped): live when the target is safe."""
    text, href = m.group(1), m.group(2)
    if not safe_href(href) or "<" in href:  # "<": markup (<code>) put into the target above
        return m.group(0)
    return f'<a href="{href}">{text}</a>'


def markdown_html(text: str) -> str:
    """The small Markdown subset findings use: paragraphs, lists, headings, pipe tables."""
    blocks: list[str] = []
    lines = text.strip().splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].rstrip()
        if not line.strip():
            i += 1
            continue
        if line.lstrip().startswith("|"):
            rows = []
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                cells = [c.strip() for c in lines[i].strip().strip("|").split("|")]
                if not all(re.fullmatch(r":?-{2,}:?", c) for c in cells if c):
                    rows.append(cells)
                i += 1
            body = ""
            for k, row in enumerate(rows):
                tag = "th" if k == 0 else "td"
                body += "<tr>" + "".join(f"<{tag}>{_inline(c)}</{tag}>" for c in row) + "</tr>"
            blocks.append(f'<div class="scroll"><table>{body}</table></div>')
            continue
        m = re.match(r"(#{1,6})\s+(.*)", line)
        if m:
            level = min(6, len(m.group(1)) + 3)
            blocks.append(f"<h{level}>{_inline(m.group(2))}</h{level}>")
            i += 1
            continue
        if re.match(r"\s*([-*+]|\d+\.)\s+", line):
            tag = "ol" if re.match(r"\s*\d+\.", line) else "ul"
            items: list[str] = []
            while i < len(lines) and lines[i].strip():
                item = re.match(r"\s*([-*+]|\d+\.)\s+(.*)", lines[i])
                if item:
                    items.append(item.group(2))
                elif items:
                    items[-1] += " " + lines[i].strip()
                i += 1
            lis = "".join(f"<li>{_inline(t)}</li>" for t in items)
            blocks.append(f"<{tag}>{lis}</{tag}>")
            continue
        para = [line.strip()]  # at least this line: "#tag" is no heading and must not hang
        i += 1
        while i < len(lines) and lines[i].strip() and not lines[i].lstrip().startswith(("|", "#")):
            para.append(lines[i].strip())
            i += 1
        blocks.append(f"<p>{_inline(' '.join(para))}</p>")
    return "\n".join(blocks)


def table_html(df: pd.DataFrame, *, index: bool = True) -> str:
    if df.empty:
        return "<p><em>(no data)</em></p>"

    def fmt(x: float) -> str:
        return f"{x:.4g}"

    table = df.to_html(float_format=fmt, border=0, na_rep="", index=index)
    return f'<div class="scroll">{table}</div>'


def image_html(path: Path) -> str:
    try:
        data = base64.b64encode(path.read_bytes()).decode("ascii")
    except OSError as exc:
        return f'<p class="error">figure {esc(path.name)} is missing: {esc(exc)}</p>'
    return (f'<figure><img src="data:image/png;base64,{data}" alt="{esc(path.stem)}">'
            f"<figcaption>{esc(path.stem)}</figcaption></figure>")


def _relpath(folder: Path, out: Path) -> str:
    """``folder`` relative to the page's folder, with a trailing slash ('' for the same)."""
    try:
        rel = folder.resolve().relative_to(out.resolve()).as_posix()
    except ValueError:
        return folder.resolve().as_uri() + "/"
    return "" if rel == "." else rel + "/"


def anchor(*parts: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", "--".join(parts))


def rendered_html(r: Rendered, *, checks: bool = True) -> list[str]:
    out: list[str] = []
    if r.failures and checks:
        out.append(f'<p class="error">Fails: {esc("; ".join(r.failures))}.</p>')
    if r.note:
        out.append(f'<p class="meta">{esc(r.note)}.</p>')
    bad = [x for x in r.records if x.get("status") != "completed"]
    if bad:
        out.append(f"<p>{len(bad)} run(s) did not complete:</p><ul>")
        out += [f"<li><code>{esc(x.get('run_id', '?'))}</code>: {esc(x.get('status'))}: "
                f"{esc(x.get('reason', ''))}</li>" for x in bad[:20]]
        out.append("</ul>")
    if r.findings.strip():
        out += ["<h4>Findings</h4>", markdown_html(r.findings)]
    if r.gates and checks:
        out.append('<h4>Gates</h4><ul class="checks">')
        out += [f"<li>{badge(c.passed)} <strong>{esc(c.name)}</strong>: {_inline(c.detail)}</li>"
                for c in r.gates]
        out.append("</ul>")
    if r.claims and checks:
        out.append('<h4>Claims</h4><ul class="checks">')
        out += [f"<li>{check_badge(c)} <strong>{esc(c.claim)}</strong> {esc(c.name)} "
                f"<em>Rule:</em> {_inline(c.rule)} <em>Evidence:</em> {_inline(c.detail)}</li>"
                for c in r.claims]
        out.append("</ul>")
    head = r.headline_table()
    names = ([head[0]] if head else []) + [n for n in r.tables if not head or n != head[0]]
    for name in names:
        out += [f"<h4>Table: {esc(name)}</h4>", table_html(r.tables[name])]
    if r.figures:
        out.append("<h4>Figures</h4><div>")
        out += [image_html(f) for f in r.figures]
        out.append("</div>")
    return out


def combined_html(sec: CaseSection) -> list[str]:
    """With several solvers: the metrics side by side and the case's all-solver figures."""
    figures = sec.combined.figures if sec.combined is not None else []
    has_table = sec.by_solver is not None and not sec.by_solver.empty
    has_cross = sec.cross_code is not None and not sec.cross_code.empty
    if not figures and not has_table and not has_cross:
        return []
    out = [f'<section class="solver" id="{anchor(sec.name, "all-solvers")}">',
           "<h3>all solvers compared</h3>"]
    if sec.by_solver is not None and has_table:
        out += ["<h4>Metrics by solver</h4>", table_html(sec.by_solver)]
    if sec.cross_code is not None and has_cross:
        out += ["<h4>Cross-code: MPS backends and outside codes</h4>",
                f"<p>{esc(sec.cross_code_caption)}</p>", table_html(sec.cross_code, index=False)]
    if figures:
        out += ["<h4>Figures (all solvers)</h4><div>", *[image_html(f) for f in figures], "</div>"]
    return out + ["</section>"]


def render_index(sections: list[CaseSection], manifest: dict[str, Any], out: Path) -> str:
    ok = exit_ok(sections, bool(manifest.get("strict_claims")))
    title = f"mpsbench validation ({manifest.get('tier', '?')}): {verdict(ok)}"
    claims = [c for sec in sections for s in sec.solvers for c in s.rendered.claims]
    counts = f' <small>claims: {esc(claim_counts(claims))}</small>' if claims else ""
    body = [f"<h1>mpsbench validation ({esc(manifest.get('tier', '?'))}) {badge(ok)}{counts}</h1>",
            f'<p class="meta">{_inline(header_lines(manifest)[0])}</p>']
    nav = ['<nav><a href="#claims"><strong>Claims</strong></a> '
           '<a href="#gates"><strong>Gates</strong></a><strong>Cases</strong><ul>']
    for sec in sections:
        subs = "".join(f'<a href="#{anchor(sec.name, s.solver)}">{esc(s.solver)}</a>'
                       for s in sec.solvers)
        nav.append(f'<li><a href="#{anchor(sec.name)}">{esc(sec.title or sec.name)}</a> '
                   f"{badge(sec.passed)} <small>{subs}</small></li>")
    nav.append("</ul></nav>")
    body += nav
    body += claims_html(sections)
    overview = pd.DataFrame(overview_rows(sections))
    body += ['<h2 id="gates">Gates</h2>', f"<p>{_inline(GATES_INTRO)}</p>",
             table_html(overview, index=False)]
    for sec in sections:
        body.append(f'<section class="case" id="{anchor(sec.name)}">')
        body.append(f"<h2>{esc(sec.title or sec.name)} <code>{esc(sec.name)}</code> "
                    f"{badge(sec.passed)}</h2>")
        if sec.description:
            body.append(markdown_html(sec.description))
        if sec.folder is not None and (sec.folder / "report.md").exists():
            rel = _relpath(sec.folder, out)
            links = ", ".join(f'<a href="{esc(rel + name)}">{esc(name)}</a>'
                              for name in ("report.md", "results.csv", "tables/")
                              if (sec.folder / name).exists())
            body.append(f'<p class="meta">Case folder <code>{esc(rel or "./")}</code>: {links}</p>')
        if sec.error:
            body.append(f'<p class="error">{esc(sec.error)}</p>')
        for s in sec.solvers:
            r = s.rendered
            body.append(f'<section class="solver" id="{anchor(sec.name, s.solver)}">')
            body.append(f"<h3>solver {esc(s.solver)} {esc(s.version)} {badge(r.passed)}</h3>")
            body.append(f'<p class="meta">{len(r.records)} runs, {r.completed} completed.</p>')
            body += rendered_html(r)
            body.append("</section>")
        if sec.combined is not None:
            body += combined_html(sec)
        body.append("</section>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{esc(title)}</title><style>{CSS}</style></head>\n<body><main>\n"
            + "\n".join(body) + "\n</main></body></html>\n")
