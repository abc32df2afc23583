"""Text from records, manifests and plugins, made harmless in Markdown and HTML reports.

Run ids, reasons, parameter values and manifest fields come from files anybody can edit and
from plugin code.  In a Markdown report (report.md, summary.md, compare.md) :func:`md_escape`
turns ``&`` and ``<`` into entities (so no HTML tag or entity gets through to a Markdown viewer;
``>`` cannot open a tag and stays, so "0.1 -> 0.05" and "T >= 8 s" read as written in the raw
file too) and defuses links whose target is not :func:`safe_href`; in the page,
``mpsbench.results.html`` escapes everything and renders only safe links.
"""

from __future__ import annotations

import html
import re
from typing import Any

import pandas as pd

_LINK = re.compile(r"\[([^\]]*)\]\(([^)]*)\)")
_CODE = re.compile(r"(`+)(.+?)\1", re.S)
_SCHEME = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*):")


def safe_href(url: str) -> bool:
    """Whether a link target may become a live link: an http(s) URL, a relative path or a
    ``#`` anchor.  Anything with another scheme (``javascript:``, ``data:``, ``file:``), a
    network path (``//host``) or a control character or space is not."""
    url = html.unescape(url)
    if not url or any(ord(c) < 0x21 or ord(c) == 0x7F for c in url) or "\\" in url:
        return False
    if url.startswith("#"):
        return True
    if url.startswith("//"):
        return False
    scheme = _SCHEME.match(url)
    if scheme is None:
        return True  # a relative path (a ':' only after a '/', '?' or '#')
    return scheme.group(1).lower() in ("http", "https") and url[len(scheme.group(0)):
                                                               ].startswith("//")


def md_escape(text: Any) -> str:
    """``text`` for a Markdown report: HTML characters as entities outside code spans (inside
    them Markdown shows text literally anyway), unsafe links shown as text."""
    s = str(text)
    out = []
    pos = 0
    for m in _CODE.finditer(s):
        out.append(_escape_plain(s[pos:m.start()]))
        out.append(m.group(0))
        pos = m.end()
    out.append(_escape_plain(s[pos:]))
    return "".join(out)


def _escape_plain(s: str) -> str:
    s = s.replace("&", "&amp;").replace("<", "&lt;")

    def link(m: re.Match[str]) -> str:
        if safe_href(m.group(2)):
            return m.group(0)
        return f"\\[{m.group(1)}\\]({m.group(2)})"

    return _LINK.sub(link, s)


def md_cell(value: Any) -> Any:
    """A table cell for Markdown: strings escaped (and ``|``, which would split the cell)."""
    if isinstance(value, str):
        return md_escape(value).replace("|", "\\|")
    return value


def md_frame(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with every text cell, index label and column name passed through :func:`md_cell`."""
    out = df.copy()
    for col in out.columns:
        if _is_text(out[col]):
            out[col] = out[col].map(md_cell)
    out.columns = _index(out.columns)
    out.index = _index(out.index)
    return out


def _is_text(values: Any) -> bool:
    return values.dtype == object or pd.api.types.is_string_dtype(values.dtype)


def _index(idx: pd.Index) -> pd.Index:
    if isinstance(idx, pd.MultiIndex):
        levels = [list(lvl.map(md_cell)) if _is_text(lvl) else list(lvl) for lvl in idx.levels]
        return idx.set_levels(levels)
    if _is_text(idx):
        return pd.Index([md_cell(v) for v in idx], name=idx.name)
    return idx
