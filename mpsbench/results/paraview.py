"""ParaView series of a run's frames: binary VTU files (written with meshio) and a ``.pvd``
collection that gives each file its time value.

Layout, under a folder's ``paraview/`` (``mpsbench validate ... --vtu``, ``mpsbench export``)::

    paraview/<run_id>.pvd              the series: one DataSet per frame, timestep = t [s]
    paraview/<run_id>/frame_<k>.vtu    frame k: the particles as VTK vertices, with point data
                                       velocity [m/s] (3 components, z = 0), pressure [Pa],
                                       kind, and every extra field

A case run made of several solver runs gets one series per solver run
(``<run_id>_part<i>.pvd``).  Open the ``.pvd`` in ParaView (File > Open) and play it; colour by
pressure, view as Points.  meshio is the ``vtu`` extra (``pip install "mpsbench[vtu]"``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from mpsbench.errors import InputFileError, UsageError
from mpsbench.results.frames import StoredFrame, read_frames
from mpsbench.results.paths import component, inside
from mpsbench.results.records import atomic_write_text, load_arrays, run_id_problem

INSTALL = 'pip install "mpsbench[vtu]"'


def require_meshio() -> Any:
    """meshio, or a UsageError saying how to install it."""
    try:
        import meshio
    except ImportError:
        raise UsageError(f"--vtu needs meshio: {INSTALL}") from None
    return meshio


def write_series(run_id: str, frames: list[StoredFrame], dest: Path,
                 root: Path | None = None) -> list[Path]:
    """Write the ``.pvd`` series (one per solver run) and their VTU files into ``dest``;
    return the ``.pvd`` paths.  ``root``: the results folder nothing may be written outside
    of (default ``dest``)."""
    meshio = require_meshio()
    root = root or dest
    component("run id", run_id)
    parts = sorted({f.part for f in frames})
    out = []
    for part in parts:
        name = run_id if len(parts) == 1 else f"{run_id}_part{part}"
        folder = inside(root, dest / name)
        folder.mkdir(parents=True, exist_ok=True)
        entries = []
        for k, frame in enumerate(f for f in frames if f.part == part):
            path = folder / f"frame_{k:04d}.vtu"
            _write_vtu(meshio, path, frame)
            entries.append((frame.time, f"{name}/{path.name}"))
        pvd = inside(root, dest / f"{name}.pvd")
        atomic_write_text(pvd, _pvd(entries))
        out.append(pvd)
    return out


def _write_vtu(meshio: Any, path: Path, frame: StoredFrame) -> None:
    p = frame.particles
    n = p.n
    points = np.column_stack([p.pos, np.zeros(n)])
    point_data = {
        "velocity": np.column_stack([p.vel, np.zeros(n)]),
        "pressure": np.asarray(p.pressure, float),
        "kind": np.asarray(p.kind, np.int32),
        **{name: np.asarray(v, float) for name, v in p.fields.items()},
    }
    # the time is the .pvd's timestep (meshio's VTU writer drops field data)
    mesh = meshio.Mesh(points, [("vertex", np.arange(n, dtype=np.int64).reshape(n, 1))],
                       point_data=point_data)
    tmp = path.with_name(f".{path.name}.tmp.vtu")  # meshio picks the format by the suffix
    try:
        meshio.write(tmp, mesh, file_format="vtu", binary=True, compression="zlib")
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def _pvd(entries: list[tuple[float, str]]) -> str:
    rows = "\n".join(f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>'
                     for t, f in entries)
    return ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" '
            'byte_order="LittleEndian">\n  <Collection>\n' + rows + "\n  </Collection>\n"
            "</VTKFile>\n")


def read_pvd(path: Path) -> list[tuple[float, Path]]:
    """(time, VTU path) of each DataSet of a ``.pvd`` file, in file order."""
    import xml.etree.ElementTree as ET

    root = ET.parse(path).getroot()
    return [(float(d.attrib["timestep"]), path.parent / d.attrib["file"])
            for d in root.iter("DataSet")]


def export_runs(case_folder: Path, run_ids: list[str], dest: Path | None = None,
                root: Path | None = None) -> tuple[list[Path], list[str]]:
    """The series of each run of ``case_folder/runs/`` that kept frames, written to ``dest``
    (default ``case_folder/paraview/``): (the ``.pvd`` files, the run ids that kept none)."""
    dest = dest or case_folder / "paraview"
    pvds: list[Path] = []
    without: list[str] = []
    for rid in run_ids:
        frames = read_frames(load_arrays(case_folder, rid), str(case_folder / "runs" / rid))
        if not frames:
            without.append(rid)
            continue
        pvds += write_series(rid, frames, dest, root or dest)
    return pvds, without


def run_location(path: Path) -> tuple[Path, str]:
    """(case folder, run id) of a run named by its record or arrays file
    (``<folder>/runs/<run_id>.json`` or ``.npz``); InputFileError otherwise."""
    if path.suffix not in (".json", ".npz") or path.parent.name != "runs":
        raise InputFileError(f"{path}: not a run; give runs/<run_id>.json or runs/<run_id>.npz "
                             "of a results folder")
    problem = run_id_problem(path.stem)
    if problem is not None:
        raise InputFileError(f"{path}: {problem}")
    if not path.with_suffix(".json").is_file() and not path.with_suffix(".npz").is_file():
        raise InputFileError(f"{path}: no such run")
    return path.parent.parent, path.stem


def frames_of(path: Path) -> tuple[Path, str, list[StoredFrame]]:
    """The frames of the run named by ``path`` (:func:`run_location`); InputFileError saying
    how to get them when the run kept none."""
    folder, rid = run_location(path)
    frames = read_frames(load_arrays(folder, rid), str(folder / "runs" / f"{rid}.npz"))
    if not frames:
        raise InputFileError(f"{folder / 'runs' / rid}.npz: the run kept no frames; run it "
                             "with 'mpsbench validate ... --vtu' (a run done without frames "
                             "runs again)")
    return folder, rid, frames
