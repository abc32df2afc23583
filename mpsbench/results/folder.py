"""The results folder of ``mpsbench validate all``: all cases, all solvers, one report.

This module writes the folder (calling :mod:`.summary` and :mod:`.html`) and reads it back.

Layout (``OUT`` defaults to ``reports/<YYYYmmdd-HHMM>-<tier>/``)::

    OUT/results.csv, results.json   every record of every case (one per run)
    OUT/summary.md                  per case and solver: pass/fail, finding, headline table
    OUT/index.html                  one self-contained page (figures embedded, no network)
    OUT/figures/<case>/<name>.png   copies of every case figure; with several solvers also
                                    figures/<case>/<solver>/<name>.png (per-solver figures)
    OUT/manifest.json               tier, solvers, command, times, environment, unavailable cases
    OUT/<case>/                     the case folder (runs/, results, tables/, figures/,
                                    checks.json, findings.md, report.md; see
                                    mpsbench.results.case_report)
    OUT/<case>/by-solver/<solver>/  only with several solvers: that solver's tables, figures,
                                    checks and report (the case folder then compares solvers)

A folder written by ``mpsbench validate CASE`` (a single case folder, ``runs/`` at the top) is a
results folder too: ``mpsbench report`` renders its summary.md and index.html in place.

Pass/fail rules (gates decide; claims only with --strict-claims): :mod:`.sections`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.errors import InputFileError
from mpsbench.results.case_report import Rendered
from mpsbench.results.html import render_index
from mpsbench.results.paths import atomic_copy, component, inside, safe_dir
from mpsbench.results.records import (
    COMMON_COLUMNS,
    ENV_COLUMNS,
    atomic_write_text,
    load_records,
    solver_folder,
)
from mpsbench.results.sections import CaseSection, exit_ok
from mpsbench.results.summary import render_summary

MANIFEST = "manifest.json"


def all_records_frame(records: list[dict[str, Any]], param_names: list[str]) -> pd.DataFrame:
    """Every record: common columns, then parameters, then metrics, then the environment."""
    df = pd.DataFrame.from_records(records)
    if df.empty:
        return df
    first = [c for c in COMMON_COLUMNS if c in df.columns]
    params = [c for c in dict.fromkeys(param_names) if c in df.columns and c not in first]
    last = [c for c in ENV_COLUMNS if c in df.columns]
    rest = [c for c in df.columns if c not in first and c not in params and c not in last]
    return df[first + params + rest + last]


def copy_figures(out: Path, sections: list[CaseSection]) -> dict[Path, Path]:
    """Copy every figure to ``out/figures/<case>/[<solver>/]``; return source -> copy."""
    copies: dict[Path, Path] = {}
    for sec in sections:
        if sec.folder is None or sec.folder.resolve() == out.resolve():
            continue  # a single-case folder: its figures/ already is the top-level one
        parts: list[tuple[str, Rendered]] = []
        several = sec.combined is not None
        if sec.combined is not None:
            parts.append(("", sec.combined))
        parts += [(solver_folder(s.solver) if several else "", s.rendered) for s in sec.solvers]
        case_dir = out / "figures" / component("case", sec.name)
        for sub, rendered in parts:
            dest = case_dir / component("solver", sub) if sub else case_dir
            for fig in rendered.figures:
                if fig.exists():
                    safe_dir(out, dest)
                    atomic_copy(fig, inside(out, dest / component("figure", fig.name)))
                    copies[fig] = dest / fig.name
    return copies


def write_top_level(
    out: Path, sections: list[CaseSection], manifest: dict[str, Any], param_names: list[str],
    *, write_results: bool = True,
) -> bool:
    """Write results.csv/json, figures/, summary.md and index.html; return True when every
    case passes its gates (and, when the manifest says ``strict_claims``, no claim is
    refuted)."""
    out.mkdir(parents=True, exist_ok=True)
    records = [r for sec in sections for r in sec.records]
    if write_results:
        atomic_write_text(out / "results.csv",
                          all_records_frame(records, param_names).to_csv(index=False))
        atomic_write_text(out / "results.json", json.dumps(records, indent=1, default=str))
    copy_figures(out, sections)
    atomic_write_text(out / "summary.md", render_summary(sections, manifest, out))
    atomic_write_text(out / "index.html", render_index(sections, manifest, out))
    return exit_ok(sections, bool(manifest.get("strict_claims")))


# ---------------------------------------------------------------- reading a folder back


def read_manifest(out: Path) -> dict[str, Any]:
    """The folder's manifest.json ({} when there is none: a folder from an older version);
    InputFileError when it is there but unreadable, truncated or not an object."""
    path = out / MANIFEST
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, ValueError, RecursionError) as exc:
        raise InputFileError(f"{path}: unreadable or truncated ({type(exc).__name__}: "
                             f"{str(exc)[:120]})") from None
    if not isinstance(data, dict) or not isinstance(data.get("cases", []), list) \
            or not all(isinstance(c, dict) for c in data.get("cases", [])):
        raise InputFileError(f"{path}: not a results manifest (an object whose 'cases' is a "
                             "list of objects)")
    return data


def case_folders(out: Path) -> list[tuple[str, Path, list[dict[str, Any]]]]:
    """(case name, case folder, records) for every case found in a results folder.

    Every record must be readable (:func:`~mpsbench.results.records.load_records` names the
    first that is not) and belong to its folder's case: one case per folder, and in a folder
    of several cases the sub-folder is named after it.
    """
    found: list[tuple[str, Path, list[dict[str, Any]]]] = []
    if (out / "runs").is_dir():  # a single-case folder from 'mpsbench validate CASE'
        records = load_records(out)
        name = _one_case(out, records) or out.name
        return [(name, out, records)]
    for sub in sorted(p for p in out.iterdir() if p.is_dir() and not p.name.startswith(".")):
        if (sub / "runs").is_dir():
            inside(out, sub)  # a symbolic link out of the folder is not one of its cases
            records = load_records(sub)
            name = _one_case(sub, records) or sub.name
            if name != sub.name:
                raise InputFileError(f"{sub / 'runs'}: records of case {name!r} in the folder "
                                     f"of case {sub.name!r}; move them to {name}/runs/")
            found.append((name, sub, records))
    return found


def _one_case(folder: Path, records: list[dict[str, Any]]) -> str | None:
    names = list(dict.fromkeys(str(r["case"]) for r in records))
    if len(names) > 1:
        other = next(r for r in records if r["case"] == names[1])
        raise InputFileError(f"{folder / 'runs' / (other['run_id'] + '.json')}: case "
                             f"{names[1]!r}, but the folder's other records are of case "
                             f"{names[0]!r}: one case per folder")
    return names[0] if names else None
