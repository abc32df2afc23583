"""``index.html``: the page a person reads for a results folder.

Order: the claims table (the paper's statements: verdict, and rule and evidence folded
out) and the gates overview (one row per case and solver) first, then one section per case:
its headline figure, its findings, gates and claims, its other figures, and its tables folded
away (``<details>``); with several solvers the cross-solver comparison comes first, then one
section per solver.

Figures are stored once: the page links the PNG files of the case folders by relative path
(``<case>/figures/<name>.png``) instead of embedding a second copy of each, so the page stays
small and still loads nothing from the network (it opens from a file:// URL with its folder).
Tables are pandas HTML; the style sheet is inline.
"""

from __future__ import annotations

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
figure.headline{display:block;margin:.5em 0 1em}figure.headline img{max-height:80vh}
div.figures figure{max-width:48%}div.figures figure img{max-height:420px}
details{margin:.4em 0}details>summary{cursor:pointer;color:#0969da}
details.tables{border:1px solid #d0d7de;border-radius:6px;padding:.3em .8em;background:#fff}
figcaption{font-size:.85em;color:#57606a;text-align:center}
code{background:#eff1f3;border-radius:3px;padding:0 .25em;font-size:.9em}
ul.checks{list-style:none;padding-left:0}ul.checks li{margin:.2em 0}
table.claims td,table.claims th{text-align:left;vertical-align:top}table.claims p{margin:.3em 0}
table.claims details>summary{color:#57606a}
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
    """The claims table: one row per claim tested, the verdict as a badge; each row's rule,
    evidence and source fold out (``<details>``), so the table stays a screen tall."""
    rows = claim_rows(sections)
    if not rows:
        return []
    shown = [c for c in rows[0] if c not in ("source", "rule", "evidence")]
    head = "".join(f"<th>{esc(c)}</th>" for c in shown) + "<th>rule and evidence</th>"
    body = []
    for row in rows:
        cells = "".join(
            f"<td>{claim_badge(str(row[c])) if c == 'verdict' else _inline(str(row[c]))}</td>"
            for c in shown)
        more = (f"<details><summary>{_inline(_clip(str(row['evidence'])))}</summary>"
                f"<p><em>Evidence:</em> {_inline(str(row['evidence']))}</p>"
                f"<p><em>Rule:</em> {_inline(str(row['rule']))}</p>"
                f"<p><em>Source:</em> {_inline(str(row['source']))}</p></details>")
        body.append(f"<tr>{cells}<td>{more}</td></tr>")
    return ['<h2 id="claims">Claims</h2>', f"<p>{_inline(CLAIMS_INTRO)}</p>",
            f'<div class="scroll"><table class="claims"><tr>{head}</tr>{"".join(body)}'
            "</table></div>"]


def _clip(text: str, n: int = 60) -> str:
    """The start of ``text`` (at a word boundary) for a folded cell's one-line summary."""
    text = " ".join(text.split())
    return text if len(text) <= n else text[:n].rsplit(" ", 1)[0] + " ..."


def overview_html(rows: list[dict[str, Any]]) -> str:
    """The gates overview: one row per (case, solver), the case linked to its section and
    the result as a badge."""
    if not rows:
        return "<p><em>(no cases)</em></p>"
    cols = list(rows[0])
    head = "".join(f"<th>{esc(c)}</th>" for c in cols)
    body = []
    for row in rows:
        cells = []
        for c in cols:
            v = row[c]
            if c == "case":
                target = anchor(str(v), str(row["solver"])) if row.get("solver") else anchor(str(v))
                cells.append(f'<td><a href="#{target}">{esc(v)}</a></td>')
            elif c == "result":
                cells.append(f"<td>{badge(v == 'PASS')}</td>")
            else:
                cells.append(f"<td>{esc(v)}</td>")
        body.append(f"<tr>{''.join(cells)}</tr>")
    return f'<div class="scroll"><table><tr>{head}</tr>{"".join(body)}</table></div>'


def _inline(text: str) -> str:
    """Escape, then Markdown's inline code, bold, emphasis and links.

    reST's double backticks are read as inline code too.  Only http(s), relative and ``#``
    link targets become links (:func:`safe_href`); any other
    (``javascript:``, ``data:``, ...) stays text, since findings, check details and manifest
    fields can carry text from records and plugins.
    """
    out = esc(text)
    # reST's ``literal`` (case descriptions are docstrings) before Markdown's `code`
    out = re.sub(r"``(.+?)``", r"<code>\1</code>", out)
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


def image_html(path: Path, out: Path, *, headline: bool = False) -> str:
    """A figure linked (not embedded) by its path relative to the page's folder ``out``: the
    PNG is stored once, in its case folder; a click opens it at full size."""
    if not path.is_file():
        return f'<p class="error">figure {esc(path.name)} is missing</p>'
    href = esc(_relfile(path, out))
    cls = ' class="headline"' if headline else ""
    return (f'<figure{cls}><a href="{href}"><img src="{href}" alt="{esc(path.stem)}" '
            f'loading="lazy"></a><figcaption>{esc(path.stem)}</figcaption></figure>')


def _relfile(path: Path, out: Path) -> str:
    """``path`` relative to the page's folder (a file:// URL when it is outside it)."""
    try:
        return path.resolve().relative_to(out.resolve()).as_posix()
    except ValueError:
        return path.resolve().as_uri()


def _relpath(folder: Path, out: Path) -> str:
    """``folder`` relative to the page's folder, with a trailing slash ('' for the same)."""
    try:
        rel = folder.resolve().relative_to(out.resolve()).as_posix()
    except ValueError:
        return folder.resolve().as_uri() + "/"
    return "" if rel == "." else rel + "/"


def anchor(*parts: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", "--".join(parts))


def tables_html(tables: dict[str, pd.DataFrame], head: tuple[str, pd.DataFrame] | None
                ) -> list[str]:
    """The tables, each folded in its own ``<details>`` (the headline table first)."""
    if not tables:
        return []
    names = ([head[0]] if head else []) + [n for n in tables if not head or n != head[0]]
    out = [f'<details class="tables"><summary>Tables ({len(names)}): '
           f'{esc(", ".join(names))}</summary>']
    for name in names:
        mark = " <small>(headline)</small>" if head and name == head[0] else ""
        out += [f"<details><summary>{esc(name)}{mark}</summary>", table_html(tables[name]),
                "</details>"]
    return out + ["</details>"]


def figures_html(figures: list[Path], out: Path) -> tuple[list[str], list[str]]:
    """The first figure (the headline one, :meth:`Rendered.ordered_figures` puts it first) at
    full width, and the others side by side."""
    if not figures:
        return [], []
    rest = [image_html(f, out) for f in figures[1:]]
    return ([image_html(figures[0], out, headline=True)],
            ['<div class="figures">', *rest, "</div>"] if rest else [])


def rendered_html(r: Rendered, out: Path, *, checks: bool = True) -> list[str]:
    """One (case, solver): headline figure, findings, gates, claims, the other figures, the
    runs that did not complete, then the tables folded away."""
    html_out: list[str] = []
    if r.failures and checks:
        html_out.append(f'<p class="error">Fails: {esc("; ".join(r.failures))}.</p>')
    if r.note:
        html_out.append(f'<p class="meta">{esc(r.note)}.</p>')
    first, rest = figures_html(r.ordered_figures(), out)
    html_out += first
    if r.findings.strip():
        html_out += ["<h4>Findings</h4>", markdown_html(r.findings)]
    if r.gates and checks:
        html_out.append('<h4>Gates</h4><ul class="checks">')
        html_out += [f"<li>{badge(c.passed)} <strong>{esc(c.name)}</strong>: "
                     f"{_inline(c.detail)}</li>" for c in r.gates]
        html_out.append("</ul>")
    if r.claims and checks:
        html_out.append('<h4>Claims</h4><ul class="checks">')
        html_out += [f"<li>{check_badge(c)} <strong>{esc(c.claim)}</strong> {esc(c.name)} "
                     f"<em>Rule:</em> {_inline(c.rule)} <em>Evidence:</em> "
                     f"{_inline(c.detail)}</li>" for c in r.claims]
        html_out.append("</ul>")
    if rest:
        html_out += ["<h4>More figures</h4>", *rest]
    bad = [x for x in r.records if x.get("status") != "completed"]
    if bad:
        html_out.append(f"<details><summary>{len(bad)} run(s) did not complete</summary><ul>")
        html_out += [f"<li><code>{esc(x.get('run_id', '?'))}</code>: {esc(x.get('status'))}: "
                     f"{esc(x.get('reason', ''))}</li>" for x in bad[:20]]
        html_out.append("</ul></details>")
    html_out += tables_html(r.tables, r.headline_table())
    return html_out


def combined_html(sec: CaseSection, out: Path) -> list[str]:
    """With several solvers: the case's all-solver figures and the metrics side by side."""
    figures = sec.combined.ordered_figures() if sec.combined is not None else []
    has_table = sec.by_solver is not None and not sec.by_solver.empty
    has_cross = sec.cross_code is not None and not sec.cross_code.empty
    if not figures and not has_table and not has_cross:
        return []
    body = [f'<section class="solver" id="{anchor(sec.name, "all-solvers")}">',
            "<h3>all solvers compared</h3>"]
    first, rest = figures_html(figures, out)
    body += first + rest
    if sec.by_solver is not None and has_table:
        body += tables_html({"metrics by solver": sec.by_solver}, None)
    if sec.cross_code is not None and has_cross:
        body += ["<h4>Cross-code: MPS backends and outside codes</h4>",
                 f"<p>{esc(sec.cross_code_caption)}</p>", table_html(sec.cross_code, index=False)]
    return body + ["</section>"]


def render_index(sections: list[CaseSection], manifest: dict[str, Any], out: Path) -> str:
    ok = exit_ok(sections, bool(manifest.get("strict_claims")))
    title = f"mpsbench validation ({manifest.get('tier', '?')}): {verdict(ok)}"
    claims = [c for sec in sections for s in sec.solvers for c in s.rendered.claims]
    counts = f' <small>claims: {esc(claim_counts(claims))}</small>' if claims else ""
    body = [f"<h1>mpsbench validation ({esc(manifest.get('tier', '?'))}) {badge(ok)}{counts}</h1>",
            f'<p class="meta">{_inline(header_lines(manifest)[0])}</p>']
    links = " ".join(f'<a href="#{anchor(sec.name)}">{esc(sec.name)}</a>' for sec in sections)
    body.append('<nav>' + ('<a href="#claims"><strong>Claims</strong></a> ' if claims else "")
                + '<a href="#gates"><strong>Gates</strong></a> '
                + f"<strong>Cases:</strong> {links}</nav>")
    body += claims_html(sections)  # as in summary.md: the claims, then the gates
    body += ['<h2 id="gates">Gates</h2>', f"<p>{_inline(GATES_INTRO)}</p>",
             overview_html(overview_rows(sections))]
    for sec in sections:
        body.append(f'<section class="case" id="{anchor(sec.name)}">')
        body.append(f"<h2>{esc(sec.title or sec.name)} <code>{esc(sec.name)}</code> "
                    f"{badge(sec.passed)}</h2>")
        if sec.description:  # the case's setup: one line until opened
            body += ["<details><summary>About this case</summary>",
                     markdown_html(sec.description), "</details>"]
        if sec.error:
            body.append(f'<p class="error">{esc(sec.error)}</p>')
        if sec.combined is not None:
            body += combined_html(sec, out)
        for s in sec.solvers:
            r = s.rendered
            body.append(f'<section class="solver" id="{anchor(sec.name, s.solver)}">')
            body.append(f"<h3>solver {esc(s.solver)} {esc(s.version)} {badge(r.passed)}</h3>")
            body.append(f'<p class="meta">{len(r.records)} runs, {r.completed} completed.</p>')
            body += rendered_html(r, out)
            body.append("</section>")
        if sec.folder is not None and (sec.folder / "report.md").exists():
            rel = _relpath(sec.folder, out)
            links = ", ".join(f'<a href="{esc(rel + name)}">{esc(name)}</a>'
                              for name in ("report.md", "results.csv", "tables/", "figures/")
                              if (sec.folder / name).exists())
            body.append(f'<p class="meta">Case folder <code>{esc(rel or "./")}</code>: {links}</p>')
        body.append("</section>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{esc(title)}</title><style>{CSS}</style></head>\n<body><main>\n"
            + "\n".join(body) + "\n</main></body></html>\n")
