"""One mpsbench process at a time per output folder, and output folders that can be written.

Every command that writes a results folder (``validate``, ``study run``, ``report``) holds
:func:`folder_lock` on it for as long as it writes: a second one on the same folder is refused
with exit status 2 instead of tearing ``results.csv`` or a record.  The lock is a POSIX record
lock (``lockf``) on ``OUT/.mpsbench.lock``; the operating system drops it when the process dies,
so a killed run never leaves a folder locked.  ``lockf``, not ``flock``: it belongs to this
process only, so worker processes forked from it (which inherit the file descriptor) do not
keep the folder locked after it was killed.

:func:`prepare_folder` turns the ways an output folder can be unusable (an existing file, a
path below a file, a folder that cannot be written) into one-line usage errors before anything
runs.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from pathlib import Path

from mpsbench.errors import UsageError

LOCK_FILE = ".mpsbench.lock"


def prepare_folder(out: Path, option: str = "--out") -> Path:
    """Create ``out`` (and its parents) if needed and check that it can be written."""
    for parent in [out, *out.parents]:
        if parent.exists() and not parent.is_dir():
            what = "is" if parent == out else f"is below {parent}, which is"
            raise UsageError(f"{option} {out}: {what} a file, not a folder; pick another {option}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{option} {out}: cannot create the folder: {_why(exc)}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {out}: the folder is not writable; pick another {option}")
    return out


@contextlib.contextmanager
def folder_lock(out: Path, command: str, option: str = "--out") -> Iterator[None]:
    """Hold the lock on ``out`` (created if needed) while the block runs; UsageError naming
    the holder's pid and command when another process holds it."""
    prepare_folder(out, option)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    try:
        fh = open(out / LOCK_FILE, "a+")  # noqa: SIM115 - held for the whole command
    except OSError as exc:
        raise UsageError(f"{option} {out}: cannot write in the folder: {_why(exc)}") from None
    try:
        try:
            fcntl.lockf(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            holder = fh.read().strip() or "?"
            raise UsageError(
                f"{out} is in use by another mpsbench process (pid {holder}); wait for it to "
                f"finish or pick another {option}"
            ) from None
        fh.seek(0)
        fh.truncate()
        fh.write(f"{os.getpid()}: {command}")
        fh.flush()
        try:
            yield
        finally:
            fh.seek(0)
            fh.truncate()  # no stale holder named after we are done
    finally:
        fh.close()


def held_by_other(out: Path) -> str | None:
    """The holder (``pid: command``) when another process holds the lock on ``out``, else None
    (for readers such as ``mpsbench compare``, which must not read a folder being written)."""
    path = out / LOCK_FILE
    if sys.platform == "win32" or not path.is_file():
        return None
    import fcntl

    try:
        with open(path, "r+") as fh:
            try:
                fcntl.lockf(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                return fh.read().strip() or "?"
            fcntl.lockf(fh.fileno(), fcntl.LOCK_UN)
    except OSError:
        return None
    return None


def _why(exc: OSError) -> str:
    return exc.strerror or str(exc)
