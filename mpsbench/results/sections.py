"""Sections of a results folder: a case's records rendered once per solver (and across solvers
when several ran), with the pass/fail rules, the overview rows and the header line that the
summary (:mod:`.summary`) and the page (:mod:`.html`) both show.

Pass/fail: a (case, solver) fails when one of its gates fails or none of its runs completed;
a case fails when one of its solvers fails, or it could not be loaded, planned or rendered.
Claims (docs/method.md section 8) never fail a case; with --strict-claims a refuted claim fails
the whole run (:func:`exit_ok`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.cases import Case, CaseCheck
from mpsbench.errors import where
from mpsbench.results.case_report import Rendered, render_case_outputs
from mpsbench.results.paths import component, inside
from mpsbench.results.records import solver_folder, solver_label


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
    # with an outside code among them: accuracy and speed per physical parameter set
    # (:mod:`.cross_code`), also written to cross-code.csv / cross-code.md in the case folder
    cross_code: pd.DataFrame | None = None
    cross_code_caption: str = ""
    error: str = ""

    @property
    def passed(self) -> bool:
        """Every gate of every solver passed (claims do not count)."""
        return (not self.error and bool(self.solvers)
                and all(s.rendered.passed for s in self.solvers))

    @property
    def refuted(self) -> list[CaseCheck]:
        return [c for s in self.solvers for c in s.rendered.refuted]


def exit_ok(sections: list[CaseSection], strict_claims: bool = False) -> bool:
    """The exit verdict: every case passes its gates (and, with ``strict_claims``, no claim is
    refuted)."""
    ok = all(s.passed for s in sections)
    return ok and not (strict_claims and any(s.refuted for s in sections))


def solver_order(records: list[dict[str, Any]]) -> list[str]:
    """The solver specs of the records in order of appearance (name, or name:options)."""
    return list(dict.fromkeys(solver_label(r) for r in records))


def in_solver_order(records: list[dict[str, Any]], solvers: Any) -> list[dict[str, Any]]:
    """``records`` with the solvers in the order given (a manifest's ``solvers``, the command
    line's order; stable, unknown specs last): the stored files are read in name order, and the
    first solver is the one the others' time to solution is relative to."""
    if not isinstance(solvers, list) or not solvers:
        return records
    rank = {str(spec): k for k, spec in enumerate(solvers)}
    return sorted(records, key=lambda r: rank.get(solver_label(r), len(rank)))


def by_spec(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The records as the case's tables and figures see them: ``solver`` holds the whole spec,
    so runs of one backend with different options are told apart (the records themselves keep
    the name and the options in separate columns)."""
    return [{**r, "solver": solver_label(r)} if r.get("solver_options") else r for r in records]


def _version(records: list[dict[str, Any]]) -> str:
    return next((str(r["solver_version"]) for r in records if r.get("solver_version")), "")


def render_case(case: Case, records: list[dict[str, Any]], folder: Path) -> CaseSection:
    """Write a case's outputs (per solver too when there are several) and describe them."""
    section = CaseSection(case.name, case.title, case.description.strip(), folder, records)
    if not records:
        section.error = "no runs were planned for this tier"
        return section
    solvers = solver_order(records)
    view = by_spec(records)
    if len(solvers) == 1:
        rendered = render_case_outputs(case, view, folder)
        section.solvers = [SolverSection(solvers[0], _version(records), rendered)]
        return section
    section.combined = render_case_outputs(case, view, folder)
    section.by_solver = solver_table(case, view)
    _cross_code(section, case, view, folder)
    for solver in solvers:
        recs = [r for r in view if r.get("solver") == solver]
        sub = inside(folder, folder / "by-solver" / component("solver", solver_folder(solver)))
        out = render_case_outputs(case, recs, sub, arrays_dir=folder)
        section.solvers.append(SolverSection(solver, _version(recs), out))
    return section


def _cross_code(section: CaseSection, case: Case, records: list[dict[str, Any]],
                folder: Path) -> None:
    from mpsbench.results.case_report import markdown_table
    from mpsbench.results.cross_code import cross_code_caption, cross_code_table
    from mpsbench.results.escape import md_escape
    from mpsbench.results.records import atomic_write_text

    table = cross_code_table(case, records)
    if table.empty:
        return
    section.cross_code = table
    section.cross_code_caption = cross_code_caption(case, records)
    atomic_write_text(folder / "cross-code.csv", table.to_csv(index=False))
    atomic_write_text(folder / "cross-code.md",
                      f"# {md_escape(case.title or case.name)}: cross-code table\n\n"
                      f"{md_escape(section.cross_code_caption)}\n\n{markdown_table(table)}")


def _compact(wide: pd.DataFrame, metrics: list[str], solvers: list[str]) -> pd.DataFrame:
    """Columns ``metric [solver]``, without the metrics no solver reported in any row (the
    Lobovsky sensors of a Koshizuka-Oka-only study), and with one ``metric [all solvers]``
    column for a metric every solver reports the same in every row (a set-up value such as the
    column width or the sampling interval; or a result two backends agree on to the last bit,
    which the column's name then says).  Solvers in ``solvers`` order."""
    out: dict[str, pd.Series] = {}
    for m in metrics:
        rank = {name: k for k, name in enumerate(solvers)}
        cols = sorted((c for c in wide.columns if c[0] == m),
                      key=lambda c: rank.get(c[1], len(rank)))
        if not cols or all(wide[c].isna().all() for c in cols):
            continue
        first = wide[cols[0]]
        cost = m in ("particle_steps_per_s", "wall_time_s")  # compared even when equal
        if not cost and len(cols) > 1 and all(wide[c].equals(first) for c in cols[1:]):
            out[f"{m} [all solvers]"] = first
            continue
        for c in cols:
            out[f"{c[0]} [{c[1]}]"] = wide[c]
    return pd.DataFrame(out, index=wide.index)


def solver_table(case: Case, records: list[dict[str, Any]]) -> pd.DataFrame:
    """The case's metrics (and throughput, wall time) per parameter set, one column per solver,
    and the time to solution of each solver against the first: ``wall_time_s`` ratio (every
    solver ran the same parameter set to the same simulated time, so the ratio of wall times is
    that of times to solution; a semi-implicit backend trades many cheap steps for few costly
    ones)."""
    df = pd.DataFrame.from_records(records)
    metrics = [m for m in [*case.metrics, "particle_steps_per_s", "wall_time_s"]
               if m in df.columns]
    if df.empty or not metrics:
        return pd.DataFrame()
    varying = [p.name for p in case.params
               if p.name in df.columns and df[p.name].astype(str).nunique() > 1]
    key = varying or ["case"]
    table = df.set_index([*key, "solver"])[metrics]
    table = table[~table.index.duplicated()]
    wide = pd.DataFrame(table.unstack("solver"))
    solvers = solver_order(records)
    wide = _compact(wide, metrics, solvers)
    if "wall_time_s" in metrics and "status" in df.columns and len(solvers) > 1:
        # a run that diverged or failed stopped early: its wall time is no time to solution
        status = df.set_index([*key, "solver"])["status"]
        done = pd.DataFrame(status[~status.index.duplicated()].unstack("solver")) == "completed"

        def solved(solver: str) -> pd.Series:
            wall = pd.to_numeric(wide[f"wall_time_s [{solver}]"], errors="coerce")
            return wall.where(done[solver].reindex(wall.index, fill_value=False) & (wall > 0))

        for other in solvers[1:]:
            if f"wall_time_s [{other}]" in wide.columns and f"wall_time_s [{solvers[0]}]" in wide:
                ratio = solved(other) / solved(solvers[0])
                wide[f"time to solution [{other} / {solvers[0]}]"] = ratio.round(3)
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
        view = by_spec(records)
        for s in solvers:
            recs = [r for r in view if r.get("solver") == s]
            rendered = Rendered.from_disk(folder / "by-solver" / solver_folder(s), recs)
            section.solvers.append(SolverSection(s, _version(recs), rendered))
    if not records:
        section.error = "no records"
    undecided = [s.rendered.folder for s in section.solvers
                 if not (s.rendered.folder / "checks.json").is_file()]
    if records and undecided:  # no stored checks: nothing can decide pass or fail
        section.error = (f"no checks.json in {undecided[0]}: the case's checks can neither "
                         "be run nor read, so nothing decides pass or fail")
    return section


def safe_render_case(case: Case, records: list[dict[str, Any]], folder: Path) -> CaseSection:
    """:func:`render_case`, but a bug in the case's tables/figures/checks fails only that case."""
    try:
        return render_case(case, records, folder)
    except Exception as exc:  # noqa: BLE001 - reported in the section, the other cases go on
        return CaseSection(case.name, case.title, case.description.strip(), folder, records,
                           error=f"rendering failed: {type(exc).__name__}: {exc}{where(exc)}")


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def overview_rows(sections: list[CaseSection]) -> list[dict[str, Any]]:
    rows = []
    for sec in sections:
        if sec.error and not sec.solvers:
            rows.append({"case": sec.name, "solver": "", "runs": len(sec.records), "completed": 0,
                         "not completed": 0, "gates passed": "", "claims": "",
                         "result": "FAIL", "wall time [s]": 0.0})
            continue
        for s in sec.solvers:
            r = s.rendered
            n_ok = sum(1 for c in r.gates if c.passed)
            n_dec = sum(1 for c in r.gates if c.passed is not None)
            rows.append({
                "case": sec.name, "solver": s.solver, "runs": len(r.records),
                "completed": r.completed, "not completed": len(r.records) - r.completed,
                "gates passed": f"{n_ok}/{n_dec}" if r.gates else (
                    "(no supported run)" if r.records and len(r.unsupported) == len(r.records)
                    else "(none)"),
                "claims": claim_counts(r.claims),
                "result": verdict(r.passed and not sec.error),
                "wall time [s]": round(sum(float(x.get("wall_time_s") or 0) for x in r.records), 1),
            })
    return rows


def claim_counts(claims: list[CaseCheck]) -> str:
    """``2 supported, 1 refuted`` (empty without claims)."""
    counts: dict[str, int] = {}
    for c in claims:
        counts[c.verdict] = counts.get(c.verdict, 0) + 1
    return ", ".join(f"{counts[v]} {v}" for v in ("supported", "refuted", "inconclusive")
                     if v in counts)


def claim_rows(sections: list[CaseSection]) -> list[dict[str, Any]]:
    """One row per claim tested (per case, and per solver when several ran): claim, source,
    rule, verdict, evidence (the numbers and the number of runs)."""
    several = any(len(sec.solvers) > 1 for sec in sections)
    rows = []
    for sec in sections:
        for s in sec.solvers:
            for c in s.rendered.claims:
                row = {"claim": f"{c.claim} {c.name}".strip(), "case": sec.name}
                if several:
                    row["solver"] = s.solver
                n = len(c.runs)
                runs = f" ({n} run{'' if n == 1 else 's'})" if n else ""
                row.update({"source": c.source, "rule": c.rule, "verdict": c.verdict,
                            "evidence": c.detail + runs})
                rows.append(row)
    return sorted(rows, key=lambda r: (_claim_number(r["claim"]), r["case"]))


def _claim_number(text: str) -> tuple[int, str]:
    head = text.split(" ", 1)[0]
    digits = "".join(ch for ch in head if ch.isdigit())
    return (int(digits) if digits else 10**6, head)


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
