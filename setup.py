"""Build hook: a wheel built from a git checkout records that checkout's commit.

``pip install .`` (the README's first command) installs a copy of the code, which is no longer
in any git checkout, and pip's ``direct_url.json`` names only the folder, so results would carry
no commit.  ``build_py`` therefore writes ``mpsbench/_build_commit.json`` (``commit``, ``dirty``:
a tracked file differed from it) into the build when the source tree is a git checkout, and
:func:`mpsbench.results.provenance.build_commit` reads it.  Everything else is in pyproject.toml.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
COMMIT_FILE = "_build_commit.json"  # = mpsbench.results.provenance.BUILD_COMMIT_FILE


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(["git", *args], cwd=HERE, capture_output=True, text=True,
                             timeout=20, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def checkout_state() -> dict[str, object] | None:
    """{"commit", "dirty"} of the git checkout this file is in (as git_state: untracked files
    do not count), or None outside a checkout (an sdist)."""
    if _git("ls-files", "--error-unmatch", "--", "pyproject.toml") is None:
        return None
    commit = _git("rev-parse", "HEAD")
    status = _git("status", "--porcelain", "--untracked-files=no")
    if not commit or status is None:
        return None
    return {"commit": commit[:12], "dirty": bool(status)}


class BuildPyWithCommit(build_py):
    def run(self) -> None:
        super().run()
        state = checkout_state()
        if state is not None and not self.editable_mode:  # an editable install is the checkout
            target = Path(self.build_lib) / "mpsbench" / COMMIT_FILE
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(json.dumps(state) + "\n")


if __name__ == "__main__":  # as setuptools' build backend runs it (importing it builds nothing)
    setup(cmdclass={"build_py": BuildPyWithCommit})
