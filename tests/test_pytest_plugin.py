"""The pytest plugin (``--mpsbench-solver``, ``--mpsbench-case``): items, outcomes, errors.

Each test runs pytest (pytester, in process) in a temporary folder, as a solver author's suite
would run, and reads the outcome of every item from pytest's own JUnit file.  The plugin is
loaded with ``-p mpsbench.pytest_plugin`` and entry-point autoloading off, so the test holds in
a checkout whose installed metadata predates the ``pytest11`` entry point; the slow workflow
test (tests/test_ci_examples.py) uses the installed entry point in a fresh environment.  The
cases are the toy cases of tests/fake_cases.py, registered by the folder's conftest.py (the
registries are restored afterwards).
"""

from __future__ import annotations

import textwrap
import tomllib
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol

import pytest

# Imported here, so pytester's sys.modules snapshot keeps them between the inner runs (it drops
# what an inner run imported; the next one would import numpy's dependants again).
import mpsbench.pytest_plugin  # noqa: F401
import mpsbench.results.junit  # noqa: F401
import mpsbench.testing.plugins  # noqa: F401
import tests.fake_cases  # noqa: F401
from mpsbench.cases import CASES
from mpsbench.run.protocol import SOLVERS

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parents[1]

CONFTEST = """
import os

# Imported here, so pytester's sys.modules snapshot keeps them between the inner runs (it drops
# what an inner run imported; the next one would import numpy's dependants again).
import mpsbench.pytest_plugin  # noqa: F401
import mpsbench.results.junit  # noqa: F401
import mpsbench.testing.plugins  # noqa: F401
import tests.fake_cases  # noqa: F401
from mpsbench.cases import CASES
from mpsbench.run.protocol import SOLVERS
from tests.fake_cases import Shaky, ToyCounter, ToyDiffusion, ToyReference

toy = ToyDiffusion()
toy.fail_check = os.environ.get("TOY_FAIL_CHECK") == "1"
for case in (toy, ToyCounter(), Shaky()):
    CASES.register(case.name, case, replace=True)


class Hopeful(ToyReference):
    name = "hopeful"
    expected_failures = {"check_api_shape": "we think it breaks"}


SOLVERS.register("hopeful", Hopeful, replace=True)
"""

Run = tuple[int, str, dict[str, tuple[str, str]]]


class Runner(Protocol):
    def __call__(self, *args: str, env: dict[str, str] | None = None) -> Run: ...


@pytest.fixture
def run_pytest(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch) -> Iterator[Runner]:
    """``run(*args, env=...)`` -> exit code, output, {item id: (outcome, message)}."""
    saved = [(reg, dict(reg._entries), reg._scanned) for reg in (CASES, SOLVERS)]
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")
    pytester.makeconftest(CONFTEST)

    def run(*args: str, env: dict[str, str] | None = None) -> Run:
        for key, value in (env or {}).items():
            monkeypatch.setenv(key, value)
        junit = pytester.path / "pytest-junit.xml"
        junit.unlink(missing_ok=True)
        result = pytester.runpytest_inprocess(
            "-p", "mpsbench.pytest_plugin", "-p", "no:cacheprovider", "-rA",
            f"--junit-xml={junit}", *args)
        for key in env or {}:
            monkeypatch.delenv(key)
        outcomes: dict[str, tuple[str, str]] = {}
        if junit.exists():
            for case in ET.parse(junit).getroot().iter("testcase"):
                res = next((e for e in case if e.tag in ("failure", "error", "skipped")), None)
                tag = "passed" if res is None else res.tag
                message = "" if res is None else res.get("message", "")
                outcomes[f"{case.get('classname')}::{case.get('name')}"] = (tag, message)
        output = "\n".join(result.outlines + result.errlines)
        return int(result.ret), output, outcomes

    try:
        yield run
    finally:
        for reg, entries, scanned in saved:
            reg._entries.clear()
            reg._entries.update(entries)
            reg._scanned = scanned


def test_inert_without_options(run_pytest: Runner, pytester: pytest.Pytester) -> None:
    (pytester.path / "test_mine.py").write_text("def test_one():\n    assert True\n")
    code, out, items = run_pytest()
    assert code == 0, out
    assert list(items) == ["test_mine::test_one"]


def test_conformance_checks_become_items(run_pytest: Runner, pytester: pytest.Pytester) -> None:
    (pytester.path / "test_mine.py").write_text("def test_one():\n    assert True\n")
    code, out, items = run_pytest("--mpsbench-solver", "reference",
                                  "--mpsbench-check", "momentum", "--mpsbench-check", "api")
    assert code == 0, out
    assert items == {
        "test_mine::test_one": ("passed", ""),
        "mpsbench-conformance[reference]::check_api_shape": ("passed", ""),
        "mpsbench-conformance[reference]::check_momentum_pgm2": ("passed", ""),
        "mpsbench-conformance[reference]::check_momentum_pgm3": ("passed", ""),
    }
    # -m mpsbench selects the plugin's items ("not mpsbench" all the others)
    code, out, items = run_pytest("--mpsbench-solver", "reference",
                                  "--mpsbench-check", "api", "-m", "mpsbench")
    assert code == 0 and list(items) == ["mpsbench-conformance[reference]::check_api_shape"], out


def test_expected_failures_and_undeclared_capabilities(run_pytest: Runner) -> None:
    code, out, items = run_pytest("--mpsbench-solver", "hopeful", "--mpsbench-check",
                                  "api_shape", "--mpsbench-check", "uniform_diffusion", "-rX")
    assert code == 0, out
    # xfail(strict=False) that passes: pytest reports XPASS, the JUnit file a pass
    assert "XPASS mpsbench-conformance[hopeful]::check_api_shape" in out
    assert items["mpsbench-conformance[hopeful]::check_uniform_diffusion_xu-jin"] == \
        ("passed", "")


def test_ini_options(run_pytest: Runner, pytester: pytest.Pytester) -> None:
    (pytester.path / "pyproject.toml").write_text(textwrap.dedent("""
        [tool.pytest.ini_options]
        mpsbench_solvers = ["reference"]
        mpsbench_checks = ["api_shape"]
        mpsbench_cases = ["toy-counter"]
        mpsbench_tier = "quick"
    """))
    code, out, items = run_pytest()
    assert code == 0, out
    case = "mpsbench-case[toy-counter-reference]::"
    assert sorted(k.rsplit("_", 1)[0] for k in items) == [  # the quick tier: k = 1, 2
        f"{case}check drift small", f"{case}run toy-counter_reference_k=1",
        f"{case}run toy-counter_reference_k=2", "mpsbench-conformance[reference]::check_api",
    ], out


def test_case_runs_and_checks_become_items(run_pytest: Runner, tmp_path: Path) -> None:
    out_dir = tmp_path / "kept"
    code, out, items = run_pytest(
        "--mpsbench-solver", "reference", "--mpsbench-case", "toy-diffusion",
        "--mpsbench-set", "laplacian=xu-jin,koshizuka-oka", "--mpsbench-set", "steps=2",
        "--mpsbench-out", str(out_dir), "-k", "toy")
    assert code == 0, out
    runs = {k: v for k, v in items.items() if "::run " in k}
    assert len(runs) == 2 and all(v == ("passed", "") for v in runs.values()), items
    assert all("steps=2" in k for k in runs)
    checks = {k.split("::")[1]: v for k, v in items.items() if "::check " in k}
    assert checks["check l2 error below limit"] == ("passed", "")
    assert checks["check undecided check"] == ("skipped", "undecided: no data to decide")
    assert (out_dir / "toy-diffusion-reference" / "report.md").is_file()  # --mpsbench-out

    code, out, items = run_pytest("--mpsbench-solver", "reference",
                                  "--mpsbench-case", "toy-diffusion", "-k", "toy",
                                  env={"TOY_FAIL_CHECK": "1"})
    assert code == 1, out
    check = "mpsbench-case[toy-diffusion-reference]::check l2 error below limit"
    assert items[check][0] == "failure" and items[check][1].startswith("worst "), items
    assert "Traceback" not in out


def test_diverged_and_failed_runs_fail_with_their_reason(run_pytest: Runner) -> None:
    code, out, items = run_pytest("--mpsbench-solver", "reference",
                                  "--mpsbench-case", "shaky", "-m", "mpsbench", "-k", "shaky")
    assert code == 1, out
    by_mode = {mode: v for k, v in items.items() for mode in ("ok", "diverge", "raise")
               if f"mode={mode}_" in k}
    assert by_mode["ok"] == ("passed", "")
    assert by_mode["diverge"] == ("failure", "diverged: velocity above 100 m/s at step 3")
    assert by_mode["raise"][0] == "failure"
    assert by_mode["raise"][1].startswith("failed: RuntimeError: solver crashed")
    prefix = "mpsbench-case[shaky-reference]::check "
    assert items[prefix + "never holds"] == ("failure", "0.3 > 0.1")
    assert items[prefix + "cannot decide"] == ("skipped", "undecided: needs two resolutions")


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        (["--mpsbench-solver", "nope"], 2, "unknown solver 'nope'"),
        (["--mpsbench-solver", "reference", "--mpsbench-check", "zzz"], 2,
         "no conformance check matches ['zzz']"),
        (["--mpsbench-solver", "reference", "--mpsbench-case", "nope"], 2,
         "case 'nope' on solver 'reference': unknown case 'nope'"),
        (["--mpsbench-solver", "reference", "--mpsbench-case", "toy-counter", "--mpsbench-tier",
          "huge"], 2, "tier = 'huge' is not allowed"),
        (["--mpsbench-solver", "reference", "--mpsbench-case", "toy-counter", "--mpsbench-set",
          "laplacian=xu-jin"], 2, "case 'toy-counter' on solver 'reference': case "
         "'toy-counter' has no parameter 'laplacian'"),
        (["--mpsbench-case", "toy-counter"], 4, "--mpsbench-case (mpsbench_cases) needs"),
        (["--mpsbench-solver", "reference", "--mpsbench-set", "k"], 4, "expected KEY=VALUE"),
    ],
)
def test_bad_options_are_reported_in_one_line(run_pytest: Runner, args: list[str], code: int,
                                              message: str) -> None:
    got, out, _ = run_pytest(*args)
    assert got == code, out
    assert message in out
    assert "Traceback" not in out and "INTERNALERROR" not in out


def test_pyproject_declares_the_plugin_entry_point() -> None:
    with open(ROOT / "pyproject.toml", "rb") as fh:
        project = tomllib.load(fh)["project"]
    assert project["entry-points"]["pytest11"] == {"mpsbench": "mpsbench.pytest_plugin"}
