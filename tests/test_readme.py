"""The README stays true: set-up commands first, examples run, model table matches registries."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np

from mpsbench.physics.config import Models
from mpsbench.physics.gradients import GRADIENTS
from mpsbench.physics.laplacians import LAPLACIANS, get_laplacian
from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.operators import lattice_constants, lattice_pairs
from mpsbench.physics.weights import WEIGHTS, get_weight

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()

VENV = "python3 -m venv .venv && . .venv/bin/activate && "
FIRST_COMMANDS = [
    VENV + 'pip install ".[fast]" && mpsbench validate all',
    VENV + 'pip install -e ".[test]" && pytest',
]


def blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", README, flags=re.S)


def test_starts_with_the_two_setup_commands() -> None:
    lines = README.splitlines()
    assert lines[0].startswith("# ")
    assert lines[1:5] == ["", "```", *FIRST_COMMANDS]


def test_ci_runs_the_readme_test_command() -> None:
    ci = (Path(__file__).resolve().parents[1] / ".ci" / "run").read_text()
    assert 'pip install -e ".[test]"' in ci
    assert re.search(r"^\s*(check\s+)?pytest\s*$", ci, flags=re.M)


def test_model_table_matches_registries() -> None:
    names = set(re.findall(r"^\| [A-Za-z ]+ \| `([a-z0-9-]+)` \|", README, flags=re.M))
    assert names == set(WEIGHTS.names()) | set(LAPLACIANS.names()) | set(GRADIENTS.names())


def test_plugin_examples_run() -> None:
    python = blocks("python")
    assert len(python) == 2
    namespace: dict = {}
    try:
        for code in python:
            exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102
        wf = get_weight("quartic")
        assert float(wf.w(0.5, 1.0)) == 0.0625
        assert Models(weight="quartic", laplacian="plain-weighted").laplacian == "plain-weighted"
        pos, box = lattice_pairs(10)
        pairs = build_pairs(pos, 2.1, box)
        n0, lam = lattice_constants("quartic", 2.1)
        lap = get_laplacian("plain-weighted")
        phi = np.sin(2 * np.pi * pos[:, 0] / 10)
        np.testing.assert_allclose(
            lap.matrix(pairs, wf, 2.1, n0, lam) @ phi, lap.apply(pairs, phi, wf, 2.1, n0, lam)
        )
    finally:
        WEIGHTS.unregister("quartic")
        LAPLACIANS.unregister("plain-weighted")


def test_entry_point_example_is_valid_toml() -> None:
    (toml,) = blocks("toml")
    eps = tomllib.loads(toml)["project"]["entry-points"]
    assert list(eps) == ["mpsbench.laplacians"]
    assert LAPLACIANS.group == "mpsbench.laplacians"
