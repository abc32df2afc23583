"""``mpsbench export RUN_OR_FOLDER --vtu``: ParaView series from the frames stored in
``runs/*.npz`` (kept by ``mpsbench validate ... --vtu``; :mod:`mpsbench.results.frames`).

RUN_OR_FOLDER is one run (``<folder>/runs/<run_id>.json`` or ``.npz``), a case folder
(``mpsbench validate CASE``) or a results folder (``mpsbench validate all``: every case folder
in it).  Writes ``<case folder>/paraview/<run_id>.pvd`` and its VTU files
(:mod:`mpsbench.results.paraview`), or into ``--out DIR``.
Exit status: 0 written, 2 nothing to export (no run kept frames), a bad path or no meshio.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mpsbench.errors import UsageError

ORDER = 36


def register(sub: Any) -> None:
    p = sub.add_parser(
        "export",
        help="write ParaView series (.pvd + VTU) from the frames stored in runs/*.npz",
        description="Write a ParaView series per run from the frames a run kept "
        "('mpsbench validate ... --vtu'), without running anything.",
    )
    p.add_argument("path", metavar="RUN_OR_FOLDER",
                   help="runs/<run_id>.json or .npz, a case folder or a results folder")
    p.add_argument("--vtu", action="store_true", required=True,
                   help="VTU files and a .pvd series with time values (the one format)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write the series here (default: <case folder>/paraview/)")
    p.set_defaults(func=cmd_export)


def cmd_export(args: argparse.Namespace) -> int:
    from mpsbench.results.folder import case_folders
    from mpsbench.results.paraview import export_runs, frames_of, require_meshio, write_series

    require_meshio()
    path = Path(args.path)
    out = Path(args.out) if args.out else None
    if path.is_file():
        folder, rid, frames = frames_of(path)
        dest = out or folder / "paraview"
        _mkdir(dest)
        pvds = write_series(rid, frames, dest)
        without: list[str] = []
    elif path.is_dir():
        pvds, without = [], []
        found = case_folders(path)
        if not found:
            raise UsageError(f"{path}: no runs/ folder here or in a case folder below it")
        for name, folder, records in found:
            dest = (out / name if len(found) > 1 else out) if out else folder / "paraview"
            _mkdir(dest)
            got, missing = export_runs(folder, [str(r["run_id"]) for r in records], dest)
            pvds += got
            without += missing
    else:
        raise UsageError(f"{path}: no such run or folder")
    if not pvds:
        raise UsageError(f"{path}: no run kept frames; run it with 'mpsbench validate ... "
                         "--vtu'")
    for pvd in pvds:
        print(pvd)
    if without:
        print(f"{len(without)} run(s) kept no frames (run them with --vtu), e.g. {without[0]}",
              file=sys.stderr)
    return 0


def _mkdir(dest: Path) -> None:
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out {dest}: cannot create: {exc.strerror or exc}") from None
