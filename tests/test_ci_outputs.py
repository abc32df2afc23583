"""Outputs for CI: ``validate --junit-xml``, ``compare --json`` and ``$GITHUB_STEP_SUMMARY``.

The JUnit files are read back with junitparser (the parser CI report tools build on) and their
structure is held against the JUnit schema's (testsuites > testsuite > testcase, counts that
add up); the comparison JSON is loaded back into a Comparison whose counts and text summary
equal the ones the command computed.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from junitparser import Error, Failure, JUnitXml, Skipped

from mpsbench import cli
from mpsbench.cases import CaseCheck
from mpsbench.results.case_report import Rendered
from mpsbench.results.compare import Change, CompareError, Comparison, compare, load_results
from mpsbench.results.compare import summary_line as compare_summary_line
from mpsbench.results.compare_json import SCHEMA, comparison_from_json, comparison_to_json
from mpsbench.results.junit import check_outcome, junit_tree
from mpsbench.results.sections import CaseSection, SolverSection
from mpsbench.results.step_summary import ENV, append_step_summary
from tests.fake_cases import Shaky, ToyCounter, ToyDiffusion, only_cases


class NoSmoke(ToyCounter):
    """A case without a smoke tier: 'validate all --tier smoke' cannot plan it."""

    name = "no-smoke"
    tiers = {"quick": [{"k": [1]}]}


@pytest.fixture(autouse=True)
def no_step_summary(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(ENV, raising=False)  # a test run inside GitHub Actions writes nothing


@pytest.fixture
def toys() -> Iterator[tuple[ToyDiffusion, ToyCounter]]:
    diffusion, counter = ToyDiffusion(), ToyCounter()
    with only_cases(diffusion, counter):
        yield diffusion, counter


def validate(out: Path, *extra: str) -> int:
    return cli.main(["validate", "all", "--tier", "smoke", "--out", str(out), "--jobs", "1",
                     *extra])


def outcome(case: Any) -> str:
    kinds = {type(r) for r in case.result}
    if not kinds:
        return "passed"
    assert len(kinds) == 1, kinds
    return {Failure: "failure", Error: "error", Skipped: "skipped"}[kinds.pop()]


def suites(path: Path) -> dict[str, dict[str, Any]]:
    """name -> {testcase name -> junitparser TestCase} of a JUnit file."""
    xml = JUnitXml.fromfile(str(path))
    return {s.name: {c.name: c for c in s} for s in xml}


def assert_schema_structure(path: Path) -> None:
    """Element names and counts as the JUnit schema has them (what Jenkins and GitLab read)."""
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    total = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    for suite in root:
        assert suite.tag == "testsuite" and suite.get("name")
        cases = suite.findall("testcase")
        assert [c.tag for c in suite if c.tag != "properties"] == ["testcase"] * len(cases)
        counts = {"tests": len(cases),
                  "failures": sum(c.find("failure") is not None for c in cases),
                  "errors": sum(c.find("error") is not None for c in cases),
                  "skipped": sum(c.find("skipped") is not None for c in cases)}
        assert {k: int(suite.get(k, -1)) for k in counts} == counts, suite.get("name")
        for case in cases:
            time = case.get("time")
            assert case.get("name") and case.get("classname") and time is not None
            assert float(time) >= 0
            results = [e.tag for e in case if e.tag in ("failure", "error", "skipped")]
            assert len(results) <= 1
            for e in case:
                if e.tag in ("failure", "error"):
                    assert e.get("message") and e.get("type")
        for key in total:
            total[key] += counts[key]
    assert {k: int(root.get(k, -1)) for k in total} == total


# --------------------------------------------------------------------------- JUnit XML


def test_validate_junit_xml_maps_runs_checks_and_unavailable_cases(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    junit = tmp_path / "ci" / "junit.xml"
    with only_cases(Shaky(), ToyCounter(), NoSmoke()):
        assert validate(tmp_path / "r", "--junit-xml", str(junit)) == 1
    assert f"junit:  {junit}" in capsys.readouterr().out
    assert_schema_structure(junit)
    got = suites(junit)
    assert set(got) == {"shaky[reference]", "toy-counter[reference]", "no-smoke"}

    shaky = got["shaky[reference]"]
    runs = {name: case for name, case in shaky.items() if name.startswith("run ")}
    assert len(runs) == 3 and len(shaky) == 6  # one per run and one per check
    by_mode = {next(m for m in ("ok", "diverge", "raise") if f"mode={m}" in n): c
               for n, c in runs.items()}
    assert outcome(by_mode["ok"]) == "passed"
    assert outcome(by_mode["diverge"]) == "failure"
    assert by_mode["diverge"].result[0].message == "velocity above 100 m/s at step 3"
    assert by_mode["diverge"].result[0].type == "diverged"
    assert outcome(by_mode["raise"]) == "error"
    assert by_mode["raise"].result[0].type == "failed"
    assert "RuntimeError: solver crashed" in by_mode["raise"].result[0].message
    assert "\x1b" not in junit.read_text()
    assert "mode = ok" in (by_mode["ok"].system_out or "")
    assert float(by_mode["ok"].time) == pytest.approx(0.01, abs=1e-3)  # the run's wall time
    assert outcome(shaky["check value is one"]) == "passed"
    assert outcome(shaky["check never holds"]) == "failure"
    assert shaky["check never holds"].result[0].message == "0.3 > 0.1"
    assert outcome(shaky["check cannot decide"]) == "skipped"
    assert "needs two resolutions" in shaky["check cannot decide"].result[0].message

    assert [outcome(c) for c in got["toy-counter[reference]"].values()] == ["passed", "passed"]
    (broken,) = got["no-smoke"].values()
    assert outcome(broken) == "error" and broken.result[0].type == "unavailable"
    assert "tier = 'smoke' is not allowed" in broken.result[0].message

    root = ET.parse(junit).getroot()
    properties = root.find("testsuite[@name='shaky[reference]']/properties")
    assert properties is not None
    props = {p.get("name"): p.get("value") for p in properties}
    assert props["case"] == "shaky" and props["solver"] == "reference"
    assert props["tier"] == "smoke" and props["mpsbench_version"]


def test_junit_of_one_case(toys: object, tmp_path: Path) -> None:
    junit = tmp_path / "one.xml"
    assert cli.main(["validate", "toy-diffusion", "--tier", "smoke", "--out",
                     str(tmp_path / "r"), "--junit-xml", str(junit)]) == 0
    assert_schema_structure(junit)
    (suite,) = JUnitXml.fromfile(str(junit))
    assert suite.name == "toy-diffusion[reference]"
    # two runs, two gates (one undecided) and the toy's claim (supported)
    assert (suite.tests, suite.failures, suite.errors, suite.skipped) == (5, 0, 0, 1)
    props = {p.name: p.value for p in suite.properties()}
    assert props["solver_version"] == "1.0" and props["case"] == "toy-diffusion"


def test_unwritable_junit_path_is_a_usage_error(toys: object, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert validate(tmp_path / "r", "--junit-xml", str(blocker / "junit.xml")) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("mpsbench validate: error: --junit-xml ")
    assert (tmp_path / "r" / "summary.md").is_file()  # the report stands


def test_check_outcome_follows_a_checks_kind() -> None:
    assert check_outcome(CaseCheck("a", True, "ok")) == ("passed", "ok")
    assert check_outcome(CaseCheck("a", False, "0.3 > 0.1")) == ("failed", "0.3 > 0.1")
    assert check_outcome(CaseCheck("a", None, "no data"))[0] == "skipped"

    claim = CaseCheck("paper says", False, "0.3 > 0.1", kind="claim")
    outcome_, message = check_outcome(claim)
    assert outcome_ == "skipped" and "does not gate" in message and "0.3 > 0.1" in message
    assert check_outcome(claim, strict_claims=True) == ("failed", "0.3 > 0.1")


def test_junit_tree_of_a_section_without_records() -> None:
    rendered = Rendered([], [], {}, [], "", Path("."))
    sec = CaseSection("empty", solvers=[SolverSection("reference", "1.0", rendered)],
                      error="no runs were planned for this tier")
    root = junit_tree([sec], {"tier": "smoke"})
    assert root.get("errors") == "1" and root.get("tests") == "1"


# --------------------------------------------------------------------------- compare --json


def test_compare_json_round_trips(toys: tuple[ToyDiffusion, ToyCounter], tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    base, cur = tmp_path / "base", tmp_path / "cur"
    assert validate(base) == 0
    toys[0].error_scale = 2.0  # a model change doubling the error: a regression
    toys[1].drift_scale = 0.5  # and an improvement
    assert validate(cur) == 0
    capsys.readouterr()
    assert cli.main(["compare", str(base), str(cur), "--json"]) == 1
    captured = capsys.readouterr()
    doc = json.loads(captured.out)  # stdout holds the document and nothing else
    assert "REGRESSION" in captured.err and "baseline:" in captured.err
    assert doc["schema"] == SCHEMA and doc["verdict"] == "regression"
    assert doc["baseline"]["path"] == str(base) and doc["baseline"]["records"] == 3
    assert doc["baseline"]["tier"] == "smoke"

    rebuilt = comparison_from_json(doc)
    assert {k: rebuilt.count(k) for k in doc["counts"]} == doc["counts"]
    direct = compare(load_results(base), load_results(cur))
    assert compare_summary_line(rebuilt) == compare_summary_line(direct)
    assert rebuilt.changes == direct.changes
    assert doc["counts"]["regression"] == 2 and doc["counts"]["better"] == 1
    assert {c["metric"] for c in doc["changes"] if c["kind"] == "regression"} == {"l2_error"}
    reg = next(c for c in doc["changes"] if c["kind"] == "regression")
    assert reg["relative"] == pytest.approx(1.0)  # doubled
    assert sorted(row["case"] for row in doc["timing"]) == ["toy-counter", "toy-diffusion"]
    assert rebuilt.timing.shape == direct.timing.shape
    assert (cur / "compare.md").is_file()  # the Markdown is still written

    assert cli.main(["compare", str(base), str(base), "--json"]) == 0
    ok = json.loads(capsys.readouterr().out)
    assert ok["verdict"] == "ok" and ok["counts"]["regression"] == 0


def test_compare_json_non_finite_values_and_bad_documents() -> None:
    import pandas as pd

    cmp = Comparison(2, 2, 2, 3, [
        Change("regression", "r1", "l2_error", 0.5, math.inf, "lower, 0.05"),
        Change("info", "r2", "peak", math.nan, 1.0, "info", "new metric"),
        Change("regression", "r2", "status", "completed", "diverged", note="blew up"),
    ], pd.DataFrame())
    doc = json.loads(json.dumps(comparison_to_json(cmp, "a", "b"), allow_nan=False))
    assert doc["changes"][0]["current"] == "Infinity"
    assert doc["changes"][0]["relative"] is None  # not a number: no relative change
    back = comparison_from_json(doc)
    assert back.changes[0].current == math.inf and math.isnan(back.changes[1].baseline)
    assert back.changes[2] == cmp.changes[2] and back.timing.empty
    assert compare_summary_line(back) == compare_summary_line(cmp)

    with pytest.raises(CompareError, match="not a mpsbench.compare/1 document"):
        comparison_from_json({"schema": "other"})
    with pytest.raises(CompareError, match="malformed"):
        comparison_from_json({**doc, "changes": [{"kind": "regression"}]})
    with pytest.raises(CompareError, match="unknown change kind"):
        comparison_from_json({**doc, "changes": [{**doc["changes"][0], "kind": "weird"}]})


# --------------------------------------------------------------------------- step summary


def test_step_summary_appended_by_validate_and_compare(
    toys: tuple[ToyDiffusion, ToyCounter], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    summary = tmp_path / "step_summary.md"
    summary.write_text("earlier step\n")
    base = tmp_path / "base"
    assert validate(base) == 0  # not set: nothing written anywhere
    assert summary.read_text() == "earlier step\n"
    monkeypatch.setenv(ENV, str(summary))
    toys[0].fail_check = True
    assert validate(tmp_path / "cur") == 1
    assert cli.main(["compare", str(base), str(tmp_path / "cur")]) == 0
    text = summary.read_text()
    assert text.startswith("earlier step\n")  # appended, not replaced
    assert "## mpsbench validate (all, tier smoke): FAIL (1/2 cases pass)" in text
    assert "### toy-diffusion: FAIL" in text and "gate failed: l2 error below limit" in text
    assert "**FAIL** l2 error below limit" in text
    assert "| toy-counter" in text  # the overview table
    assert "## mpsbench compare: no regression" in text
    assert text.index("mpsbench validate") < text.index("mpsbench compare")
    assert "](" not in text  # no links into the report folder: they would not resolve


def test_step_summary_cut_at_the_limit_and_unwritable(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "s.md"
    assert append_step_summary("x" * (2 * 1024 * 1024), {ENV: str(target)}) == target
    data = target.read_bytes()
    assert len(data) <= 1024 * 1024 and b"1 MiB step-summary limit" in data
    assert append_step_summary("text", {ENV: str(tmp_path)}) is None  # a folder
    assert "cannot append to GITHUB_STEP_SUMMARY" in capsys.readouterr().err
    assert append_step_summary("text", {}) is None
