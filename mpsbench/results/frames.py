"""Frames in a run's arrays file: how ``runs/<run_id>.npz`` stores the particle states that
``mpsbench validate ... --vtu`` kept (:mod:`mpsbench.run.frames`), and reading them back.

``runs/<run_id>.npz`` (numpy's compressed archive, read with ``numpy.load``) holds:

* the arrays the case keeps for its figures (profiles, probe histories, its own snapshots;
  each case's ``execute`` says which);
* with ``--vtu``, the frames, under names that start with ``frame``:

  ``frame_time`` (n,) [s], ``frame_step`` (n,), ``frame_part`` (n,): the time and step count
  the run had reached, and which solver run of the case run the frame belongs to (0, 1, ...;
  a case run can be several solver runs); per frame k, ``frame<k>_pos`` (N, 2) [m],
  ``frame<k>_vel`` (N, 2) [m/s], ``frame<k>_pressure`` (N,) [Pa], ``frame<k>_kind`` (N,)
  (0 fluid, 1 wall, 2 dummy wall, ...: :class:`mpsbench.physics.particles.Kind`) and
  ``frame<k>_field_<name>`` (N,) for each extra per-particle field (the diffused scalar,
  number density, ...).

Frames are outputs, never inputs: no record column, run id or comparison depends on them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mpsbench.errors import InputFileError
from mpsbench.physics.particles import Particles

PREFIX = "frame"


def frame_arrays(results: list[Any]) -> dict[str, np.ndarray]:
    """The frames of a case run's solver runs (:class:`~mpsbench.run.runner.RunResult`), as
    arrays for the run's npz ({} when none kept frames)."""
    out: dict[str, np.ndarray] = {}
    times, steps, parts = [], [], []
    k = 0
    for part, result in enumerate(results):
        for frame in getattr(result, "frames", []):
            p = frame.particles
            out[f"{PREFIX}{k}_pos"] = np.asarray(p.pos, float)
            out[f"{PREFIX}{k}_vel"] = np.asarray(p.vel, float)
            out[f"{PREFIX}{k}_pressure"] = np.asarray(p.pressure, float)
            out[f"{PREFIX}{k}_kind"] = np.asarray(p.kind).astype(np.int8)
            for name, values in p.fields.items():
                out[f"{PREFIX}{k}_field_{name}"] = np.asarray(values, float)
            times.append(frame.time)
            steps.append(frame.step)
            parts.append(part)
            k += 1
    if not k:
        return {}
    out[f"{PREFIX}_time"] = np.asarray(times, float)
    out[f"{PREFIX}_step"] = np.asarray(steps, np.int64)
    out[f"{PREFIX}_part"] = np.asarray(parts, np.int64)
    return out


@dataclass
class StoredFrame:
    time: float
    step: int
    part: int
    particles: Particles


def has_frames(path: Path) -> bool:
    """Whether the arrays file ``path`` holds frames (False when it is missing or unreadable)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return f"{PREFIX}_time" in data.files
    except Exception:  # noqa: BLE001 - missing, truncated: no frames to use
        return False


def read_frames(arrays: dict[str, np.ndarray], where: str = "") -> list[StoredFrame]:
    """The frames stored in a run's arrays ([] when it kept none); InputFileError when they
    are incomplete."""
    if f"{PREFIX}_time" not in arrays:
        return []
    times = np.asarray(arrays[f"{PREFIX}_time"], float)
    steps = np.asarray(arrays.get(f"{PREFIX}_step", np.zeros(len(times))), np.int64)
    parts = np.asarray(arrays.get(f"{PREFIX}_part", np.zeros(len(times))), np.int64)
    out = []
    for k, t in enumerate(times):
        keys = [f"{PREFIX}{k}_{name}" for name in ("pos", "vel", "pressure", "kind")]
        missing = [key for key in keys if key not in arrays]
        if missing:
            raise InputFileError(f"{where or 'arrays'}: frame {k} lacks {', '.join(missing)}")
        head = f"{PREFIX}{k}_field_"
        fields = {key[len(head):]: np.asarray(v, float) for key, v in arrays.items()
                  if key.startswith(head)}
        p = Particles(np.asarray(arrays[keys[0]], float), np.asarray(arrays[keys[1]], float),
                      np.asarray(arrays[keys[3]]).astype(int), np.asarray(arrays[keys[2]], float),
                      fields)
        out.append(StoredFrame(float(t), int(steps[k]), int(parts[k]), p))
    return out

