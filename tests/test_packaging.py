"""pyproject's hand-written package list covers every package folder on disk (and no more)."""

from __future__ import annotations

import tomllib
from pathlib import Path

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
    missing = sorted(on_disk - listed)
    stale = sorted(listed - on_disk)
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {missing}"
    assert not stale, f"listed in pyproject.toml but no such package folder: {stale}"
    assert {"mpsbench", "mpsbench.commands", "mpsbench.solvers", "mpsbench.validations"} <= listed


def test_every_mapped_root_is_a_package() -> None:
    for folder in load_setuptools()["package-dir"].values():
        assert (ROOT / folder / "__init__.py").is_file(), folder
