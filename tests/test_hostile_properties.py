"""Property tests (issue #19): random text into the parsers raises nothing but the project's
own error type (:class:`mpsbench.errors.MpsbenchError`), and rendered links are always safe."""

from __future__ import annotations

import json
import re
import string
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mpsbench.cases import CASES, get_case
from mpsbench.commands.validate import parse_overrides
from mpsbench.errors import MpsbenchError
from mpsbench.results.compare import load_results
from mpsbench.results.escape import md_escape, safe_href
from mpsbench.results.html import _inline, markdown_html
from mpsbench.results.records import read_record
from mpsbench.results.study_spec import TOP_KEYS, load_study, parse_study

BUILTIN = ("diffusion", "couette", "water-jet", "dam-break", "hydrostatic", "poiseuille",
           "taylor-green", "cavity")
SETTINGS = settings(max_examples=150, suppress_health_check=[HealthCheck.function_scoped_fixture])

# text that looks like what people type: numbers, fractions, names, junk
NUMBERISH = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers().map(str),
    st.tuples(st.integers(-10**400, 10**400), st.integers(-10**400, 10**400)).map(
        lambda t: f"{t[0]}/{t[1]}"),
    st.text(alphabet="0123456789.eE+-/ _,nainf", max_size=30),
)
TEXT = st.one_of(NUMBERISH, st.text(max_size=60))


def param_names() -> list[tuple[str, str]]:
    return [(c, p.name) for c in BUILTIN for p in get_case(c).params]


@pytest.mark.parametrize(("case", "name"), param_names())
@SETTINGS
@given(text=TEXT)
def test_param_parse_raises_only_config_errors(case: str, name: str, text: str) -> None:
    param = get_case(case).param(name)
    try:
        value = param.parse(text)
    except MpsbenchError:
        return
    assert param.check(value) == value  # what parse accepts, check accepts


@SETTINGS
@given(items=st.lists(st.one_of(
    st.tuples(st.sampled_from(["l0", "laplacian", "dt", "seed", "jitter", "nosuch", ""]),
              TEXT).map(lambda kv: f"{kv[0]}={kv[1]}"),
    st.text(max_size=40)), max_size=4))
def test_set_overrides_raise_only_own_errors(items: list[str]) -> None:
    case = get_case("diffusion")
    try:
        overrides = parse_overrides(case, items)
    except MpsbenchError:
        return
    for key, values in overrides.items():
        for v in values:
            case.param(key).check(v)


def _write(tmp_path: Path, data: str | bytes) -> Path:
    path = tmp_path / "study.toml"
    if isinstance(data, bytes):
        path.write_bytes(data)
    else:
        path.write_text(data, encoding="utf-8", errors="surrogatepass")
    return path


TOML_LINES = st.lists(st.one_of(
    st.sampled_from(['case = "couette"', 'case = "diffusion"', 'tier = "smoke"', "[params]",
                     "[grid]", "[[runs]]", "[tolerances]", 'solvers = ["reference"]',
                     "jobs = 2", 'name = "x"', "l2_error = 0.05"]),
    st.tuples(st.sampled_from(["l0", "laplacian", "re_ratio", "seed", "weight", "dt", "case",
                               "name", "jobs", "tier", "out", "cases", "max"]),
              st.one_of(NUMBERISH, st.text(max_size=12).map(json.dumps),
                        st.lists(NUMBERISH, max_size=3).map(lambda xs: "[" + ", ".join(
                            json.dumps(x) for x in xs) + "]"))).map(lambda kv: f"{kv[0]} = "
                                                                    f"{kv[1]}"),
    st.text(max_size=30)), max_size=8).map("\n".join)


@SETTINGS
@given(text=st.one_of(TOML_LINES, st.text(max_size=200)))
def test_study_text_raises_only_own_errors(tmp_path: Path, text: str) -> None:
    try:
        load_study(_write(tmp_path, text), max_runs=200)
    except MpsbenchError:
        pass


@SETTINGS
@given(data=st.binary(max_size=200))
def test_study_bytes_raise_only_own_errors(tmp_path: Path, data: bytes) -> None:
    try:
        load_study(_write(tmp_path, data), max_runs=200)
    except MpsbenchError:
        pass


TOML_VALUE = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30),
              st.floats(allow_nan=True), st.text(max_size=10),
              st.sampled_from(["couette", "diffusion", "xu-jin", "wf2", "smoke", "1/40", "1/0"])),
    lambda inner: st.one_of(st.lists(inner, max_size=3),
                            st.dictionaries(st.sampled_from(["l0", "laplacian", "weight",
                                                             "re_ratio", "max", "min", "x"]),
                                            inner, max_size=3)),
    max_leaves=8,
).filter(lambda v: v is not None)


@SETTINGS
@given(data=st.dictionaries(st.one_of(st.sampled_from(list(TOP_KEYS)), st.text(max_size=5)),
                            TOML_VALUE, max_size=6))
def test_study_tables_raise_only_own_errors(data: dict[str, Any]) -> None:
    try:
        parse_study(data, max_runs=200)
    except MpsbenchError:
        pass


@SETTINGS
@given(text=st.one_of(st.text(max_size=300), st.lists(st.lists(
    st.one_of(st.text(alphabet=string.printable, max_size=8), NUMBERISH), min_size=1,
    max_size=5), max_size=5).map(lambda rows: "\n".join(",".join(r) for r in rows))))
def test_baseline_csv_raises_only_own_errors(tmp_path: Path, text: str) -> None:
    path = tmp_path / "results.csv"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        load_results(path)
    except MpsbenchError:
        pass


JSONISH = st.recursive(
    st.one_of(st.none(), st.booleans(), st.floats(), st.integers(), st.text(max_size=12)),
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(st.sampled_from(
                                ["case", "solver", "run_id", "status", "l2_error", "x"]),
                                inner, max_size=5)),
    max_leaves=12)


@SETTINGS
@given(data=JSONISH, raw=st.booleans())
def test_records_and_baselines_raise_only_own_errors(tmp_path: Path, data: Any,
                                                     raw: bool) -> None:
    text = json.dumps(data)
    rec = tmp_path / "runs" / "x.json"
    rec.parent.mkdir(exist_ok=True)
    rec.write_text(text[: len(text) // 2] if raw else text)
    try:
        read_record(rec)
    except MpsbenchError:
        pass
    base = tmp_path / "results.json"
    base.write_text(text)
    try:
        load_results(base)
    except MpsbenchError:
        pass


HREF = re.compile(r'<a href="([^"]*)"')
LINKISH = st.lists(st.one_of(
    st.text(max_size=10),
    st.tuples(st.text(alphabet=string.ascii_letters + " ", max_size=6),
              st.one_of(st.sampled_from(["javascript:alert(1)", "JaVaScRiPt:x", " javascript:x",
                                         "data:text/html,x", "vbscript:x", "//evil.example",
                                         "java\tscript:x", "file:///etc/passwd", "report.md",
                                         "https://example.org/a", "#top", "a/b:c"]),
                        st.text(max_size=15))).map(lambda t: f"[{t[0] or 'x'}]({t[1]})"),
    st.sampled_from(["`", "**", "_", "*", "&", "<", ">", "\n", "|", "#"])), max_size=8).map("".join)


@SETTINGS
@given(text=LINKISH)
def test_rendered_links_are_only_http_relative_or_anchors(text: str) -> None:
    for page in (_inline(text), markdown_html(text)):
        for href in HREF.findall(page):
            assert safe_href(href), (text, href)
            assert not href.lower().lstrip().startswith(("javascript", "data", "vbscript"))
        assert "<script" not in page.lower()
    md = md_escape(text)
    assert "<" not in re.sub(r"(`+)(.+?)\1", "", md, flags=re.S)  # no HTML outside code


def test_markdown_escape_keeps_comparisons_readable() -> None:
    """Only what can open a tag or an entity is escaped: arrows and >= stay as written."""
    assert md_escape("0.103 U -> 0.049 U, T >= 8 s") == "0.103 U -> 0.049 U, T >= 8 s"
    assert md_escape("a <b> & c") == "a &lt;b> &amp; c"


def test_the_built_in_cases_are_registered() -> None:
    assert set(BUILTIN) <= set(CASES.names())
