"""JUnit XML of a validation (``mpsbench validate ... --junit-xml PATH``), for CI test reports.

One ``<testsuite>`` per (case, solver), named ``<case>[<solver>]``, holding one ``<testcase>``
per run and one per case check:

* a run (``name="run <run id>"``, ``time`` its wall time): passes when it completed; a run that
  *diverged* is a ``<failure type="diverged">`` (the solver ran and blew up), one that *failed*
  (an exception, an unsupported problem, a crash or a time-out) an ``<error type="failed">``;
  the message is the record's reason.  Its ``<system-out>`` lists the run's parameters and
  metrics.  A diverged run is a JUnit failure even when the case passes (a case's verdict rests
  on its checks, which may not need that run), so CI shows it either way.
* a check (``name="check <name>"``): mapped by :func:`check_outcome`, the one place that turns
  a :class:`~mpsbench.cases.CaseCheck` into a test outcome (the pytest plugin uses it too):
  did not hold -> ``<failure type="check">``, undecided -> ``<skipped>``.
* a case that could not be loaded, planned or rendered: one ``<testcase name="case">`` with an
  ``<error type="unavailable">`` and the reason, so a broken case is never a silent pass.

Suite properties: case, solver, solver version, tier, mpsbench version, git commit.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Literal

from mpsbench.cases import CaseCheck
from mpsbench.results.records import atomic_write_text
from mpsbench.results.sections import CaseSection

Outcome = Literal["passed", "failed", "skipped"]

# Record fields that are not a run's parameters or metrics (shown as properties or not at all).
_NOT_SHOWN = frozenset({
    "case", "solver", "solver_version", "tier", "run_id", "status", "reason", "mpsbench_version",
    "python", "numpy_version", "machine", "git_commit",
})
# Characters XML 1.0 cannot carry (a solver's reason may hold terminal escapes or NULs).
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def check_outcome(check: CaseCheck, strict_claims: bool = False) -> tuple[Outcome, str]:
    """How a case check reads in a test report: ``(outcome, message)``.

    Held -> passed; did not hold -> failed; undecided (``passed`` is None: the data to decide
    is missing) -> skipped.  A check whose ``kind`` says it does not gate the case's verdict
    (anything but ``"gate"``; checks without a kind gate) is skipped, not failed, when it did
    not hold: it is reported, and the message says so, but it does not turn CI red (a refuted
    claim under ``strict_claims``, as ``--strict-claims`` asks, does).
    """
    kind = str(getattr(check, "kind", "gate") or "gate")
    if check.passed is True:
        return "passed", check.detail
    if check.passed is None:
        return "skipped", f"undecided: {check.detail}"
    if kind != "gate" and not (strict_claims and kind == "claim"):
        return "skipped", f"did not hold ({kind}; does not gate the verdict): {check.detail}"
    return "failed", check.detail


def clean(text: Any) -> str:
    """``text`` as a string XML 1.0 can hold (invalid characters become U+FFFD)."""
    return _NOT_XML.sub("\ufffd", str(text))


def _value(v: Any) -> str:
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def _run_case(rec: dict[str, Any], classname: str) -> ET.Element:
    rid = str(rec.get("run_id", "?"))
    tc = ET.Element("testcase", name=clean(f"run {rid}"), classname=clean(classname),
                    time=f"{float(rec.get('wall_time_s') or 0.0):.3f}")
    status = str(rec.get("status", "?"))
    reason = clean(rec.get("reason") or status)
    if status == "diverged":
        ET.SubElement(tc, "failure", message=reason, type="diverged").text = reason
    elif status != "completed":
        ET.SubElement(tc, "error", message=reason, type=clean(status)).text = reason
    shown = [f"{k} = {_value(v)}" for k, v in rec.items() if k not in _NOT_SHOWN]
    ET.SubElement(tc, "system-out").text = clean("\n".join([f"status = {status}", *shown]))
    return tc


def _check_case(check: CaseCheck, classname: str, strict_claims: bool = False) -> ET.Element:
    tc = ET.Element("testcase", name=clean(f"check {check.name}"), classname=clean(classname),
                    time="0.000")
    outcome, message = check_outcome(check, strict_claims)
    if outcome == "failed":
        ET.SubElement(tc, "failure", message=clean(message), type="check").text = clean(message)
    elif outcome == "skipped":
        ET.SubElement(tc, "skipped", message=clean(message))
    else:
        ET.SubElement(tc, "system-out").text = clean(message)
    return tc


def _suite(name: str, cases: list[ET.Element], props: dict[str, Any], timestamp: str) -> ET.Element:
    suite = ET.Element("testsuite", name=clean(name))
    counts = {"tests": len(cases), "failures": 0, "errors": 0, "skipped": 0}
    for tc in cases:
        for tag, key in (("failure", "failures"), ("error", "errors"), ("skipped", "skipped")):
            counts[key] += tc.find(tag) is not None
    suite.attrib.update({k: str(v) for k, v in counts.items()})
    suite.set("time", f"{sum(float(tc.get('time', 0)) for tc in cases):.3f}")
    if timestamp:
        suite.set("timestamp", clean(timestamp))
    properties = ET.SubElement(suite, "properties")
    for key, value in props.items():
        if value not in (None, ""):
            ET.SubElement(properties, "property", name=key, value=clean(value))
    suite.extend(cases)
    return suite


def junit_tree(sections: Iterable[CaseSection], manifest: dict[str, Any]) -> ET.Element:
    """The JUnit document of a validation's sections (see the module docstring)."""
    env = manifest.get("environment", {}) or {}
    common = {"tier": manifest.get("tier"), "mpsbench_version": env.get("mpsbench_version"),
              "git_commit": env.get("git_commit")}
    stamp = str(manifest.get("started") or "")
    root = ET.Element("testsuites", name="mpsbench validate")
    for sec in sections:
        if sec.error:
            tc = ET.Element("testcase", name="case", classname=clean(sec.name), time="0.000")
            ET.SubElement(tc, "error", message=clean(sec.error), type="unavailable").text = \
                clean(sec.error)
            root.append(_suite(sec.name, [tc], {"case": sec.name, **common}, stamp))
        for s in sec.solvers:
            classname = f"{sec.name}.{s.solver}"
            cases = [_run_case(r, classname) for r in s.rendered.records]
            cases += [_check_case(c, classname, bool(manifest.get("strict_claims")))
                      for c in s.rendered.checks]
            props = {"case": sec.name, "solver": s.solver, "solver_version": s.version, **common}
            root.append(_suite(f"{sec.name}[{s.solver}]", cases, props, stamp))
    for key in ("tests", "failures", "errors", "skipped"):
        root.set(key, str(sum(int(s.get(key, 0)) for s in root)))
    root.set("time", f"{sum(float(s.get('time', 0)) for s in root):.3f}")
    ET.indent(root)
    return root


def write_junit(
    path: str | Path, sections: Iterable[CaseSection], manifest: dict[str, Any]
) -> Path:
    """Write the JUnit XML file (atomically; parent folders are made)."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    text = ET.tostring(junit_tree(sections, manifest), encoding="unicode")
    atomic_write_text(target, '<?xml version="1.0" encoding="utf-8"?>\n' + text + "\n")
    return target
