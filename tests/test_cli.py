"""The command line, end to end in a subprocess, plus the error path in process."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import mpsbench
from mpsbench import cli
from mpsbench.commands import catalog
from mpsbench.errors import ConfigError, UsageError
from mpsbench.registry import PluginLoadError, UnknownNameError


def run(*args: str, module: str = "mpsbench.cli") -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", module, *args], capture_output=True, text=True, timeout=120
    )


def test_help() -> None:
    out = run("--help")
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("usage: mpsbench")
    for command in ("models", "solvers"):
        assert command in out.stdout


@pytest.mark.parametrize("module", ["mpsbench.cli", "mpsbench"])
def test_version(module: str) -> None:
    out = run("--version", module=module)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == f"mpsbench {mpsbench.__version__}"
    assert mpsbench.__version__ != "0.0.0+unknown"  # the package metadata is installed


def test_models_json() -> None:
    out = run("models", "--json")
    assert out.returncode == 0, out.stderr
    cat = json.loads(out.stdout)
    names = {key: {row["name"] for row in rows} for key, rows in cat.items()}
    assert names["weights"] >= {"wf1", "wf2"}
    assert names["laplacians"] >= {"koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic"}
    assert names["gradients"] >= {"pgm1", "pgm2", "pgm3"}
    for rows in cat.values():
        for row in rows:
            if row["origin"] == "builtin":
                assert row["available"] and row["error"] is None and row["description"]


def test_models_table() -> None:
    out = run("models")
    assert out.returncode == 0, out.stderr
    for line in ("Weighting functions:", "Laplacian models:", "Pressure gradient models:"):
        assert line in out.stdout
    assert "xu-jin-analytic" in out.stdout and "pgm3" in out.stdout


def test_solvers_json() -> None:
    out = run("solvers", "--json")
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)
    by_name = {row["name"]: row for row in rows}
    assert "reference" in by_name  # listed even while it cannot be loaded
    for row in rows:
        assert isinstance(row["available"], bool)
        if row["available"]:
            assert set(row["capabilities"]) >= {"physics", "boundaries", "features"}
        else:
            assert row["error"]


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (("no-such-command",), "invalid choice: 'no-such-command'"),
        (("models", "--bogus"), "unrecognized arguments: --bogus"),
        (("--no-such-flag",), "unrecognized arguments"),
    ],
)
def test_bad_arguments_exit_2_without_traceback(args: tuple[str, ...], fragment: str) -> None:
    out = run(*args)
    assert out.returncode == 2
    assert fragment in out.stderr
    assert "Traceback" not in out.stderr
    assert len(out.stderr.splitlines()) <= 3


def test_no_command_prints_help_and_exits_2() -> None:
    out = run()
    assert out.returncode == 2
    assert "usage: mpsbench" in out.stdout
    assert "Traceback" not in out.stderr


@pytest.mark.parametrize(
    "exc",
    [
        UnknownNameError("unknown solver 'x'; known solvers: reference"),
        ConfigError("Models.weight = 'x' is not allowed: one of 'wf1', 'wf2'"),
        PluginLoadError("solver 'x' could not be loaded"),
        UsageError("bad input"),
    ],
)
def test_user_errors_are_one_line_exit_2(
    exc: Exception, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def failing(args: object) -> int:
        raise exc

    monkeypatch.setattr(catalog, "cmd_models", failing)
    assert cli.main(["models"]) == 2
    err = capsys.readouterr().err
    assert err == f"mpsbench models: error: {exc}\n"


def test_main_in_process(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["models", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["laplacians"]
    assert "xu-jin" in {row["name"] for row in rows}
