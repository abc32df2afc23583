"""Provenance in every record and manifest: machine, versions, commits (issue 18 item 6)."""

from __future__ import annotations

import importlib
import importlib.util
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from mpsbench import cli
from mpsbench.results import provenance
from mpsbench.results.records import ENV_COLUMNS, environment
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases


def git(repo: Path, *args: str) -> str:
    out = subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=repo,
                         capture_output=True, text=True, check=True)
    return out.stdout.strip()


@pytest.fixture
def repo(tmp_path: Path) -> Iterator[Path]:
    """A git checkout holding one committed module, ``provtoy.py``."""
    root = tmp_path / "repo"
    root.mkdir()
    git(root, "init", "-q")
    (root / "provtoy.py").write_text("X = 1\n")
    git(root, "add", "provtoy.py")
    git(root, "commit", "-q", "-m", "one")
    provenance.git_state.cache_clear()
    yield root
    provenance.git_state.cache_clear()


def test_environment_has_every_column_but_the_solvers_commit() -> None:
    env = environment()
    assert set(env) == set(ENV_COLUMNS) - {"solver_commit"}
    assert env["cpu_count"] >= 1 and env["cpu_model"]
    assert env["machine"].endswith(env["cpu_model"])
    np_version = importlib.import_module("numpy").__version__
    assert env["numpy_version"] == np_version and env["python"] == sys.version.split()[0]
    # this test runs from a checkout: mpsbench's commit is known, and dirty is a flag
    head = git(Path(__file__).parent, "rev-parse", "HEAD")
    assert head.startswith(env["git_commit"]) and isinstance(env["git_dirty"], bool)
    assert environment() == env and environment() is not environment()  # cached, a fresh copy


def test_environment_with_solvers_gives_their_version_and_commit() -> None:
    env = environment(["reference", "no-such-solver"])
    ref = env["solvers"]["reference"]
    assert ref["solver_version"]
    assert ref["solver_commit"].split("-")[0] == env["git_commit"]  # a built-in: our checkout
    assert env["solvers"]["no-such-solver"] == {"solver_version": None, "solver_commit": None}


def test_git_state_clean_dirty_untracked_and_foreign(repo: Path, tmp_path: Path) -> None:
    head = git(repo, "rev-parse", "HEAD")
    commit, dirty = provenance.git_state(str(repo / "provtoy.py"))
    assert commit == head[: provenance.COMMIT_CHARS] and dirty is False
    (repo / "scratch.txt").write_text("untracked files are not code\n")
    provenance.git_state.cache_clear()
    assert provenance.git_state(str(repo / "provtoy.py")) == (commit, False)
    (repo / "provtoy.py").write_text("X = 2\n")
    provenance.git_state.cache_clear()
    assert provenance.git_state(str(repo / "provtoy.py")) == (commit, True)
    # a file the checkout does not track (an installed package inside someone's repository)
    (repo / "other.py").write_text("")
    assert provenance.git_state(str(repo / "other.py")) == (None, None)
    (tmp_path / "loose.py").write_text("")
    assert provenance.git_state(str(tmp_path / "loose.py")) == (None, None)


def test_code_commit_of_a_checkout_and_of_a_vcs_install(
    repo: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.syspath_prepend(str(repo))
    try:
        importlib.import_module("provtoy")
        head = git(repo, "rev-parse", "HEAD")[: provenance.COMMIT_CHARS]
        assert provenance.code_commit("provtoy") == head
        (repo / "provtoy.py").write_text("X = 3\n")
        provenance.git_state.cache_clear()
        assert provenance.code_commit("provtoy") == head + "-dirty"
    finally:
        sys.modules.pop("provtoy", None)

    # installed by pip from a git URL: PEP 610 direct_url.json holds the commit
    site = tmp_path / "site"
    (site / "vcstoy").mkdir(parents=True)
    (site / "vcstoy" / "__init__.py").write_text("")
    info = site / "vcstoy-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: vcstoy\nVersion: 1.0\n")
    (info / "top_level.txt").write_text("vcstoy\n")
    (info / "direct_url.json").write_text(json.dumps(
        {"url": "https://example.org/vcstoy.git",
         "vcs_info": {"vcs": "git", "commit_id": "0123456789abcdef0123"}}))
    monkeypatch.syspath_prepend(str(site))
    provenance._distributions.cache_clear()
    try:
        importlib.import_module("vcstoy")
        assert provenance.code_commit("vcstoy") == "0123456789ab"
        (info / "direct_url.json").write_text(json.dumps({"url": "file:///x", "dir_info": {}}))
        assert provenance.code_commit("vcstoy") is None  # a plain install cannot tell
    finally:
        sys.modules.pop("vcstoy", None)
        provenance._distributions.cache_clear()


def test_an_installed_copy_reads_the_commit_its_build_recorded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``pip install .`` copies the code out of the checkout; setup.py's build_py leaves the
    commit in the package (BUILD_COMMIT_FILE), which code_commit reads when git cannot tell."""
    site = tmp_path / "site"
    pkg = site / "buildtoy"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    monkeypatch.syspath_prepend(str(site))
    record = pkg / provenance.BUILD_COMMIT_FILE
    try:
        importlib.import_module("buildtoy.sub")
        assert provenance.code_commit("buildtoy.sub") is None  # no record, no checkout
        record.write_text(json.dumps({"commit": "fedcba9876543210", "dirty": False}))
        assert provenance.build_commit("buildtoy") == ("fedcba987654", False)
        assert provenance.code_commit("buildtoy.sub") == "fedcba987654"  # a module inside it
        record.write_text(json.dumps({"commit": "fedcba9876543210", "dirty": True}))
        assert provenance.code_commit("buildtoy.sub") == "fedcba987654-dirty"
        for hostile in ("not json", "[1, 2]", '{"commit": 5, "dirty": false}',
                        '{"commit": "abc"}', '{"commit": "", "dirty": false}',
                        '{"commit": "abc", "dirty": "no"}'):
            record.write_text(hostile)
            assert provenance.build_commit("buildtoy") == (None, None), hostile
    finally:
        for name in ("buildtoy.sub", "buildtoy"):
            sys.modules.pop(name, None)


def test_setup_py_records_the_checkouts_commit(tmp_path: Path) -> None:
    """setup.py's checkout_state, run on this repository when it is a git checkout, gives what
    git says (the build hook writes exactly that into the wheel)."""
    root = Path(__file__).parents[1]
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True,
                          text=True)
    if head.returncode != 0:
        pytest.skip("not a git checkout (an sdist): the hook records nothing")
    spec = importlib.util.spec_from_file_location("mpsbench_setup", root / "setup.py")
    assert spec is not None and spec.loader is not None
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)  # not __main__: defines the hook, builds nothing
    status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                            capture_output=True, text=True, check=True).stdout
    assert hook.checkout_state() == {"commit": head.stdout.strip()[:12],
                                     "dirty": bool(status.strip())}
    assert hook.COMMIT_FILE == provenance.BUILD_COMMIT_FILE


def test_physical_cores_from_cpuinfo(monkeypatch: pytest.MonkeyPatch) -> None:
    # 4 logical CPUs on 2 hyper-threaded cores
    blocks = [f"processor\t: {i}\nmodel name\t: Toy CPU  9000\nphysical id\t: 0\n"
              f"core id\t: {i // 2}" for i in range(4)]
    monkeypatch.setattr(provenance, "_cpuinfo", lambda: "\n\n".join(blocks) + "\n")
    assert provenance.physical_cores() == 2
    assert provenance.cpu_model() == "Toy CPU 9000"
    monkeypatch.setattr(provenance, "_cpuinfo", lambda: "processor\t: 0\n")
    assert provenance.physical_cores() is None


@pytest.fixture
def toys() -> Iterator[None]:
    with only_cases(ToyDiffusion(), ToyCounter()):
        yield


def test_every_record_and_the_manifest_carry_the_provenance(toys: None, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert cli.main(["validate", "all", "--tier", "smoke", "--out", str(out), "--jobs", "1"]) == 0
    env = environment()
    records = json.loads((out / "results.json").read_text())
    assert records
    for rec in records:
        assert set(ENV_COLUMNS) <= set(rec)
        assert {k: rec[k] for k in env} == env
        assert rec["solver_commit"].split("-")[0] == env["git_commit"]
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert header[-len(ENV_COLUMNS):] == list(ENV_COLUMNS)  # the environment comes last
    manifest = json.loads((out / "manifest.json").read_text())
    assert {k: manifest["environment"][k] for k in env} == env
    assert set(manifest["environment"]["solvers"]) == {"reference"}
