"""index.html as a person reads it: the headline figure of a case first, its tables folded
away, figures linked once, reST literals as code (issue 18, item 8)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from mpsbench.cases import CaseCheck
from mpsbench.results.case_report import Rendered
from mpsbench.results.html import _inline, rendered_html


def _rendered(tmp_path: Path, headline_figure: str = "") -> Rendered:
    fdir = tmp_path / "case" / "figures"
    fdir.mkdir(parents=True)
    figures = []
    for name in ("a_detail", "b_overview"):
        (fdir / f"{name}.png").write_bytes(b"\x89PNG not really")
        figures.append(fdir / f"{name}.png")
    tables = {"errors": pd.DataFrame({"l2": [0.1, 0.2]}), "timings": pd.DataFrame({"s": [1.0]})}
    checks = [CaseCheck("error below limit", True, "worst 0.1 < 0.5")]
    records = [{"run_id": "r1", "status": "completed"}]
    return Rendered(records, checks, tables, figures, "Model X wins.", tmp_path / "case",
                    "errors", headline_figure)


def test_headline_figure_first_then_findings_gates_figures_tables(tmp_path: Path) -> None:
    page = "\n".join(rendered_html(_rendered(tmp_path, "b_overview"), tmp_path))
    first = page.index('src="case/figures/b_overview.png"')  # relative to the page's folder
    assert 'class="headline"' in page[page.rindex("<figure", 0, first):first]
    assert first < page.index("Model X wins.") < page.index("error below limit") \
        < page.index('src="case/figures/a_detail.png"') < page.index("<table")
    # every table folded in its own <details>, the headline table first and marked
    tables = page[page.index('<details class="tables">'):]
    assert tables.count("<details>") == 2 and tables.count("<table") == 2
    assert tables.index("errors <small>(headline)</small>") < tables.index("<summary>timings")
    assert page.count("<img ") == 2 and "base64" not in page  # each figure linked once


def test_without_a_headline_figure_the_first_drawn_leads(tmp_path: Path) -> None:
    page = "\n".join(rendered_html(_rendered(tmp_path), tmp_path))
    assert page.index("a_detail.png") < page.index("b_overview.png")
    head = page[:page.index("a_detail.png")]
    assert 'class="headline"' in head


def test_missing_figure_is_named_not_linked(tmp_path: Path) -> None:
    r = _rendered(tmp_path)
    r.figures[0].unlink()
    page = "\n".join(rendered_html(r, tmp_path))
    assert "figure a_detail.png is missing" in page and "a_detail.png\"" not in page


def test_rest_double_backticks_are_code() -> None:
    assert _inline("set ``vtu = true`` or `x`") == "set <code>vtu = true</code> or <code>x</code>"
    assert _inline("``a`b``") == "<code>a`b</code>"
    assert "`" not in _inline("the ``Case.estimate`` method and ``l0``")
