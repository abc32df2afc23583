"""The results folder of ``mpsbench validate all``: all cases, all solvers, one report.

Layout (``OUT`` defaults to ``reports/<YYYYmmdd-HHMM>-<tier>/``)::

    OUT/results.csv, results.json   every record of every case (one per run)
    OUT/summary.md                  per case and solver: pass/fail, finding, headline table
    OUT/index.html                  one self-contained page (figures embedded, no network)
    OUT/figures/<case>/<name>.png   copies of every case figure; with several solvers also
                                    figures/<case>/<solver>/<name>.png (per-solver figures)
    OUT/manifest.json               tier, solvers, command, times, environment, unavailable cases
    OUT/<case>/                     the case folder (runs/, results, tables/, figures/,
                                    checks.json, findings.md, report.md; see mpsbench.reporting)
    OUT/<case>/by-solver/<solver>/  only with several solvers: that solver's tables, figures,
                                    checks and report (the case folder then compares solvers)

A folder written by ``mpsbench validate CASE`` (a single case folder, ``runs/`` at the top) is a
results folder too: ``mpsbench report`` renders its summary.md and index.html in place.

Pass/fail: a (case, solver) fails when one of its checks fails or none of its runs completed;
a case fails when one of its solvers fails, or it could not be loaded, planned or rendered.
"""

from __future__ import annotations

import json
import shutil
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.cases import Case
from mpsbench.reporting import Rendered, check_lines, markdown_table, render_case_outputs
from mpsbench.study import COMMON_COLUMNS, atomic_write_text, load_records

ENV_COLUMNS = ("mpsbench_version", "python", "numpy_version", "machine", "git_commit")
MANIFEST = "manifest.json"


@dataclass
class SolverSection:
    solver: str
    version: str
    rendered: Rendered


@dataclass
class CaseSection:
    """A case in the report: one section per solver, plus a cross-solver one with several."""

    name: str
    title: str = ""
    description: str = ""
    folder: Path | None = None
    records: list[dict[str, Any]] = field(default_factory=list)
    solvers: list[SolverSection] = field(default_factory=list)
    combined: Rendered | None = None
    by_solver: pd.DataFrame | None = None  # with several solvers: metrics side by side
    error: str = ""

    @property
    def passed(self) -> bool:
        return (not self.error and bool(self.solvers)
                and all(s.rendered.passed for s in self.solvers))


def solver_order(records: list[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(str(r.get("solver", "?")) for r in records))


def _version(records: list[dict[str, Any]]) -> str:
    return next((str(r["solver_version"]) for r in records if r.get("solver_version")), "")


def render_case(case: Case, records: list[dict[str, Any]], folder: Path) -> CaseSection:
    """Write a case's outputs (per solver too when there are several) and describe them."""
    section = CaseSection(case.name, case.title, case.description.strip(), folder, records)
    if not records:
        section.error = "no runs were planned for this tier"
        return section
    solvers = solver_order(records)
    if len(solvers) == 1:
        rendered = render_case_outputs(case, records, folder)
        section.solvers = [SolverSection(solvers[0], _version(records), rendered)]
        return section
    section.combined = render_case_outputs(case, records, folder)
    section.by_solver = solver_table(case, records)
    for solver in solvers:
        recs = [r for r in records if r.get("solver") == solver]
        out = render_case_outputs(case, recs, folder / "by-solver" / solver, arrays_dir=folder)
        section.solvers.append(SolverSection(solver, _version(recs), out))
    return section


def solver_table(case: Case, records: list[dict[str, Any]]) -> pd.DataFrame:
    """The case's metrics (and throughput) per parameter set, one column per solver."""
    df = pd.DataFrame.from_records(records)
    metrics = [m for m in [*case.metrics, "particle_steps_per_s"] if m in df.columns]
    if df.empty or not metrics:
        return pd.DataFrame()
    varying = [p.name for p in case.params
               if p.name in df.columns and df[p.name].astype(str).nunique() > 1]
    key = varying or ["case"]
    table = df.set_index([*key, "solver"])[metrics]
    table = table[~table.index.duplicated()]
    wide = pd.DataFrame(table.unstack("solver"))
    wide.columns = pd.Index([f"{col[0]} [{col[1]}]" for col in wide.columns])
    return wide


def case_from_disk(name: str, records: list[dict[str, Any]], folder: Path, why: str) -> CaseSection:
    """A case section from files an earlier render wrote (the case's code is unavailable)."""
    section = CaseSection(name, name, f"_(re-rendered from files: {why})_", folder, records)
    solvers = solver_order(records)
    if len(solvers) == 1:
        section.solvers = [SolverSection(solvers[0], _version(records),
                                         Rendered.from_disk(folder, records))]
    else:
        section.combined = Rendered.from_disk(folder, records)
        for s in solvers:
            recs = [r for r in records if r.get("solver") == s]
            rendered = Rendered.from_disk(folder / "by-solver" / s, recs)
            section.solvers.append(SolverSection(s, _version(recs), rendered))
    if not records:
        section.error = "no records"
    return section


def safe_render_case(case: Case, records: list[dict[str, Any]], folder: Path) -> CaseSection:
    """:func:`render_case`, but a bug in the case's tables/figures/checks fails only that case."""
    try:
        return render_case(case, records, folder)
    except Exception as exc:  # noqa: BLE001 - reported in the section, the other cases go on
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" (at {tb[-1].filename}:{tb[-1].lineno})" if tb else ""
        return CaseSection(case.name, case.title, case.description.strip(), folder, records,
                           error=f"rendering failed: {type(exc).__name__}: {exc}{where}")


# ---------------------------------------------------------------- top-level files


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
        parts += [(s.solver if several else "", s.rendered) for s in sec.solvers]
        for sub, rendered in parts:
            dest = out / "figures" / sec.name / sub if sub else out / "figures" / sec.name
            for fig in rendered.figures:
                if fig.exists():
                    dest.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(fig, dest / fig.name)
                    copies[fig] = dest / fig.name
    return copies


def write_top_level(
    out: Path, sections: list[CaseSection], manifest: dict[str, Any], param_names: list[str],
    *, write_results: bool = True,
) -> bool:
    """Write results.csv/json, figures/, summary.md and index.html; return True when all pass."""
    from mpsbench.html import render_index

    out.mkdir(parents=True, exist_ok=True)
    records = [r for sec in sections for r in sec.records]
    if write_results:
        all_records_frame(records, param_names).to_csv(out / "results.csv", index=False)
        atomic_write_text(out / "results.json", json.dumps(records, indent=1, default=str))
    copy_figures(out, sections)
    atomic_write_text(out / "summary.md", render_summary(sections, manifest, out))
    atomic_write_text(out / "index.html", render_index(sections, manifest, out))
    return all(sec.passed for sec in sections)


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def overview_rows(sections: list[CaseSection]) -> list[dict[str, Any]]:
    rows = []
    for sec in sections:
        if sec.error and not sec.solvers:
            rows.append({"case": sec.name, "solver": "", "runs": len(sec.records), "completed": 0,
                         "not completed": 0, "checks passed": "", "result": "FAIL",
                         "wall time [s]": 0.0})
            continue
        for s in sec.solvers:
            r = s.rendered
            n_ok = sum(1 for c in r.checks if c.passed)
            n_dec = sum(1 for c in r.checks if c.passed is not None)
            rows.append({
                "case": sec.name, "solver": s.solver, "runs": len(r.records),
                "completed": r.completed, "not completed": len(r.records) - r.completed,
                "checks passed": f"{n_ok}/{n_dec}" if r.checks else "(none)",
                "result": verdict(r.passed and not sec.error),
                "wall time [s]": round(sum(float(x.get("wall_time_s") or 0) for x in r.records), 1),
            })
    return rows


def header_lines(manifest: dict[str, Any]) -> list[str]:
    env = manifest.get("environment", {})
    bits = [f"tier **{manifest.get('tier', '?')}**",
            f"solvers {', '.join(manifest.get('solvers', [])) or '?'}",
            f"mpsbench {env.get('mpsbench_version', '?')}"]
    if env.get("git_commit"):
        bits.append(f"commit {env['git_commit']}")
    bits.append(f"{env.get('machine', '?')}, Python {env.get('python', '?')}")
    if manifest.get("started"):
        bits.append(f"started {manifest['started']}")
    if manifest.get("wall_s") is not None:
        bits.append(f"took {float(manifest['wall_s']):.0f} s with {manifest.get('jobs', 1)} job(s)")
    return ["; ".join(bits) + "."]


def render_summary(sections: list[CaseSection], manifest: dict[str, Any], out: Path) -> str:
    ok = all(s.passed for s in sections)
    n_pass = sum(1 for s in sections if s.passed)
    lines = [f"# mpsbench validation: {verdict(ok)} ({n_pass}/{len(sections)} cases pass)", ""]
    lines += header_lines(manifest) + [""]
    overview = pd.DataFrame(overview_rows(sections))
    lines += ["## Overview", "", _md(overview), ""]
    for sec in sections:
        lines += [f"## {sec.title or sec.name} (`{sec.name}`): {verdict(sec.passed)}", ""]
        if sec.error:
            lines += [f"**Error:** {sec.error}", ""]
        several = len(sec.solvers) > 1
        for s in sec.solvers:
            r = s.rendered
            if several:
                lines += [f"### solver {s.solver} {s.version}: {verdict(r.passed)}", ""]
            else:
                lines += [f"Solver {' '.join(filter(None, (s.solver, s.version)))}: "
                          f"{len(r.records)} runs, {r.completed} completed.", ""]
            lines += _rendered_lines(r, out)
        if sec.by_solver is not None and not sec.by_solver.empty:
            lines += ["### all solvers: metrics side by side", "", markdown_table(sec.by_solver)]
        if sec.folder is not None and (sec.folder / "report.md").exists():
            rel = _rel(sec.folder / "report.md", out)
            lines += [f"Full report: [{rel}]({rel})", ""]
    return "\n".join(lines).rstrip() + "\n"


def _rendered_lines(r: Rendered, out: Path) -> list[str]:
    lines: list[str] = []
    if r.failures:
        lines += ["Fails: " + "; ".join(r.failures) + ".", ""]
    if r.findings.strip():
        lines += [r.findings.strip(), ""]
    if r.checks:
        lines += ["Checks:", ""] + check_lines(r.checks) + [""]
    head = r.headline_table()
    if head is not None:
        lines += [f"Table **{head[0]}**:", "", markdown_table(head[1])]
    return lines


def _md(df: pd.DataFrame) -> str:
    return markdown_table(df) if df.empty else str(df.to_markdown(index=False)) + "\n"


def _rel(path: Path, base: Path) -> str:
    try:
        return path.resolve().relative_to(base.resolve()).as_posix()
    except ValueError:
        return path.as_posix()


# ---------------------------------------------------------------- reading a folder back


def read_manifest(out: Path) -> dict[str, Any]:
    try:
        data = json.loads((out / MANIFEST).read_text())
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def case_folders(out: Path) -> list[tuple[str, Path, list[dict[str, Any]]]]:
    """(case name, case folder, records) for every case found in a results folder."""
    found: list[tuple[str, Path, list[dict[str, Any]]]] = []
    if (out / "runs").is_dir():  # a single-case folder from 'mpsbench validate CASE'
        records = load_records(out)
        names = list(dict.fromkeys(str(r.get("case")) for r in records)) or [out.name]
        return [(names[0], out, records)]
    for sub in sorted(p for p in out.iterdir() if p.is_dir()):
        if (sub / "runs").is_dir():
            records = load_records(sub)
            name = str(records[0].get("case")) if records else sub.name
            found.append((name, sub, records))
    return found
