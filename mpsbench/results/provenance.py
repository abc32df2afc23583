"""Where a result was made: the machine, the library versions, and the commit of the code.

:func:`mpsbench.results.records.environment` assembles these into the columns every record
carries (listed in ``records.ENV_COLUMNS``, documented in docs/columns.md); the bench and the
manifest use the same functions.  Everything here is cached per process: a sweep asks once,
but ``git`` calls cost tens of milliseconds each and a dask worker asks for every run.

Nothing here raises: what cannot be found is ``None`` (an empty cell, "not known").
"""

from __future__ import annotations

import functools
import json
import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

# the libraries whose version changes numbers or speed; read from the installed metadata, so
# asking does not import them (numba takes a second to import)
LIBRARIES = ("numpy", "scipy", "numba", "pandas")
COMMIT_CHARS = 12  # enough to be unique in any repository this project meets
# written next to mpsbench/__init__.py by setup.py's build_py when a wheel is built from a git
# checkout (``pip install .``): {"commit": ..., "dirty": ...}
BUILD_COMMIT_FILE = "_build_commit.json"
GIT_TIMEOUT_S = 5.0
# /proc/cpuinfo keys of the CPU's name: x86, some ARM boards, other ARM, MIPS
CPU_MODEL_KEYS = ("model name", "Model", "Hardware", "cpu model")


@functools.cache
def _machine() -> tuple[tuple[str, Any], ...]:
    model = cpu_model()
    count = os.cpu_count()
    desc = f"{platform.system()} {platform.machine()} {count} cpu"
    return (
        ("os", platform.platform()),
        ("cpu_model", model),
        ("cpu_count", count),
        ("cpu_cores", physical_cores()),
        ("machine", f"{desc}, {model}" if model else desc),
    )


def machine_environment() -> dict[str, Any]:
    """The machine columns: ``os``, ``cpu_model``, ``cpu_count`` (logical CPUs),
    ``cpu_cores`` (physical cores, when the OS says) and the one-line ``machine``."""
    return dict(_machine())


def _cpuinfo() -> str:
    try:
        return Path("/proc/cpuinfo").read_text(errors="replace")
    except OSError:
        return ""


def cpu_model() -> str | None:
    """The CPU's marketing name (Linux /proc/cpuinfo, macOS sysctl), else the architecture
    name Python knows, else None."""
    for line in _cpuinfo().splitlines():
        key, sep, value = line.partition(":")
        if sep and key.strip() in CPU_MODEL_KEYS and value.strip():
            return " ".join(value.split())
    if sys.platform == "darwin":
        text = _run(["sysctl", "-n", "machdep.cpu.brand_string"], None)
        if text:
            return text
    return platform.processor() or None


def physical_cores() -> int | None:
    """Distinct (package, core) pairs of /proc/cpuinfo; None where it does not list them."""
    cores: set[tuple[str, str]] = set()
    package = core = None
    for line in _cpuinfo().splitlines() + [""]:
        key, _, value = (part.strip() for part in line.partition(":"))
        if key == "physical id":
            package = value
        elif key == "core id":
            core = value
        elif not key:  # a blank line ends one logical CPU's block
            if package is not None and core is not None:
                cores.add((package, core))
            package = core = None
    return len(cores) or None


@functools.cache
def library_versions() -> tuple[tuple[str, str | None], ...]:
    """(``<lib>_version``, version or None when not installed) for each of LIBRARIES."""
    out: list[tuple[str, str | None]] = []
    for name in LIBRARIES:
        try:
            out.append((f"{name}_version", metadata.version(name)))
        except metadata.PackageNotFoundError:
            out.append((f"{name}_version", None))
    return tuple(out)


def _run(cmd: list[str], cwd: Path | None) -> str | None:
    try:
        out = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True,
                             timeout=GIT_TIMEOUT_S, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


@functools.cache
def git_state(path: str) -> tuple[str | None, bool | None]:
    """(commit, dirty) of the git checkout that tracks the file ``path``; (None, None) when the
    file is not tracked by one (an installed wheel, or a virtualenv inside someone else's
    repository: the enclosing repository's commit would be a lie).

    ``dirty``: a tracked file differs from the commit (untracked files do not count: results
    folders and scratch files are not code).
    """
    file = Path(path).resolve()
    where = file.parent
    if _run(["git", "ls-files", "--error-unmatch", "--", file.name], where) is None:
        return None, None
    status = _run(["git", "status", "--porcelain=v2", "--branch", "--untracked-files=no"], where)
    if status is None:
        return None, None
    commit = None
    dirty = False
    for line in status.splitlines():
        if line.startswith("# branch.oid "):
            oid = line.split()[2]
            commit = None if oid == "(initial)" else oid[:COMMIT_CHARS]
        elif not line.startswith("#"):
            dirty = True
    return commit, dirty


def build_commit(package: str) -> tuple[str | None, bool | None]:
    """(commit, dirty) that the build of an installed top-level ``package`` recorded in its
    :data:`BUILD_COMMIT_FILE` (setup.py: a wheel built from a git checkout); (None, None) when
    there is none or it cannot be read."""
    file = getattr(sys.modules.get(package), "__file__", None)
    if not file:
        return None, None
    try:
        state = json.loads((Path(file).parent / BUILD_COMMIT_FILE).read_text())
        commit, dirty = state["commit"], state["dirty"]
    except (OSError, ValueError, KeyError, TypeError):
        return None, None
    if not isinstance(commit, str) or not commit or not isinstance(dirty, bool):
        return None, None
    return commit[:COMMIT_CHARS], dirty


def code_commit(module_name: str) -> str | None:
    """The commit of the code of a module: its git checkout's (``-dirty`` appended when that
    checkout has local changes), else the one its package's build recorded
    (:func:`build_commit`), else the commit pip recorded when it installed the module's
    distribution from a VCS URL (PEP 610 ``direct_url.json``), else None."""
    module = sys.modules.get(module_name)
    file = getattr(module, "__file__", None)
    if file:
        commit, dirty = git_state(file)
        if commit:
            return commit + ("-dirty" if dirty else "")
    top = module_name.split(".")[0]
    commit, dirty = build_commit(top)
    if commit:
        return commit + ("-dirty" if dirty else "")
    for dist_name in _distributions().get(top, []):
        try:
            text = metadata.distribution(dist_name).read_text("direct_url.json")
            commit = json.loads(text or "{}").get("vcs_info", {}).get("commit_id")
        except (metadata.PackageNotFoundError, ValueError, AttributeError):
            continue
        if commit:
            return str(commit)[:COMMIT_CHARS]
    return None


@functools.cache
def _distributions() -> dict[str, list[str]]:
    return dict(metadata.packages_distributions())


def mpsbench_environment() -> dict[str, Any]:
    """``mpsbench_version``, ``git_commit`` and ``git_dirty`` of this installation."""
    import mpsbench

    commit, dirty = git_state(mpsbench.__file__ or "")
    if commit is None:  # an installed copy: the commit its build recorded, if any
        commit, dirty = build_commit("mpsbench")
    return {"mpsbench_version": mpsbench.__version__, "git_commit": commit, "git_dirty": dirty}


@functools.cache
def _solver(spec: str) -> tuple[str | None, str | None]:
    from mpsbench.run.specs import get_solver_class

    try:
        cls = get_solver_class(spec)
    except Exception:  # noqa: BLE001 - an unavailable solver has no provenance, not an error
        return None, None
    version = getattr(cls, "version", None)
    return (None if version is None else str(version)), code_commit(cls.__module__)


def solver_provenance(spec: str) -> dict[str, str | None]:
    """``solver_version`` (the backend's ``version``) and ``solver_commit`` (see
    :func:`code_commit`; a built-in backend gives mpsbench's own commit) of a solver."""
    version, commit = _solver(spec)
    return {"solver_version": version, "solver_commit": commit}
