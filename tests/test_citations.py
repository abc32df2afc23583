"""Every "method.md section N" cited in the code, the docs and the reports they write names a
section that exists in docs/method.md."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SECTION = re.compile(r"^##+ (\d+)([a-z]?)\.", re.M)
# "method.md section 6 a", "method.md 6c", "method.md sections 1-3", "method.md 6d, 8, 9"
NUMBER = r"\d+(?:\s?[a-d](?![A-Za-z]))?"
CITATION = re.compile(
    rf"method\.md[:,]?\s+(?:sections?\s+)?({NUMBER}(?:\s*(?:,|and|-|to)\s*{NUMBER})*)")


def sections() -> set[str]:
    text = (ROOT / "docs" / "method.md").read_text()
    return {n + s for n, s in SECTION.findall(text)} | {n for n, _ in SECTION.findall(text)}


def cited() -> list[tuple[str, str]]:
    out = []
    for folder in ("mpsbench", "solvers", "validations", "docs", "tests", "examples"):
        for path in (ROOT / folder).rglob("*"):
            if path.suffix not in (".py", ".md", ".toml") or ".venv" in path.parts \
                    or path.name == Path(__file__).name:  # its own counter-example
                continue
            for m in CITATION.finditer(path.read_text()):
                for ref in re.findall(r"(\d+)\s?([a-d]?)(?![A-Za-z])", m.group(1)):
                    out.append((f"{path.relative_to(ROOT)}: {m.group(0)!r}", ref[0] + ref[1]))
    return out


def test_citations_point_at_existing_sections() -> None:
    known = sections()
    assert {"1", "6a", "6d", "8", "9", "11"} <= known
    refs = cited()
    assert len(refs) > 50  # the scan finds the citations at all
    missing = [where for where, ref in refs if ref not in known]
    assert not missing, missing


def test_the_scan_would_catch_a_missing_section() -> None:
    bad = [m.group(1) for m in CITATION.finditer("see docs/method.md section 14 and 6 e")]
    assert bad and "14" in bad[0]
