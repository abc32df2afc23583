"""docs/columns.md documents every parameter and metric of every built-in case."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from mpsbench.cases import get_case
from mpsbench.results.records import COMMON_COLUMNS, ENV_COLUMNS

DOC = Path(__file__).resolve().parents[1] / "docs" / "columns.md"


def _section(text: str, case: str) -> str:
    match = re.search(rf"^## {re.escape(case)}\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert match, f"docs/columns.md has no section '## {case}'"
    return match.group(1)


@pytest.mark.parametrize("case", ["diffusion", "couette", "water-jet", "dam-break", "hydrostatic",
                                  "poiseuille", "taylor-green", "cavity"])
def test_every_column_of_the_case_is_documented(case: str) -> None:
    section = _section(DOC.read_text(), case)
    c = get_case(case)
    names = [p.name for p in c.params] + list(c.metrics)
    # per-sensor columns may be documented once as name_sensor<k>
    missing = [n for n in names if f"`{n}`" not in section
               and f"`{re.sub(r'_sensor[1-4]$', '_sensor<k>', n)}`" not in section]
    assert not missing, f"{case}: not in docs/columns.md: {missing}"


def test_every_common_and_environment_column_is_documented() -> None:
    section = _section(DOC.read_text(), "Columns of every record")
    missing = [n for n in (*COMMON_COLUMNS, *ENV_COLUMNS) if f"`{n}`" not in section]
    assert not missing, f"not in docs/columns.md, 'Columns of every record': {missing}"


def test_every_bench_record_field_is_documented() -> None:
    from mpsbench.testing.bench import RECORD_FIELDS

    section = _section(DOC.read_text(), "mpsbench bench")
    missing = [n for n in RECORD_FIELDS if f"`{n}`" not in section]
    assert not missing, f"not in docs/columns.md, 'mpsbench bench': {missing}"


def test_every_solver_counter_column_is_documented() -> None:
    from mpsbench.run.implicit_scheme import COUNTERS

    section = _section(DOC.read_text(), "Columns of every record")
    missing = [n for n in COUNTERS if f"`{n}`" not in section]
    assert not missing, f"not in docs/columns.md, 'Columns of every record': {missing}"
