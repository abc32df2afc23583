"""Write a case's output folder: results, tables, figures, checks and a plain-word report.

Layout of a case folder::

    results.csv, results.json   one row per run (common columns + parameters + metrics)
    tables/<name>.csv|.md       the case's tables
    figures/<name>.png          the case's figures
    checks.json                 each gate (pass/fail) and claim (supported/refuted/inconclusive)
    findings.md                 the case's findings in plain words (also in report.md)
    report.md                   findings in plain words, claims, gates, tables, figure links

A case with refinement sets (``Case.refinements``) also gets the table
``numerical_uncertainty`` (one row per set: levels, convergence, order, u_num; docs/method.md
section 9).

Every file is written atomically (a temporary file renamed into place; figures are drawn into
a scratch folder and renamed), and text from records is escaped in the Markdown files
(:mod:`mpsbench.results.escape`).
"""

from __future__ import annotations

import html
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from mpsbench.cases import Case, CaseCheck
from mpsbench.cases.checks import claims as claims_of
from mpsbench.cases.checks import gates as gates_of
from mpsbench.errors import InputFileError
from mpsbench.results.escape import md_escape, md_frame
from mpsbench.results.paths import component
from mpsbench.results.records import COMMON_COLUMNS, NOT_RUN, atomic_write_text, load_arrays


def records_frame(records: list[dict[str, Any]], case: Case | None = None) -> pd.DataFrame:
    """Records as a DataFrame with the common columns first, then parameters, then the rest."""
    df = pd.DataFrame.from_records(records)
    if df.empty:
        return df
    first = [c for c in COMMON_COLUMNS if c in df.columns]
    params = [p.name for p in case.params if p.name in df.columns] if case else []
    rest = [c for c in df.columns if c not in first and c not in params]
    return df[first + params + rest]


def markdown_table(df: pd.DataFrame, floatfmt: str = ".4g") -> str:
    if df.empty:
        return "_(no data)_\n"
    return str(md_frame(df).to_markdown(floatfmt=floatfmt)) + "\n"


@dataclass
class Rendered:
    """What :func:`render_case_outputs` wrote for one set of records (a case for one solver,
    or a case across all solvers), or what an earlier render left on disk."""

    records: list[dict[str, Any]]
    checks: list[CaseCheck]
    tables: dict[str, pd.DataFrame]
    figures: list[Path]
    findings: str
    folder: Path
    headline: str = ""
    headline_figure: str = ""

    def ordered_figures(self) -> list[Path]:
        """The figures with the headline one (``Case.headline_figure``, a file stem; default
        the first the case drew) first."""
        first = [f for f in self.figures if f.stem == self.headline_figure][:1]
        return first + [f for f in self.figures if f not in first]

    @classmethod
    def from_disk(cls, folder: Path, records: list[dict[str, Any]]) -> Rendered:
        """What an earlier render left in ``folder`` (used when the case's code is unavailable)."""
        checks = _read_checks(folder / "checks.json")
        tables = {p.stem: _read_table(p) for p in sorted((folder / "tables").glob("*.csv"))}
        figures = sorted((folder / "figures").glob("*.png"))
        path = folder / "findings.md"
        # findings.md was written escaped (render_case_outputs): back to the case's text
        findings = html.unescape(_read_text(path)) if path.exists() else ""
        return cls(records, checks, tables, figures, findings, folder)

    @property
    def completed(self) -> int:
        return sum(1 for r in self.records if r.get("status") == "completed")

    @property
    def unsupported(self) -> list[dict[str, Any]]:
        """The runs the solver's capabilities excluded (never a failure)."""
        return [r for r in self.records if r.get("status") in NOT_RUN]

    @property
    def gates(self) -> list[CaseCheck]:
        return gates_of(self.checks)

    @property
    def claims(self) -> list[CaseCheck]:
        return claims_of(self.checks)

    @property
    def refuted(self) -> list[CaseCheck]:
        """Claims the records refute (they fail the run only with --strict-claims)."""
        return [c for c in self.claims if c.passed is False]

    @property
    def failures(self) -> list[str]:
        """Why this set fails its gates (empty when it passes; refuted claims are not here).
        Unsupported runs are not failures: a set whose every run is unsupported passes with
        nothing decided (:attr:`note`)."""
        out = [f"gate failed: {c.name}" for c in self.gates if c.passed is False]
        if not self.records:
            out.append("no runs")
        elif not self.completed and len(self.unsupported) < len(self.records):
            out.append("no run completed")
        return out

    @property
    def note(self) -> str:
        """What the unsupported runs mean for this set ("" when there are none)."""
        un = self.unsupported
        if not un:
            return ""
        why = str(un[0].get("reason", "")).split(": ", 1)[-1]
        if len(un) == len(self.records):
            return f"no supported run: all {len(un)} runs unsupported ({why})"
        return f"{len(un)} of {len(self.records)} runs unsupported ({why})"

    @property
    def passed(self) -> bool:
        return not self.failures

    def headline_table(self) -> tuple[str, pd.DataFrame] | None:
        if not self.tables:
            return None
        name = self.headline if self.headline in self.tables else next(iter(self.tables))
        return name, self.tables[name]


def write_case_outputs(
    case: Case, records: list[dict[str, Any]], outdir: str | Path
) -> list[CaseCheck]:
    """Write results, tables, figures, checks and report.md for one case; return the checks."""
    return render_case_outputs(case, records, outdir).checks


def render_case_outputs(
    case: Case, records: list[dict[str, Any]], outdir: str | Path, *,
    arrays_dir: str | Path | None = None,
) -> Rendered:
    """Like :func:`write_case_outputs` but return everything written.

    ``arrays_dir`` is the folder whose ``runs/`` holds the runs' arrays (default ``outdir``);
    the per-solver folders of ``mpsbench validate all`` read the arrays of their case folder.
    Besides the files listed in the module docstring, writes ``findings.md`` (the case's
    plain-word findings) so a report can be re-rendered without the case's code.
    """
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    source = Path(arrays_dir) if arrays_dir is not None else outdir
    df = records_frame(records, case)
    atomic_write_text(outdir / "results.csv", df.to_csv(index=False))
    atomic_write_text(outdir / "results.json", json.dumps(records, indent=1, default=str))

    tables = case.tables(records) if records else {}
    if records and case.refinements and "numerical_uncertainty" not in tables:
        unc = case.uncertainty(records).table()
        if not unc.empty:
            tables["numerical_uncertainty"] = unc
    tdir = outdir / "tables"
    tdir.mkdir(exist_ok=True)
    for name, table in tables.items():
        component("table", name)  # a file name: no '/', no '..'
        atomic_write_text(tdir / f"{name}.csv", table.to_csv())
        atomic_write_text(tdir / f"{name}.md", markdown_table(table))

    fdir = outdir / "figures"
    fdir.mkdir(exist_ok=True)
    import matplotlib

    matplotlib.use("Agg")
    figures = _draw_figures(case, records, source, fdir) if records else []

    # the gates and claims judge the runs that were made: an unsupported run is no evidence
    made = [r for r in records if r.get("status") not in NOT_RUN]
    checks = (case.checks(made) + case.claims(made)) if made else []
    atomic_write_text(outdir / "checks.json",
                      json.dumps([c.to_json() for c in checks], indent=1))
    findings = case.findings(records) if records else ""
    atomic_write_text(outdir / "findings.md",
                      md_escape(findings.strip()) + "\n" if findings.strip() else "")
    atomic_write_text(outdir / "report.md",
                      render_report(case, records, checks, tables, figures, outdir))
    return Rendered(records, checks, tables, figures, findings, outdir, case.headline,
                    case.headline_figure)


def _draw_figures(case: Case, records: list[dict[str, Any]], source: Path,
                  fdir: Path) -> list[Path]:
    """The case's figures, drawn into a scratch folder inside ``fdir`` and each renamed into
    ``fdir``: a reader never finds half a PNG, and a failing figure leaves the old ones."""
    scratch = Path(tempfile.mkdtemp(prefix=".drawing-", dir=fdir))
    try:
        drawn = [Path(f) for f in case.figures(records, lambda rid: load_arrays(source, rid),
                                               scratch)]
        out = []
        for fig in drawn:
            try:
                rel = fig.resolve().relative_to(scratch.resolve())
            except ValueError:  # the case put it somewhere else: leave it there
                out.append(fig)
                continue
            dest = fdir / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            if fig.exists():
                os.replace(fig, dest)
            out.append(dest)
        return out
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _read_text(path: Path) -> str:
    try:
        return path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})"
                             ) from None


def _read_checks(path: Path) -> list[CaseCheck]:
    """The checks an earlier render stored ([] when there is no checks.json); InputFileError
    when the file is corrupt: a broken file must not read as "no checks" (= pass)."""
    if not path.exists():
        return []
    try:
        raw = json.loads(_read_text(path))
        bad = [str(c["name"]) for c in raw if c.get("passed") not in (True, False, None)]
        checks = [CaseCheck.from_json(c) for c in raw]  # gates and claims (kind, rule, ...)
    except (ValueError, TypeError, KeyError, AttributeError, RecursionError) as exc:
        raise InputFileError(f"{path}: truncated or corrupt ({type(exc).__name__}: "
                             f"{str(exc)[:120]}); render the case again") from None
    if bad:
        raise InputFileError(f"{path}: check {bad[0]!r} has 'passed' other than true, false "
                             "or null")
    return checks


def _read_table(path: Path) -> pd.DataFrame:
    _read_text(path)  # the encoding, with the file named
    try:
        return pd.read_csv(path, index_col=0)
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise InputFileError(f"{path}: not a readable table ({str(exc)[:120]})") from None


def check_lines(checks: list[CaseCheck]) -> list[str]:
    """Markdown list items, one per gate (claims are left out: :func:`claim_lines`)."""
    return [f"- **{c.verdict}** {c.name}: {c.detail}" for c in gates_of(checks)]


def claim_lines(checks: list[CaseCheck]) -> list[str]:
    """Markdown list items, one per claim: verdict, id, statement, rule, evidence."""
    return [f"- **{c.verdict}** {c.claim}: {c.name} Rule: {c.rule} Evidence: {c.detail}"
            for c in claims_of(checks)]


def plain_check_lines(checks: list[CaseCheck]) -> list[str]:
    """The same for a terminal: no Markdown markup."""
    out = [f"{c.verdict:<4} {c.name}: {c.detail}" for c in gates_of(checks)]
    out += [f"claim {c.claim} {c.verdict}: {c.name} ({c.detail})" for c in claims_of(checks)]
    return out


def render_report(
    case: Case, records: list[dict[str, Any]], checks: list[CaseCheck],
    tables: dict[str, pd.DataFrame], figures: list[Path], outdir: Path,
) -> str:
    n = len(records)
    by_status: dict[str, int] = {}
    for r in records:
        by_status[r.get("status", "?")] = by_status.get(r.get("status", "?"), 0) + 1
    status = ", ".join(f"{v} {k}" for k, v in sorted(by_status.items()))
    lines = [f"# {md_escape(case.title or case.name)}", "", md_escape(case.description.strip()),
             ""]
    tiers = sorted({str(r.get("tier")) for r in records})
    solvers = sorted({str(r.get("solver")) for r in records})
    lines += [md_escape(f"{n} runs ({status}); tier {', '.join(tiers)}; solver "
                        f"{', '.join(solvers)}."), ""]
    failed = [r for r in records if r.get("status") != "completed"]
    unsupported = [r for r in records if r.get("status") in NOT_RUN]
    if unsupported and len(unsupported) == len(records):
        lines += ["No supported run: the solver's capabilities exclude every run of this case "
                  "at this tier (not a failure; nothing is decided).", ""]
    na = sorted({n for r in records for n in str(r.get("not_applicable") or "").split(",") if n})
    if na:
        who = ", ".join(sorted({str(r.get("solver")) for r in records if r.get("not_applicable")}))
        lines += [md_escape(f"Parameters that do not apply to {who} (its own kernels and time "
                            "step): " + ", ".join(na) + ".  Its runs hold them at the case "
                            "defaults, and checks that name them judge those runs."), ""]
    if failed:
        lines += ["Runs that did not complete:", ""]
        lines += [f"- `{r['run_id']}`: {md_escape(r.get('status'))}: "
                  f"{md_escape(r.get('reason', ''))}" for r in failed[:20]]
        lines.append("")
    findings = case.findings(records) if records else ""
    if findings:
        lines += ["## Findings", "", md_escape(findings.strip()), ""]
    if claims_of(checks):
        lines += ["## Claims", "", "The paper's statements tested as hypotheses "
                  "(docs/method.md section 8); they do not decide the exit status.", "",
                  *map(md_escape, claim_lines(checks)), ""]
    if gates_of(checks):
        lines += ["## Gates", "", "These decide the exit status (docs/method.md section 8).", "",
                  *map(md_escape, check_lines(checks)), ""]
    for name, table in tables.items():
        lines += [f"## Table: {md_escape(name)}", "", markdown_table(table),
                  f"(also `tables/{name}.csv`)", ""]
    if figures:
        lines += ["## Figures", ""]
        lines += [f"![{f.stem}]({f.relative_to(outdir).as_posix()})" for f in figures]
        lines.append("")
    return "\n".join(lines)
