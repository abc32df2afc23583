"""Hostile and broken input (issue #19): every bad input is one line and exit 2 (or a run
recorded as failed with its cause), never a traceback, never a write outside ``--out``, never a
record lost.

The table :data:`BAD` drives one test over every input; each entry builds its files in a
sandbox nested a few folders deep (so a path that climbs out of ``--out`` lands somewhere the
test looks), runs the command in this process, and the test then checks the exit status, the
error line, the absence of a traceback and that no file changed outside ``--out`` (and, for a
refused command, none inside either).
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from mpsbench import cli
from mpsbench.cases import CASES, Case, CaseCheck, CaseRun, Param
from mpsbench.errors import MpsbenchError
from mpsbench.results.lock import LOCK_FILE
from mpsbench.run.protocol import SOLVERS
from tests.fake_cases import ToyCounter, ToyDiffusion

# --------------------------------------------------------------------------- plugin cases


class RaisingCase(Case):
    """A plugin case whose run raises (with a data file that is not UTF-8, say)."""

    name = "hostile-raises"
    title = "Raises"
    params = (Param("k", 1, "a number", kind=int, minimum=1),)
    tiers = {"smoke": [{"k": [1]}]}
    metrics = {"x": "x"}
    data_file: Path | None = None

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        from mpsbench.validations import experiments

        if self.data_file is None:
            raise RuntimeError("a bug in the plugin")
        experiments.load(self.data_file)
        return CaseRun({"x": 1.0})


class EvilTables(Case):
    """A plugin case whose table name climbs out of the folder."""

    name = "hostile-tables"
    title = "Evil tables"
    params = (Param("k", 1, "a number", kind=int, minimum=1),)
    tiers = {"smoke": [{"k": [1]}]}
    metrics = {"x": "x"}

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        return CaseRun({"x": 1.0})

    def tables(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        import pandas as pd

        return {"../../../escaped-table": pd.DataFrame({"x": [1.0]})}

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        return [CaseCheck("always", True, "ok")]


class LinkCase(Case):
    """A plugin case with a free-text parameter (no choices): any string is a value."""

    name = "hostile-links"
    title = "Links"
    params = (Param("label", "plain", "a free label", kind=str),)
    tiers = {"smoke": [{"label": ["plain"]}]}
    metrics = {"x": "x"}

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        return CaseRun({"x": 1.0})

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        labels = ", ".join(str(r["label"]) for r in records)
        return [CaseCheck("labels", True, f"labels {labels}")]

    def findings(self, records: list[dict[str, Any]]) -> str:
        return "Runs: " + ", ".join(str(r["label"]) for r in records)


PLUGIN_CASES: tuple[Case, ...] = (ToyDiffusion(), ToyCounter(), RaisingCase(), EvilTables(),
                                  LinkCase())


@contextmanager
def plugin_cases() -> Iterator[None]:
    """The toy and hostile cases registered beside the built-ins (which the size guard uses)."""
    CASES.names()
    for case in PLUGIN_CASES:
        CASES.register(case.name, case, replace=True)
    try:
        yield
    finally:
        for case in PLUGIN_CASES:
            CASES.unregister(case.name)


@pytest.fixture(autouse=True)
def registered() -> Iterator[None]:
    with plugin_cases():
        yield


# --------------------------------------------------------------------------- the sandbox


@dataclass
class Box:
    """A sandbox: ``root`` (the current directory of the command) sits three folders below
    ``top`` so an escaping path still lands inside ``top``, where the test looks."""

    top: Path
    root: Path

    @property
    def out(self) -> Path:
        return self.root / "out"

    def write(self, name: str, content: str | bytes) -> Path:
        path = self.root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
        return path


def snapshot(top: Path) -> dict[str, str]:
    """Every file under ``top`` (relative path -> content hash), lock files left out."""
    out = {}
    for path in sorted(top.rglob("*")):
        if path.is_file() and path.name != LOCK_FILE:
            out[path.relative_to(top).as_posix()] = hashlib.sha1(path.read_bytes()).hexdigest()
    return out


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A results folder of the two toy cases (validate all, smoke), copied by the report and
    compare inputs."""
    out = tmp_path_factory.mktemp("template") / "r"
    with plugin_cases(), _only(ToyDiffusion.name, ToyCounter.name):
        assert cli.main(["validate", "all", "--tier", "smoke", "--out", str(out),
                         "--jobs", "1"]) == 0
    return out


@contextmanager
def _only(*names: str) -> Iterator[None]:
    saved = dict(CASES._entries)
    for name in list(CASES._entries):
        if name not in names:
            del CASES._entries[name]
    try:
        yield
    finally:
        CASES._entries.clear()
        CASES._entries.update(saved)


def results_copy(template: Path, box: Box) -> Path:
    shutil.copytree(template, box.out, ignore=shutil.ignore_patterns(LOCK_FILE))
    return box.out


def a_record(box: Box, case: str = ToyDiffusion.name) -> Path:
    return sorted((box.out / case / "runs").glob("*.json"))[0]


def edit_record(path: Path, **changes: Any) -> None:
    rec = json.loads(path.read_text())
    rec.update(changes)
    path.write_text(json.dumps(rec))


# --------------------------------------------------------------------------- the table

Setup = Callable[[Box, Path], list[str]]


@dataclass
class Bad:
    id: str
    setup: Setup  # writes the input files; returns the command line
    fragment: str  # in the error line (or, for kind "failed", in the run's recorded reason)
    kind: str = "exit2"  # or "failed": the command runs, the run is recorded failed


def _validate(*args: str) -> Setup:
    return lambda box, template: ["validate", *args, "--out", str(box.out)]


def _study(text: str | bytes, *extra: str) -> Setup:
    def setup(box: Box, template: Path) -> list[str]:
        path = box.write("study.toml", text)
        return ["study", "run", str(path), "--out", str(box.out), *extra]

    return setup


def _report(mutate: Callable[[Box], Any]) -> Setup:
    def setup(box: Box, template: Path) -> list[str]:
        results_copy(template, box)
        mutate(box)
        return ["report", str(box.out)]

    return setup


def _compare(make: Callable[[Box, Path], Path]) -> Setup:
    def setup(box: Box, template: Path) -> list[str]:
        base = make(box, template)
        return ["compare", str(base), str(template / "results.json"), "--markdown", "-"]

    return setup


def _baseline_text(name: str, edit: Callable[[str], str | bytes]) -> Callable[[Box, Path], Path]:
    def make(box: Box, template: Path) -> Path:
        return box.write(name, edit((template / name).read_text()))

    return make


def _json_metric(value: str) -> Callable[[str], str]:
    """results.json with the first l2_error replaced by a raw JSON token (NaN, Infinity)."""
    def edit(text: str) -> str:
        records = json.loads(text)
        first = next(r for r in records if "l2_error" in r)
        first["l2_error"] = "@@"
        return json.dumps(records).replace('"@@"', value, 1)

    return edit


def _csv_cell(value: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        lines = text.splitlines(keepends=True)
        header = lines[0].rstrip("\n").split(",")
        col = header.index("l2_error")
        cells = lines[1].rstrip("\n").split(",")
        cells[col] = value
        lines[1] = ",".join(cells) + "\n"
        return "".join(lines)

    return edit


def _toy_study(grid: str) -> str:
    return f'case = "{ToyCounter.name}"\ntier = "smoke"\n[grid]\n{grid}\n'


def _data_file(content: bytes | None) -> Setup:
    def setup(box: Box, template: Path) -> list[str]:
        RaisingCase.data_file = None if content is None else box.write("data/bad.csv", content)
        return ["validate", RaisingCase.name, "--tier", "smoke", "--out", str(box.out)]

    return setup


HEADER = (b"# source: a test\n# table: 1\n# units: a=m, b=m\n# nondimensionalisation: none\n")


def _plan_without_run_id(box: Box, template: Path) -> list[str]:
    box.out.mkdir(parents=True)
    (box.out / "plan.json").write_text(json.dumps({"runs": [{"case": "couette"}]}))
    return ["study", "status", str(box.out)]


def _locked_by_a_stranger(box: Box, template: Path) -> list[str]:
    results_copy(template, box)
    holder = _hold_lock(box.out)
    box.holder = holder  # type: ignore[attr-defined]
    return ["report", str(box.out)]


def _symlinked_case(box: Box) -> None:
    outside = box.top / "elsewhere"
    shutil.copytree(box.out / ToyCounter.name, outside)
    shutil.rmtree(box.out / ToyCounter.name)
    (box.out / ToyCounter.name).symlink_to(outside, target_is_directory=True)


def _two_cases_in_one_folder(box: Box) -> None:
    src = a_record(box, ToyCounter.name)
    dest = box.out / ToyDiffusion.name / "runs" / src.name
    shutil.copy(src, dest)


BAD: list[Bad] = [
    # ---- command line: parameters
    Bad("set-division-by-zero", _validate("diffusion", "--set", "l0=1/0"), "l0 = '1/0'"),
    Bad("set-overflow", _validate("diffusion", "--set", "l0=1e999"), "l0 = '1e999'"),
    Bad("set-nan", _validate("diffusion", "--set", "l0=nan"), "l0 = 'nan'"),
    Bad("set-huge-fraction", _validate("diffusion", "--set", "l0=1e308/1e-308"),
        "l0 = '1e308/1e-308'"),
    Bad("set-unknown-parameter", _validate("diffusion", "--set", "nosuch=1"),
        "has no parameter 'nosuch'"),
    Bad("set-without-value", _validate("diffusion", "--set", "l0"), "expected KEY=VALUE"),
    Bad("set-bad-choice", _validate("diffusion", "--set", "laplacian=<script>"),
        "laplacian = '<script>'"),
    Bad("unknown-case", _validate("nosuchcase"), "unknown case 'nosuchcase'"),
    Bad("unknown-solver", _validate("diffusion", "--solver", "../../etc"),
        "unknown solver '../../etc'"),
    Bad("jobs-zero", _validate("diffusion", "--jobs", "0"), "--jobs = 0"),
    # ---- command line: the output folder
    Bad("out-is-a-file", lambda box, t: ["validate", "toy-counter", "--tier", "smoke", "--out",
                                         str(box.write("taken", "x"))], "is a file"),
    Bad("out-below-a-file", lambda box, t: ["validate", "toy-counter", "--tier", "smoke",
                                            "--out", str(box.write("taken", "x") / "sub")],
        "which is a file"),
    Bad("out-in-use", lambda box, t: _locked_validate(box), "in use by another mpsbench"),
    # ---- command line: size guard
    Bad("memory-1e8-particles", _validate("diffusion", "--tier", "smoke", "--set", "l0=1e-4",
                                          "--set", "dt=1e-9"), "more than this machine's"),
    Bad("dt-above-stability-limit", _validate("diffusion", "--tier", "smoke", "--set",
                                              "l0=1e-3"), "above the explicit stability limit"),
    Bad("particles-need-yes", _validate("diffusion", "--tier", "smoke", "--set", "l0=1/1100",
                                        "--set", "dt=1e-6"), "give --yes"),
    Bad("runs-need-yes", _validate("toy-counter", "--tier", "smoke", "--set",
                                   "k=" + ",".join(str(k) for k in range(1, 6002))),
        "6,001 runs, more than 5,000"),
    Bad("bench-memory", lambda box, t: ["bench", "--n", "100000000", "--solver", "reference"],
        "more than this machine's"),
    Bad("bench-too-few", lambda box, t: ["bench", "--n", "10"], "--n 10 is not allowed"),
    Bad("check-unknown-solver", lambda box, t: ["check", "nosuch"], "unknown solver 'nosuch'"),
    # ---- study files
    Bad("study-not-utf8", _study(b'case = "couette"\nname = "\xff\xfe"\n'), "not UTF-8 text"),
    Bad("study-division-by-zero", _study('case = "couette"\n[params]\nl0 = "1/0"\n'),
        'params.l0: "1/0" is not allowed'),
    Bad("study-not-toml", _study("case = \n"), "not valid TOML"),
    Bad("study-huge-integer", _study('case = "couette"\n[params]\nseed = ' + "9" * 5000 + "\n"),
        "not valid TOML"),
    Bad("study-bad-name", _study('name = "../../escape"\ncase = "couette"\n'),
        'name: "../../escape" is not allowed'),
    Bad("study-unknown-key", _study('case = "couette"\nteir = "smoke"\n'), "did you mean"),
    Bad("study-huge-grid", _study(_toy_study("k = [" + ", ".join(map(str, range(1, 6002)))
                                             + "]")), "more than 5,000"),
    Bad("study-out-is-a-file", lambda box, t: ["study", "run", str(box.write(
        "s.toml", _toy_study("k = [1]"))), "--out", str(box.write("taken", "x"))], "is a file"),
    Bad("study-missing-file", lambda box, t: ["study", "run", str(box.root / "none.toml")],
        "no such file"),
    Bad("study-status-plan-without-run-id", _plan_without_run_id, "lacks 'run_id'"),
    # ---- data files (read inside a run: the run is recorded failed with the cause)
    Bad("data-not-utf8", _data_file(b"# source: x\n\xff\xfe\n"), "not UTF-8 text", "failed"),
    Bad("data-truncated-row", _data_file(HEADER + b"a,b\n1,2\n3\n"), "data row 3 has 1 values",
        "failed"),
    Bad("data-nan", _data_file(HEADER + b"a,b\nnan,1\n"), "is not a finite number", "failed"),
    # ---- baselines for compare
    Bad("baseline-truncated-csv", _compare(_baseline_text("results.csv", lambda s: s[:-40])),
        "truncated"),
    Bad("baseline-csv-short-row", _compare(_baseline_text(
        "results.csv", lambda s: s + "toy-counter,reference\n")), "fields, the header"),
    Bad("baseline-csv-nan", _compare(_baseline_text("results.csv", _csv_cell("nan"))),
        "l2_error = 'nan' is not a finite number"),
    Bad("baseline-json-nan", _compare(_baseline_text("results.json", _json_metric("NaN"))),
        "l2_error = nan is not a finite number"),
    Bad("baseline-json-infinity", _compare(_baseline_text("results.json",
                                                          _json_metric("-Infinity"))),
        "is not a finite number"),
    Bad("baseline-json-truncated", _compare(_baseline_text("results.json", lambda s: s[:-30])),
        "truncated or corrupt JSON"),
    Bad("baseline-not-utf8", _compare(_baseline_text("results.csv",
                                                     lambda s: s.encode() + b"\xff\n")),
        "not UTF-8"),
    Bad("baseline-folder-broken-record", lambda box, t: [
        "compare", str(_broken_runs(box, t)), str(t / "results.json"), "--markdown", "-"],
        "truncated or corrupt JSON"),
    # ---- results folders for report
    Bad("report-truncated-record", _report(lambda box: a_record(box).write_text('{"case": "to')),
        "truncated or corrupt JSON"),
    Bad("report-solver-climbs-out", _report(lambda box: edit_record(a_record(box),
                                                                    solver="../../../x")),
        "solver = '../../../x' is not allowed"),
    Bad("report-solver-absolute", _report(lambda box: edit_record(a_record(box),
                                                                  solver="/absolute/path")),
        "solver = '/absolute/path' is not allowed"),
    Bad("report-case-climbs-out", _report(lambda box: edit_record(a_record(box),
                                                                  case="../../x")),
        "case = '../../x' is not allowed"),
    Bad("report-run-id-not-file-name", _report(lambda box: edit_record(a_record(box),
                                                                       run_id="other")),
        "is not the file's name"),
    Bad("report-nan-metric", _report(lambda box: a_record(box).write_text(
        a_record(box).read_text().replace('"l2_error": ', '"l2_error": NaN, "was": '))),
        "l2_error = nan is not a finite number"),
    Bad("report-bad-status", _report(lambda box: edit_record(a_record(box), status="bogus")),
        "status = 'bogus' is not one of"),
    Bad("report-record-not-utf8", _report(lambda box: a_record(box).write_bytes(b"\xff\xfe{}")),
        "not UTF-8"),
    Bad("report-corrupt-checks-json", lambda box, t: _corrupt_checks(box, t),
        "checks.json: truncated or corrupt"),
    Bad("report-corrupt-manifest", _report(lambda box: (box.out / "manifest.json").write_text(
        "{")), "manifest.json: unreadable or truncated"),
    Bad("report-two-cases-one-folder", _report(_two_cases_in_one_folder), "one case per folder"),
    Bad("report-symlink-out-of-folder", _report(_symlinked_case), "outside the results folder"),
    Bad("report-in-use", _locked_by_a_stranger, "in use by another mpsbench"),
    # ---- plugins
    Bad("plugin-case-raises", _data_file(None), "RuntimeError: a bug in the plugin", "failed"),
    Bad("plugin-table-climbs-out", lambda box, t: [
        "validate", EvilTables.name, "--tier", "smoke", "--out", str(box.out)],
        "table name '../../../escaped-table' is not allowed", "section"),
    Bad("plugin-broken-solver", lambda box, t: _broken_solver(box), "could not be loaded"),
]


def _locked_validate(box: Box) -> list[str]:
    box.out.mkdir(parents=True)
    box.holder = _hold_lock(box.out)  # type: ignore[attr-defined]
    return ["validate", "toy-counter", "--tier", "smoke", "--out", str(box.out)]


def _hold_lock(folder: Path) -> Any:
    """Another process holding the folder's lock (POSIX locks never conflict in one process)."""
    import subprocess
    import sys

    holder = subprocess.Popen(
        [sys.executable, "-c", "import fcntl, sys, time; fh = open(sys.argv[1], 'a+'); "
         "fcntl.lockf(fh.fileno(), fcntl.LOCK_EX); fh.write('4242: a test'); fh.flush(); "
         "print('locked', flush=True); time.sleep(60)", str(folder / LOCK_FILE)],
        stdout=subprocess.PIPE, text=True)
    assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
    return holder


def _broken_runs(box: Box, template: Path) -> Path:
    folder = box.root / "base"
    shutil.copytree(template / ToyCounter.name, folder)
    (folder / "results.json").unlink()
    (folder / "results.csv").unlink()
    sorted((folder / "runs").glob("*.json"))[0].write_text('{"status": "comp')
    return folder


def _corrupt_checks(box: Box, template: Path) -> list[str]:
    results_copy(template, box)
    CASES.unregister(ToyCounter.name)  # its code is gone: shown from its files
    (box.out / ToyCounter.name / "checks.json").write_text('[{"name": "drift small", "pas')
    return ["report", str(box.out)]


def _broken_solver(box: Box) -> list[str]:
    SOLVERS.register("hostile-broken", "no_such_module_for_hostile:Solver", origin="user")
    box.cleanup = lambda: SOLVERS.unregister("hostile-broken")  # type: ignore[attr-defined]
    return ["validate", "toy-counter", "--tier", "smoke", "--solver", "hostile-broken", "--out",
            str(box.out)]


def test_the_table_has_every_kind_of_input() -> None:
    assert len(BAD) >= 40
    assert len({b.id for b in BAD}) == len(BAD)
    prefixes = {b.id.split("-")[0] for b in BAD}
    assert {"set", "out", "study", "data", "baseline", "report", "plugin"} <= prefixes


@pytest.mark.parametrize("bad", BAD, ids=[b.id for b in BAD])
def test_bad_input(bad: Bad, template: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                   capsys: pytest.CaptureFixture[str]) -> None:
    box = Box(tmp_path, tmp_path / "a" / "b" / "box")
    box.root.mkdir(parents=True)
    monkeypatch.chdir(box.root)
    try:
        argv = bad.setup(box, template)
        before = snapshot(box.top)
        status = cli.main(argv)
        after = snapshot(box.top)
    finally:
        holder = getattr(box, "holder", None)
        if holder is not None:
            holder.kill()
            holder.wait()
        getattr(box, "cleanup", lambda: None)()
    err = capsys.readouterr().err
    assert "Traceback" not in err
    out_prefix = box.out.relative_to(box.top).as_posix() + "/"
    outside = {k: v for k, v in after.items() if not k.startswith(out_prefix)}
    assert outside == {k: v for k, v in before.items() if not k.startswith(out_prefix)}, \
        "a file outside --out was written"
    if bad.kind == "exit2":
        assert status == 2, err
        errors = [line for line in err.splitlines() if ": error: " in line]
        assert len(errors) == 1 and err.rstrip("\n").endswith(errors[0]), err
        assert bad.fragment in errors[0], errors[0]
        assert after == before, "a refused command changed a file"
    elif bad.kind == "failed":  # the run is recorded failed, with the cause, the rest goes on
        records = [json.loads(p.read_text()) for p in box.out.glob("runs/*.json")]
        assert records and all(r["status"] == "failed" for r in records)
        reason = records[0]["reason"]
        assert bad.fragment in reason, reason
        # where it was raised, by module: no install path
        assert re.search(r"\(at (mpsbench/validations/experiments|tests/test_hostile)\.py:\d+\)",
                         reason), reason
        assert status == 1
    else:  # "section": the case's report fails with the cause; nothing else is written
        assert status == 1
        summary = (box.out / "summary.md").read_text()
        assert bad.fragment in summary, summary


def test_bad_inputs_run_as_a_real_process_are_one_line(tmp_path: Path) -> None:
    """The same path in a fresh interpreter: what a user sees, with and without --debug."""
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "mpsbench", "validate", "diffusion", "--set", "l0=1/0",
           "--out", str(tmp_path / "o")]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    assert out.stderr.splitlines() == [
        "mpsbench validate: error: parameter l0 = '1/0' is not allowed: a float > 0 and <= "
        "0.125"]
    debug = subprocess.run([*cmd, "--debug"], capture_output=True, text=True, timeout=120)
    assert debug.returncode == 1 and "Traceback" in debug.stderr and "ConfigError" in debug.stderr
    assert not (tmp_path / "o").exists()


def test_own_errors_share_one_base_class() -> None:
    from mpsbench.validations.experiments import DataFileError

    from mpsbench.registry import BadNameError, PluginLoadError, UnknownNameError
    from mpsbench.results.compare import CompareError
    from mpsbench.results.executors import ExecutorError
    from mpsbench.results.study_spec import StudyFileError

    for cls in (UnknownNameError, PluginLoadError, BadNameError, CompareError, ExecutorError,
                StudyFileError, DataFileError):
        assert issubclass(cls, MpsbenchError), cls
