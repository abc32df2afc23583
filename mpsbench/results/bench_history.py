"""The history of ``mpsbench bench --save`` and ``bench --compare`` against it.

Layout: pytest-benchmark's file storage, so ``pytest-benchmark list`` / ``compare`` read these
files next to the ones the pytest-benchmark suite saves (``--benchmark-autosave``)::

    STORAGE/<machine id>/<NNNN>_<commit>_<YYYYmmdd_HHMMSS>[_uncommitted-changes].json

``STORAGE`` defaults to ``.benchmarks`` (pytest-benchmark's default too), the machine id is
pytest-benchmark's (``Linux-CPython-3.11-64bit``), NNNN counts up per machine id.  One file is
one ``mpsbench bench`` run::

    machine_info   pytest-benchmark's keys (system, machine, python_version, ...) and
                   ``mpsbench``: the environment of every record (docs/columns.md)
    commit_info    id (mpsbench's commit), dirty, project
    benchmarks     one entry per solver and size: name ``bench[<solver>-<n>]``, ``stats`` over
                   the wall seconds of its blocks (min, max, mean, stddev, median, q1, q3, iqr,
                   rounds, ops, ...), ``extra_info``: the bench record
    datetime, version
    mpsbench_bench the document ``mpsbench bench --json`` prints (environment, settings,
                   records): what ``--compare`` reads

``--compare`` matches records by solver and particle count and compares two figures: the
median particle-steps/s, and the median speed-up over the first solver (when both runs have
the same first solver).  A figure counts as a *slowdown* when the current median is more than
``threshold`` (default 10 %) below the saved one *and* the two runs' interquartile ranges do
not overlap (so the drop is beyond the spread either run measured).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import platform
import re
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mpsbench.results.records import atomic_write_text

DEFAULT_STORAGE = Path(".benchmarks")
DEFAULT_THRESHOLD = 0.10
KEY = "mpsbench_bench"
FILE_RE = re.compile(r"^(\d{4})_.*\.json$")


class HistoryError(ValueError):
    """No saved run to compare with, or a file that is not one; the message says which."""


def machine_id() -> str:
    """pytest-benchmark's machine id: system, Python implementation and version, word size."""
    return "-".join((platform.system(), platform.python_implementation(),
                     ".".join(platform.python_version_tuple()[:2]), platform.architecture()[0]))


def _stats(data: Sequence[float]) -> dict[str, Any]:
    """pytest-benchmark's ``stats`` of a list of round times [s]."""
    xs = sorted(float(x) for x in data)
    n = len(xs)
    mean = statistics.fmean(xs)
    std = statistics.stdev(xs) if n > 1 else 0.0
    q1, median, q3 = (statistics.quantiles(xs, n=4, method="inclusive") if n > 1
                      else (xs[0], xs[0], xs[0]))
    iqr = q3 - q1
    inner = [x for x in xs if q1 - 1.5 * iqr <= x <= q3 + 1.5 * iqr]
    std_out = sum(1 for x in xs if abs(x - mean) > std) if std > 0 else 0
    return {
        "min": xs[0], "max": xs[-1], "mean": mean, "stddev": std, "rounds": n,
        "median": median, "iqr": iqr, "q1": q1, "q3": q3, "iqr_outliers": n - len(inner),
        "stddev_outliers": std_out, "outliers": f"{std_out};{n - len(inner)}",
        "ld15iqr": inner[0], "hd15iqr": inner[-1], "ops": 1.0 / mean if mean > 0 else 0.0,
        "total": sum(xs), "iterations": 1,
    }


def history_document(doc: dict[str, Any]) -> dict[str, Any]:
    """The file stored for one ``bench --json`` document (layout: the module docstring)."""
    env = doc.get("environment", {})
    benchmarks = []
    for rec in doc.get("records", []):
        param = f"{rec['solver']}-{rec['n']}"
        benchmarks.append({
            "group": f"mpsbench bench n={rec['n']}", "name": f"bench[{param}]",
            "fullname": f"mpsbench bench[{param}]", "params": {"solver": rec["solver"],
                                                               "n": rec["n"]},
            "param": param, "extra_info": rec,
            "options": {"steps_per_round": rec.get("steps"), "timer": "perf_counter"},
            "stats": _stats(rec["block_wall_s"]),
        })
    return {
        "machine_info": {
            "node": platform.node(), "processor": platform.processor(),
            "machine": platform.machine(), "python_implementation":
                platform.python_implementation(), "python_version": platform.python_version(),
            "release": platform.release(), "system": platform.system(),
            "cpu": {"brand_raw": env.get("cpu_model"), "count": env.get("cpu_count")},
            "mpsbench": env,
        },
        "commit_info": {"id": env.get("git_commit") or "unversioned",
                        "dirty": bool(env.get("git_dirty")), "project": "mpsbench"},
        "benchmarks": benchmarks,
        "datetime": _dt.datetime.now(_dt.UTC).isoformat(),
        "version": "mpsbench bench",
        KEY: doc,
    }


def save(doc: dict[str, Any], storage: Path = DEFAULT_STORAGE) -> Path:
    """Store one bench run; return the file written."""
    folder = Path(storage) / machine_id()
    folder.mkdir(parents=True, exist_ok=True)
    numbers = [int(m.group(1)) for p in folder.iterdir() if (m := FILE_RE.match(p.name))]
    env = doc.get("environment", {})
    stamp = _dt.datetime.now().strftime("%Y%m%d_%H%M%S")
    name = f"{max(numbers, default=0) + 1:04d}_{env.get('git_commit') or 'unversioned'}_{stamp}"
    if env.get("git_dirty"):
        name += "_uncommitted-changes"
    path = folder / f"{name}.json"
    atomic_write_text(path, json.dumps(history_document(doc), indent=1))
    return path


def _read(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data.get(KEY) if isinstance(data, dict) and isinstance(data.get(KEY), dict) else None


def load(ref: str | None, storage: Path = DEFAULT_STORAGE) -> tuple[Path, dict[str, Any]]:
    """(file, bench document) of a saved run: ``ref`` is a file, a run number (``7`` or
    ``0007``) of this machine's history, or None for its latest ``mpsbench bench`` run (files
    the pytest-benchmark suite saved in the same folder are passed over)."""
    folder = Path(storage) / machine_id()
    if ref is not None and Path(ref).is_file():
        doc = _read(Path(ref))
        if doc is None:
            raise HistoryError(f"{ref} is not a file saved by 'mpsbench bench --save'")
        return Path(ref), doc
    files = sorted((p for p in folder.glob("*.json") if FILE_RE.match(p.name)), reverse=True)
    if ref is not None:
        if not ref.isdigit():
            raise HistoryError(f"--compare {ref!r}: not a file, nor a run number of {folder}")
        files = [p for p in files if int(p.name[:4]) == int(ref)]
    for path in files:
        doc = _read(path)
        if doc is not None:
            return path, doc
    what = f"run {ref}" if ref is not None else "saved 'mpsbench bench' run"
    raise HistoryError(f"no {what} in {folder}: save one with 'mpsbench bench --save'")


@dataclass
class Row:
    """One figure of one solver and size, saved against now."""

    solver: str
    n: int
    figure: str  # "particle-steps/s" or "speed-up vs <first>"
    saved: float
    now: float
    saved_iqr: tuple[float, float]
    now_iqr: tuple[float, float]
    slowdown: bool

    @property
    def ratio(self) -> float:
        return self.now / self.saved if self.saved else math.nan


def _row(solver: str, n: int, figure: str, b: dict[str, Any], c: dict[str, Any], key: str,
         q1: str, q3: str, threshold: float) -> Row:
    saved, now = float(b[key]), float(c[key])
    b_iqr, c_iqr = (float(b[q1]), float(b[q3])), (float(c[q1]), float(c[q3]))
    slower = now < saved * (1.0 - threshold) and c_iqr[1] < b_iqr[0]
    return Row(solver, n, figure, saved, now, b_iqr, c_iqr, slower)


def compare(saved: dict[str, Any], current: dict[str, Any],
            threshold: float = DEFAULT_THRESHOLD) -> list[Row]:
    """The figures of every (solver, n) in both runs (see the module docstring)."""
    base = {(r["solver"], r["n"]): r for r in saved.get("records", [])}
    rows: list[Row] = []
    for c in current.get("records", []):
        b = base.get((c["solver"], c["n"]))
        if b is None:
            continue
        rows.append(_row(c["solver"], c["n"], "particle-steps/s", b, c, "particle_steps_per_s",
                         "particle_steps_per_s_q1", "particle_steps_per_s_q3", threshold))
        first = c.get("first_solver")
        if first and first != c["solver"] and b.get("first_solver") == first:
            rows.append(_row(c["solver"], c["n"], f"speed-up vs {first}", b, c,
                             "speedup_vs_first", "speedup_q1", "speedup_q3", threshold))
    if not rows:
        raise HistoryError("the saved run has no solver and particle count in common with "
                           "this one: " + ", ".join(sorted(f"{s} n={n}" for s, n in base)))
    return rows


def _fmt(value: float, iqr: tuple[float, float], figure: str) -> str:
    if figure == "particle-steps/s":  # in millions
        return f"{value / 1e6:.3f}M [{iqr[0] / 1e6:.3f}-{iqr[1] / 1e6:.3f}]"
    return f"{value:.3f}x [{iqr[0]:.3f}-{iqr[1]:.3f}]"


def format_rows(rows: Sequence[Row]) -> str:
    """A plain-text table: saved and current figure with their quartiles, and the ratio."""
    head = (f"{'solver':<16} {'n':>7} {'figure':<24} {'saved [q1-q3]':>24} "
            f"{'now [q1-q3]':>24} {'now/saved':>9}")
    lines = [head, "-" * len(head)]
    for r in rows:
        flag = "  SLOWER" if r.slowdown else ""
        lines.append(f"{r.solver:<16} {r.n:>7} {r.figure:<24} "
                     f"{_fmt(r.saved, r.saved_iqr, r.figure):>24} "
                     f"{_fmt(r.now, r.now_iqr, r.figure):>24} {r.ratio:>8.3f}x{flag}")
    return "\n".join(lines)
