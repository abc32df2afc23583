"""``mpsbench --help`` and ``--version`` import none of the heavy libraries (issue 20 item 4).

Each command module imports what it needs inside its function, so building the parser costs
only argparse and the small core modules.  Run in a fresh interpreter: ``-X importtime`` lists
every module the start-up imported (one line per module on stderr).
"""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

HEAVY = ("numpy", "pandas", "scipy", "matplotlib", "numba", "dask", "tabulate")


def imported_modules(*args: str) -> set[str]:
    proc = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "mpsbench", *args],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    names = re.findall(r"^import time:\s+\d+ \|\s+\d+ \|\s*(\S+)\s*$", proc.stderr, flags=re.M)
    assert names, "no -X importtime lines on stderr"
    return set(names)


@pytest.mark.parametrize("args", [("--version",), ("--help",)])
def test_start_up_imports_no_heavy_library(args: tuple[str, ...]) -> None:
    modules = imported_modules(*args)
    assert "mpsbench.cli" in modules  # the listing works: the CLI itself is in it
    heavy = sorted(m for m in modules if m.split(".")[0] in HEAVY)
    assert not heavy, f"mpsbench {' '.join(args)} imported {heavy[:10]}"


def test_every_command_is_still_registered() -> None:
    proc = subprocess.run([sys.executable, "-m", "mpsbench", "--help"],
                          capture_output=True, text=True, timeout=60, check=False)
    for command in ("validate", "compare", "report", "study", "bench", "check", "solvers"):
        assert command in proc.stdout
