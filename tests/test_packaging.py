"""Packaging: pyproject's hand-written package list covers every package folder on disk (and no
more); the license, the typing marker and the sdist's contents; a user's mypy sees the types.

The slow tests build the sdist and the wheel with ``python -m build`` (an isolated build: it
fetches setuptools >= 77) and install the wheel into a fresh virtual environment.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tarfile
import tomllib
import venv
import zipfile
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]


def load_setuptools() -> dict:
    with open(ROOT / "pyproject.toml", "rb") as fh:
        return tomllib.load(fh)["tool"]["setuptools"]


def packages_on_disk(package_dir: dict[str, str]) -> set[str]:
    """Every folder with an __init__.py under a mapped root, named as it installs."""
    found = set()
    for name, folder in package_dir.items():
        root = ROOT / folder  # mpsbench.solvers -> solvers/ is a root of its own
        for init in root.rglob("__init__.py"):
            rel = init.parent.relative_to(root)
            if any(part.startswith((".", "__")) for part in rel.parts):
                continue
            found.add(".".join([name, *rel.parts]) if rel.parts else name)
    return found


def _folder(name: str, package_dir: dict[str, str]) -> Path:
    """Where package ``name`` lives on disk under the package-dir mapping."""
    root = max((k for k in package_dir if name == k or name.startswith(k + ".")), key=len)
    return Path(package_dir[root], *name[len(root):].split(".")[1:])


def test_package_dir_maps_the_three_roots() -> None:
    package_dir = load_setuptools()["package-dir"]
    assert package_dir == {
        "mpsbench": "mpsbench",
        "mpsbench.solvers": "solvers",
        "mpsbench.validations": "validations",
    }


def test_packages_list_matches_folders() -> None:
    cfg = load_setuptools()
    listed = set(cfg["packages"])
    on_disk = packages_on_disk(cfg["package-dir"])
    # folders of data only are listed too (with their files in package-data): no __init__.py
    data_only = {name for name in listed if name in load_pyproject()["tool"]["setuptools"][
        "package-data"] and not (ROOT / _folder(name, cfg["package-dir"]) / "__init__.py").exists()}
    assert {"mpsbench.validations.data", "mpsbench.validations.baselines.smoke"} <= data_only
    listed -= data_only
    missing = sorted(on_disk - listed)
    stale = sorted(listed - on_disk)
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {missing}"
    assert not stale, f"listed in pyproject.toml but no such package folder: {stale}"
    assert {"mpsbench", "mpsbench.commands", "mpsbench.solvers", "mpsbench.validations"} <= listed


def test_every_mapped_root_is_a_package() -> None:
    for folder in load_setuptools()["package-dir"].values():
        assert (ROOT / folder / "__init__.py").is_file(), folder


# --------------------------------------------------------------------------- metadata, sdist, types


def load_pyproject() -> dict:
    with open(ROOT / "pyproject.toml", "rb") as fh:
        return tomllib.load(fh)


def test_license_is_an_spdx_expression_with_its_file() -> None:
    doc = load_pyproject()
    project = doc["project"]
    assert project["license"] == "MIT" and project["license-files"] == ["LICENSE"]
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License\n") and "the mpsbench authors" in text
    # PEP 639 metadata needs setuptools 77; a License classifier beside an expression is refused
    (setuptools,) = [r for r in doc["build-system"]["requires"] if r.startswith("setuptools")]
    assert setuptools == "setuptools>=77"
    assert not [c for c in project["classifiers"] if c.startswith("License ::")]
    assert "Typing :: Typed" in project["classifiers"]


def test_py_typed_is_package_data() -> None:
    assert (ROOT / "mpsbench" / "py.typed").is_file()
    assert "py.typed" in load_setuptools()["package-data"]["mpsbench"]


def test_manifest_ships_docs_examples_and_tests() -> None:
    lines = [line.split("#")[0].split() for line in (ROOT / "MANIFEST.in").read_text().splitlines()]
    grafted = {words[1] for words in lines if words[:1] == ["graft"]}
    assert {"docs", "examples", "tests"} <= grafted
    included = {w for words in lines if words[:1] == ["include"] for w in words[1:]}
    assert {"LICENSE", "CHANGELOG.md"} <= included


def _run(cmd: list[str], **kw: Any) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, **kw)
    assert proc.returncode == 0, f"{cmd}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc


@pytest.fixture(scope="module")
def dists(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """``python -m build``: the sdist, then the wheel built from that sdist."""
    out = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "build", "--outdir", str(out), str(ROOT)])
    (sdist,), (wheel,) = sorted(out.glob("*.tar.gz")), sorted(out.glob("*.whl"))
    return sdist, wheel


@pytest.mark.slow
def test_sdist_carries_docs_examples_and_license(dists: tuple[Path, Path]) -> None:
    sdist, _ = dists
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
        top = next(n for n in tar.getnames() if n.endswith("/PKG-INFO") and n.count("/") == 1)
        pkg_info = tar.extractfile(top).read().decode()  # type: ignore[union-attr]
    for path in ("LICENSE", "CHANGELOG.md", "README.md", "MANIFEST.in", "mpsbench/py.typed",
                 "docs/ci.md", "docs/method.md", "docs/images/couette_error_vs_re.png",
                 "examples/ci/github-actions.yml", "examples/ci/gitlab-ci.yml",
                 "examples/plugin/pyproject.toml", "examples/plugin/mpsbench-baseline/results.json",
                 "examples/studies/couette_laplacians.toml", "tests/test_packaging.py",
                 "validations/baselines/smoke/results.json"):
        assert path in names, path
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    # build leftovers of the example plugin (pip builds it in its folder) stay out
    assert not [n for n in names if ".egg-info" in n and n.split("/")[0] != "mpsbench.egg-info"]
    assert not [n for n in names if n.startswith("reports/")]
    assert "License-Expression: MIT" in pkg_info and "License-File: LICENSE" in pkg_info
    assert "Classifier: Typing :: Typed" in pkg_info


@pytest.mark.slow
def test_installed_package_is_typed_for_a_users_mypy(dists: tuple[Path, Path],
                                                     tmp_path: Path) -> None:
    """Install the wheel (what ``pip install .`` builds) into a fresh venv; the dev mypy, run on
    a user's file against that venv, sees mpsbench's annotations and reports a misuse."""
    _, wheel = dists
    with zipfile.ZipFile(wheel) as whl:
        names = set(whl.namelist())
        (entry_points,) = [n for n in names if n.endswith(".dist-info/entry_points.txt")]
        declared = whl.read(entry_points).decode()
    assert "mpsbench/py.typed" in names and "mpsbench/pytest_plugin.py" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert "[pytest11]\nmpsbench = mpsbench.pytest_plugin" in declared

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    _run([str(py), "-m", "pip", "install", "--quiet", "--no-deps", str(wheel)])
    user = tmp_path / "user"
    user.mkdir()  # outside the checkout: only the installed package is seen
    (user / "uses_mpsbench.py").write_text(
        "import mpsbench\n"
        "from mpsbench.results.records import run_id\n\n"
        "reveal_type(mpsbench.__version__)\n"
        "rid: int = run_id('diffusion', 'reference', {'l0': 0.05})\n"
        "run_id(1, 'reference', {})\n")

    def mypy() -> str:
        proc = subprocess.run(
            [sys.executable, "-m", "mypy", "--python-executable", str(py), "--no-incremental",
             "--cache-dir", os.devnull, "--show-error-codes", "uses_mpsbench.py"],
            cwd=user, capture_output=True, text=True, timeout=1200)
        return proc.stdout + proc.stderr

    out = mypy()
    assert re.search(r'Revealed type is "(builtins\.)?str"', out), out
    assert ('Incompatible types in assignment (expression has type "str", variable has type '
            '"int")') in out, out
    assert 'Argument 1 to "run_id" has incompatible type "int"; expected "str"' in out, out
    assert "import-untyped" not in out, out

    # the control: without py.typed the same install is untyped to mypy
    site = next((env_dir / "lib").glob("python3*/site-packages"))
    (site / "mpsbench" / "py.typed").unlink()
    out = mypy()
    assert "import-untyped" in out and 'Revealed type is "Any"' in out, out
    assert 'Argument 1 to "run_id"' not in out, out
