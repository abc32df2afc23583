"""Paths a report writes: always inside its results folder, written atomically.

Case, solver and run names from records become folder and file names (``<case>/``,
``by-solver/<solver>/``).  They are checked when a record is read
(:func:`mpsbench.results.records.record_problem`); :func:`inside` checks every path written on
top of that, after resolving symbolic links, so no record, plugin or link can make a report
write outside its folder.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from mpsbench.errors import InputFileError
from mpsbench.results.records import _atomic_replace

COMPONENT_CHARS = "letters, digits, '=', '.', '_', '+', '-', starting with a letter or digit"
_COMPONENT_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9=._+-]{0,199}")


def component(kind: str, name: object) -> str:
    """``name`` when it may be one folder or file name inside a results folder (no '/', '\\',
    '..', NUL, leading dot: see :data:`COMPONENT_CHARS`); else InputFileError."""
    if not isinstance(name, str) or not _COMPONENT_RE.fullmatch(name) or ".." in name:
        raise InputFileError(f"{kind} name {str(name)[:80]!r} is not allowed as a file or "
                             f"folder name: {COMPONENT_CHARS}, no '..'")
    return name


def inside(base: Path, path: Path) -> Path:
    """``path`` when it lies inside ``base`` (symbolic links resolved); else InputFileError."""
    root = base.resolve()
    target = path.resolve()
    if target != root and root not in target.parents:
        raise InputFileError(f"refusing to write {path}: it lies outside the results folder "
                             f"{base} (a name in a record, a plugin or a symbolic link points "
                             "there)")
    return path


def safe_dir(base: Path, path: Path) -> Path:
    """Create the folder ``path`` inside ``base`` (checked before and after creating it)."""
    inside(base, path)
    path.mkdir(parents=True, exist_ok=True)
    return inside(base, path)


def atomic_copy(src: Path, dst: Path) -> None:
    """Copy ``src`` to ``dst`` through a temporary file and a rename: a reader never sees half
    a figure, and an interrupted copy leaves the old one."""

    def fill(tmp: str) -> None:
        shutil.copyfile(src, tmp)

    _atomic_replace(dst, fill, suffix=dst.suffix)
