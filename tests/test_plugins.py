"""Plugins from outside: entry points in the four groups, broken ones reported, others unharmed.

In process, ``importlib.metadata.entry_points`` (as used by :mod:`mpsbench.registry`) is
replaced by a fake listing good and broken plugins of every group; the catalogs and the CLI
must list the broken ones with their name and reason and keep working for the rest.

The slow test installs ``examples/plugin`` into a fresh virtual environment next to mpsbench and
drives it through the real CLI: models, solvers, check, validate diffusion, and its own tests.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import venv
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import mpsbench.registry as registry_module
from mpsbench import cli
from mpsbench.cases import CASES
from mpsbench.commands.catalog import models_catalog, solvers_catalog
from mpsbench.errors import ConfigError
from mpsbench.physics.config import Models
from mpsbench.physics.gradients import GRADIENTS
from mpsbench.physics.laplacians import LAPLACIANS, KoshizukaOka
from mpsbench.physics.weights import WEIGHTS, WF2
from mpsbench.registry import PluginLoadError
from mpsbench.run.protocol import SOLVERS

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "examples" / "plugin"
HERE = "tests.test_plugins"


# --------------------------------------------------------------------------- fake plugins


class GoodLaplacian(KoshizukaOka):
    """A fine plugin Laplacian (LM1 under another name)."""

    name = "plugin-good"


class NotALaplacian:
    """Has no pair formula."""


class GoodWeight(WF2):
    """A fine plugin weighting function."""

    name = "plugin-wf"


class HalfWeight:
    """A weighting function without W' and W''."""

    @staticmethod
    def w_inside(r: Any, re: float) -> Any:
        return 1.0 - r / re


class NoStepSolver:
    """A solver class missing step() and state()."""

    name = "no-step"
    version = "1"
    capabilities = None

    def setup(self, problem: Any) -> None: ...

    def stable_dt(self) -> float:
        return 1.0


PLUGINS: dict[str, list[tuple[str, str]]] = {
    "mpsbench.laplacians": [
        ("plugin-good", f"{HERE}:GoodLaplacian"),
        ("plugin-missing-module", "mpsbench_no_such_package.models:Lap"),
        ("plugin-no-pair", f"{HERE}:NotALaplacian"),
        ("xu-jin", f"{HERE}:NotALaplacian"),  # cannot shadow a built-in
    ],
    "mpsbench.weights": [
        ("plugin-wf", f"{HERE}:GoodWeight"),
        ("plugin-half-wf", f"{HERE}:HalfWeight"),
    ],
    "mpsbench.solvers": [
        ("plugin-no-step", f"{HERE}:NoStepSolver"),
        ("plugin-typo", f"{HERE}:NoSuchClass"),
        ("plugin-reference", "mpsbench.solvers.reference:ReferenceSolver"),
    ],
    "mpsbench.cases": [
        ("plugin-case-broken", "mpsbench_no_such_package.cases:CASE"),
        ("plugin-case-not-a-case", f"{HERE}:GoodWeight"),
    ],
}
REGISTRIES = {
    "mpsbench.laplacians": LAPLACIANS,
    "mpsbench.weights": WEIGHTS,
    "mpsbench.solvers": SOLVERS,
    "mpsbench.cases": CASES,
    "mpsbench.gradients": GRADIENTS,
}


def fake_entry_points(*, group: str) -> list[SimpleNamespace]:
    return [
        SimpleNamespace(name=name, value=value, group=group,
                        dist=SimpleNamespace(name="fake-plugin-dist"))
        for name, value in PLUGINS.get(group, [])
    ]


@pytest.fixture
def plugins(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The real registries, rescanned with the fake entry points; restored afterwards."""
    saved = {g: (dict(r._entries), r._scanned) for g, r in REGISTRIES.items()}
    for reg in REGISTRIES.values():
        reg.names()  # built-ins and real entry points first, as in a real process
    monkeypatch.setattr(registry_module, "entry_points", fake_entry_points)
    for reg in REGISTRIES.values():
        reg._scanned = False
    yield
    for group, (entries, scanned) in saved.items():
        REGISTRIES[group]._entries = entries
        REGISTRIES[group]._scanned = scanned


def by_name(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Rows by name; the first row of a name (the registered entry, not an ignored one)."""
    out: dict[str, dict[str, Any]] = {}
    for r in rows:
        out.setdefault(r["name"], r)
    return out


def test_models_catalog_lists_broken_plugins_with_reason(plugins: None) -> None:
    cat = models_catalog()
    laps = by_name(cat["laplacians"])
    assert laps["plugin-good"]["available"] and laps["plugin-good"]["error"] is None
    assert laps["plugin-good"]["origin"] == "entry-point:fake-plugin-dist"
    missing = laps["plugin-missing-module"]
    assert not missing["available"]
    assert "plugin-missing-module" in missing["error"]
    assert "ModuleNotFoundError" in missing["error"]
    assert "mpsbench_no_such_package" in missing["error"]
    assert "has no pair(r, w, dw, d2w)" in laps["plugin-no-pair"]["error"]
    # built-ins win over a plugin of the same name, and still work; the plugin is reported
    assert laps["xu-jin"]["origin"] == "builtin" and laps["xu-jin"]["available"]
    (shadow,) = [r for r in cat["laplacians"]
                 if r["name"] == "xu-jin" and r["origin"] != "builtin"]
    assert not shadow["available"]
    assert "fake-plugin-dist" in shadow["error"]
    assert "ignored: the name is taken by builtin Laplacian model 'xu-jin'" in shadow["error"]
    for name in ("koshizuka-oka", "khayyer-gotoh", "xu-jin-analytic"):
        assert laps[name]["available"]
    weights = by_name(cat["weights"])
    assert weights["plugin-wf"]["available"]
    assert "has no dw_inside(r, re)" in weights["plugin-half-wf"]["error"]
    assert all(r["available"] for r in cat["gradients"])


def test_solvers_catalog_lists_broken_plugins_with_reason(plugins: None) -> None:
    rows = by_name(solvers_catalog())
    assert rows["reference"]["available"]
    assert rows["plugin-reference"]["available"]
    assert rows["plugin-reference"]["origin"] == "entry-point:fake-plugin-dist"
    broken = rows["plugin-no-step"]
    assert not broken["available"]
    assert "plugin-no-step" in broken["error"] and "lacks step, state" in broken["error"]
    assert "AttributeError" in rows["plugin-typo"]["error"]
    assert "NoSuchClass" in rows["plugin-typo"]["error"]


def test_cli_lists_broken_plugins_and_exits_0(
    plugins: None, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["models"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if "plugin-missing-module" in x)
    assert "[unavailable:" in line and "ModuleNotFoundError" in line
    assert "plugin-good" in out and "xu-jin-analytic" in out
    assert cli.main(["solvers"]) == 0
    out = capsys.readouterr().out
    assert "plugin-no-step  [unavailable]" in out and "lacks step, state" in out
    assert "plugin-reference" in out
    assert cli.main(["solvers", "--json"]) == 0
    rows = by_name(json.loads(capsys.readouterr().out))
    assert rows["plugin-reference"]["available"] and not rows["plugin-typo"]["available"]


def test_cli_validate_list_shows_broken_cases(
    plugins: None, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["validate", "--list"]) == 0
    out = capsys.readouterr().out
    assert "plugin-case-broken" in out and "[unavailable]" in out
    assert "must be a mpsbench.cases.Case instance" in out


def test_plugin_models_are_usable_by_name(plugins: None) -> None:
    m = Models(laplacian="plugin-good", weight="plugin-wf")
    assert m.laplacian == "plugin-good"
    with pytest.raises(PluginLoadError, match="plugin-missing-module.*ModuleNotFoundError"):
        LAPLACIANS.get("plugin-missing-module")


def test_study_file_with_a_broken_plugin_fails_before_any_run(
    plugins: None, tmp_path: Path
) -> None:
    from mpsbench.results.study_spec import StudyFileError, load_study
    from tests.test_studyfile import TOY, register_toy

    register_toy()  # removed again with the other registry changes by the fixture
    path = tmp_path / "s.toml"
    path.write_text(f'case = "{TOY}"\ntier = "smoke"\nsolvers = ["reference", "plugin-no-step"]\n'
                    '[grid]\nlaplacian = ["plugin-good", "plugin-missing-module"]\n')
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    problems = info.value.problems
    assert len(problems) == 2, problems
    assert problems[0].startswith("solvers[1]: solver 'plugin-no-step'")
    assert "lacks step, state" in problems[0]
    assert problems[1].startswith("grid.laplacian[1]: Laplacian model 'plugin-missing-module'")
    assert "ModuleNotFoundError" in problems[1]


def test_a_broken_solver_plugin_is_a_usage_error(
    plugins: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["validate", "diffusion", "--solver", "plugin-no-step", "--tier", "smoke",
                     "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "plugin-no-step" in err and "lacks step, state" in err


def test_example_plugin_in_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """The example plugin's classes, registered by hand, pass the conformance kit."""
    testing = pytest.importorskip("mpsbench.testing")
    monkeypatch.syspath_prepend(str(PLUGIN / "src"))
    from mpsbench_example.laplacian import LocalKoshizukaOka
    from mpsbench_example.solver import ExampleSolver

    from mpsbench.physics.neighbours import build_pairs
    from mpsbench.physics.operators import lattice_constants, lattice_pairs
    from mpsbench.physics.weights import get_weight

    pos, box = lattice_pairs(10, 0.1)
    w = get_weight("wf2")
    pairs = build_pairs(pos, 0.31, box)
    n0, lam = lattice_constants(w, 3.1, 0.1)
    local = LocalKoshizukaOka().coefficients(pairs, w, 0.31, n0, lam)
    lm1 = KoshizukaOka().coefficients(pairs, w, 0.31, n0, lam)
    np.testing.assert_allclose(local, lm1, rtol=1e-12, atol=1e-12)  # equal on a full lattice

    saved = LAPLACIANS._entries.get("ko-local")
    LAPLACIANS.register("ko-local", LocalKoshizukaOka, replace=True, origin="user")
    try:
        results = testing.check_solver(ExampleSolver, on_fail="raise")
        assert any(r.check == "check_uniform_diffusion_ko-local" and r.outcome == "pass"
                   for r in results)
    finally:
        LAPLACIANS.unregister("ko-local")
        if saved is not None:
            LAPLACIANS._entries["ko-local"] = saved


# --------------------------------------------------------------------------- fresh venv


def _run(cmd: list[str], **kw: Any) -> subprocess.CompletedProcess[str]:
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, **kw)
    tail = f"stdout:\n{out.stdout[-4000:]}\nstderr:\n{out.stderr[-4000:]}"
    assert out.returncode == 0, f"{cmd}\n{tail}"
    return out


@pytest.mark.slow
def test_example_plugin_in_a_fresh_venv(tmp_path: Path) -> None:
    """Install mpsbench and examples/plugin in a new venv; list, check, validate, self-test."""
    env_dir = tmp_path / "venv"
    # system site packages: numpy, scipy, ... come from the running interpreter's environment
    # when they are there, so the install does not download them again
    venv.EnvBuilder(with_pip=True, system_site_packages=False).create(env_dir)
    py = str(env_dir / "bin" / "python")
    exe = env_dir / "bin" / "mpsbench"
    # the build backend from this environment: no network for build isolation
    _run([py, "-m", "pip", "install", "--quiet", "setuptools>=77"])
    _run([py, "-m", "pip", "install", "--quiet", "--no-build-isolation", str(ROOT)])
    _run([py, "-m", "pip", "install", "--quiet", "--no-build-isolation", f"{PLUGIN}[test]"])
    work = tmp_path / "work"
    work.mkdir()  # run outside the repository: only the installed packages are seen
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}

    models = json.loads(_run([str(exe), "models", "--json"], cwd=work, env=env).stdout)
    lap = by_name(models["laplacians"])["ko-local"]
    assert lap["available"], lap
    assert lap["origin"] == "entry-point:mpsbench-example-plugin"
    solvers = by_name(json.loads(_run([str(exe), "solvers", "--json"], cwd=work, env=env).stdout))
    assert solvers["example"]["available"], solvers["example"]
    assert solvers["example"]["capabilities"]["laplacians"] == ["ko-local"]

    check = _run([str(exe), "check", "example"], cwd=work, env=env)
    assert "FAIL" not in check.stdout

    out = work / "diffusion"
    _run([str(exe), "validate", "diffusion", "--solver", "example", "--tier", "smoke",
          "--set", "laplacian=ko-local", "--out", str(out)], cwd=work, env=env)
    records = json.loads((out / "results.json").read_text())
    assert records and all(r["status"] == "completed" for r in records)
    assert {r["solver"] for r in records} == {"example"}
    assert {r["laplacian"] for r in records} == {"ko-local"}

    # the plugin's own test suite (conformance kit + run_case), as its author would run it
    tests = work / "plugin-tests"
    shutil.copytree(PLUGIN / "tests", tests)
    _run([py, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tests)], cwd=work, env=env)
    assert sys.executable != py


# --------------------------------------------------------------------------- run_case


def test_run_case_by_names_and_with_overrides(tmp_path: Path) -> None:
    from mpsbench.testing.plugins import run_case
    from tests.test_studyfile import TOY, register_toy

    register_toy()
    try:
        result = run_case(TOY, "reference", tier="smoke", re_ratio=[2.0, 3.0], l0="1/20",
                          out=tmp_path, report=True)
        assert len(result.records) == 4  # smoke: 2 weights x 2 radii
        assert {r["l0"] for r in result.records} == {0.05}
        assert [c.name for c in result.checks] == ["toy ran"]
        result.assert_ok()
        assert (tmp_path / "report.md").is_file() and result.outdir == tmp_path
        assert len(result.metric("error")) == 4

        bad = run_case(TOY, "reference", explode=True, weight="wf1")
        assert bad.outdir is None and len(bad.failed_runs) == 1
        with pytest.raises(AssertionError, match="RuntimeError: boom"):
            bad.assert_ok()
        with pytest.raises(ConfigError, match="has no parameter 'lapalcian'"):
            run_case(TOY, "reference", lapalcian="xu-jin")
        with pytest.raises(ConfigError, match="re_ratio = 0.5 is not allowed"):
            run_case(TOY, "reference", re_ratio=0.5)
    finally:
        CASES.unregister(TOY)


def test_run_case_with_an_unregistered_solver_class_and_case() -> None:
    """A solver class and a case object nobody registered: registered for the call only."""
    from mpsbench.solvers.reference import ReferenceSolver

    from mpsbench.testing.plugins import run_case
    from tests.test_studyfile import StudyToy

    class MySolver(ReferenceSolver):
        name = "my-solver"

    class MyCase(StudyToy):
        name = "my-case"

    result = run_case(MyCase(), MySolver, weight="wf2")
    assert [r["solver"] for r in result.records] == ["my-solver"]
    assert result.records[0]["case"] == "my-case" and result.failed_runs == []
    assert "my-solver" not in SOLVERS and "my-case" not in CASES
    # an instance: fresh copies per run, under a free name when its own is taken
    result = run_case(MyCase(), ReferenceSolver(), weight="wf1")
    assert result.solver == "reference-under-test" and not result.failed_runs
    assert "reference-under-test" not in SOLVERS
