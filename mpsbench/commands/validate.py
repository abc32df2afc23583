"""``mpsbench validate CASE|all``: run case studies at a tier and write a report folder.

``validate CASE`` writes one case folder (see :mod:`mpsbench.results.case_report`) plus its
summary.md and
index.html.  ``validate all`` plans every run of every registered case (built-ins and plugins) for
every ``--solver``, runs them through one pool with one progress count, and writes the results
folder described in :mod:`mpsbench.results.folder` (default ``reports/<YYYYmmdd-HHMM>-<tier>/``).

Exit status: 0 when every case passes its gates, 1 when one fails (or could not be loaded or
run), 2 on a usage error (unknown case, solver or tier, bad ``--set``, an output folder that
cannot be written or is in use, a plan refused by the size guard).  The paper's claims are
reported with their verdicts and do not change the exit status unless ``--strict-claims``
(then a refuted claim exits 1 too).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mpsbench.errors import UsageError

# The heavy modules (numpy, pandas, scipy behind the cases and results) are imported inside
# the functions that use them, so 'mpsbench --help' and '--version' stay fast.
if TYPE_CHECKING:
    from mpsbench.cases import Case
    from mpsbench.results.records import Task
    from mpsbench.results.sections import CaseSection

ORDER = 30
MAX_AUTO_JOBS = 4


def auto_jobs(requested: int | None) -> int:
    """``--jobs`` as given, or the number of CPUs, at most :data:`MAX_AUTO_JOBS` (validate all,
    report)."""
    return requested or max(1, min(os.cpu_count() or 1, MAX_AUTO_JOBS))


def _tier(value: str) -> str:
    """``--tier``: checked when parsed, without importing the cases to build the parser."""
    from mpsbench.cases import TIERS

    if value not in TIERS:
        # argparse's own wording for choices=, which this replaces
        raise argparse.ArgumentTypeError(
            f"invalid choice: {value!r} (choose from {', '.join(map(repr, TIERS))})")
    return value


def register(sub: Any) -> None:
    p = sub.add_parser(
        "validate",
        help="run a validation case (or 'all') and write results, tables, figures and a report",
        description="Run a validation case's parameter grid (or every case's, with 'all') on one "
        "or more solvers and write a report folder. Exit status: 0 every case passes its "
        "gates, 1 one fails, 2 usage error. The paper's claims get a verdict (supported, "
        "refuted, inconclusive) and change the exit status only with --strict-claims.",
    )
    p.add_argument("case", help="case name (see 'mpsbench validate --list') or 'all'", nargs="?")
    p.add_argument("--list", action="store_true", help="list the registered cases and exit")
    p.add_argument("--solver", action="append", default=None, metavar="SPEC",
                   help="solver backend, NAME or NAME:key=value,... with its options (see "
                   "'mpsbench solvers'), e.g. numba:threads=1 (repeatable; default: numba when "
                   "it is installed, else reference)")
    p.add_argument("--tier", default="quick", type=_tier, metavar="TIER",
                   help="smoke (seconds, for CI), quick (default, minutes) or paper (full grid)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE[,VALUE...]",
                   help="override a parameter for every run; a comma list sweeps it "
                   "(one case only, not with 'all')")
    p.add_argument("--jobs", type=int, default=None,
                   help="parallel worker processes (default: 1 for one case; for 'all' the "
                   f"number of CPUs, at most {MAX_AUTO_JOBS})")
    p.add_argument("--out", default=None,
                   help="output folder (default: reports/<case>-<tier>-<time> for one case, "
                   "reports/<YYYYmmdd-HHMM>-<tier> for 'all')")
    p.add_argument("--force", action="store_true", help="re-run runs whose record already exists")
    p.add_argument("--strict-claims", action="store_true",
                   help="exit 1 when a claim of the paper is refuted (claims are otherwise "
                   "findings, not failures)")
    p.add_argument("--junit-xml", default=None, metavar="PATH",
                   help="also write a JUnit XML report: one test case per run and per check "
                   "(docs/ci.md)")
    add_run_safety_options(p)
    add_vtu_options(p)
    add_executor_options(p)
    quiet = p.add_mutually_exclusive_group()
    quiet.add_argument("--quiet", action="store_true",
                       help="no progress output per run (the verdicts are printed at the end)")
    quiet.add_argument("--verbose", action="store_true",
                       help="one plain line per run even on a terminal (default there: a bar "
                       "with the share of the estimated work done and the ETA)")
    add_limit_options(p)
    p.set_defaults(func=cmd_validate)


# ---- where the runs execute (issue #18): --executor dask, --scheduler, --worker-wait
def add_executor_options(p: Any) -> None:
    p.add_argument("--executor", choices=("local", "dask"), default=None,
                   help="where runs execute: local worker processes (default) or a dask "
                   "cluster (pip install \"mpsbench[dask]\"); a worker that is lost is "
                   "reported and its runs go to another")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="dask scheduler address (implies --executor dask); without it "
                   "--executor dask starts a local cluster of --jobs workers")
    p.add_argument("--worker-wait", type=float, default=120.0, metavar="SECONDS",
                   help="with dask: stop with a message when the cluster has had no worker "
                   "for this long (default 120)")


def executor_for(args: argparse.Namespace, jobs: int) -> Any:
    """The executor of --executor/--scheduler (None: the local one of run_tasks)."""
    name = args.executor or ("dask" if args.scheduler else "local")
    if args.scheduler and name != "dask":
        raise UsageError("--scheduler goes with --executor dask")
    if not args.worker_wait > 0:
        raise UsageError(f"--worker-wait = {args.worker_wait:g} is not allowed: seconds > 0")
    if name == "local":
        return None
    from mpsbench.results.executors import ExecutorError, make_executor

    try:
        ex = make_executor("dask", jobs=jobs, scheduler=args.scheduler,
                           worker_wait=args.worker_wait)
    except ExecutorError as exc:
        raise UsageError(str(exc)) from None
    print(f"executor: {ex.describe()}", file=sys.stderr)
    return ex


def progress_for(args: argparse.Namespace, tasks: list[Task]) -> Any:
    """The progress display (:mod:`mpsbench.results.progress`) that --quiet/--verbose ask."""
    from mpsbench.results.progress import Progress

    return Progress(tasks, "quiet" if args.quiet else "verbose" if args.verbose else "auto")


# ---- ParaView output (issue #18): --vtu, --frames; an output option, not a case parameter
def add_vtu_options(p: Any) -> None:
    p.add_argument("--vtu", action="store_true",
                   help="also keep frames of every run in runs/<run_id>.npz and write a "
                   "ParaView series per run to paraview/<run_id>.pvd (binary VTU, with time "
                   "values; needs meshio: pip install \"mpsbench[vtu]\"); changes no run id "
                   "or result; a run done without frames runs again")
    p.add_argument("--frames", type=int, default=21, metavar="N",
                   help="frames per run with --vtu, evenly spaced in time (default 21)")


def vtu_frames(args: argparse.Namespace) -> int:
    """Frames per run (0 without --vtu); a usage error before any run when meshio is missing
    or N is not allowed."""
    if not args.vtu:
        return 0
    if args.frames < 1:
        raise UsageError(f"--frames = {args.frames} is not allowed: an integer >= 1")
    from mpsbench.results.paraview import require_meshio

    require_meshio()
    return int(args.frames)


def frames_retry(rule: Any, frames: int, folder_of: Any) -> Any:
    """With --vtu, a run whose record exists but whose arrays hold no frames runs again."""
    if not frames:
        return rule
    from mpsbench.results.frames import has_frames

    def retry(record: dict[str, Any]) -> bool:
        npz = Path(folder_of(record)) / "runs" / f"{record['run_id']}.npz"
        return bool(rule and rule(record)) or not has_frames(npz)

    return retry


def write_paraview(folder: Path, records: list[dict[str, Any]], root: Path) -> None:
    from mpsbench.results.paraview import export_runs

    pvds, _ = export_runs(folder, [str(r["run_id"]) for r in records], root=root)
    if pvds:
        print(f"paraview: {len(pvds)} series in {folder / 'paraview'}", file=sys.stderr)


# ---- resuming and the size guard (issue #19): --retry-failed, --yes
def add_run_safety_options(p: Any) -> None:
    p.add_argument("--retry-failed", action="store_true",
                   help="re-run the runs recorded failed, diverged, timed-out or crashed (and "
                   "only those; not unsupported ones) among those whose record exists")
    p.add_argument("--yes", action="store_true",
                   help="run a plan above the size guard's thresholds (more than 5,000 runs, "
                   "or a run of more than 1,000,000 particles)")


def add_limit_options(p: Any) -> None:
    """``--max-steps``, ``--max-wall``, ``--isolate`` (validate and study run)."""
    p.add_argument("--max-steps", type=_limit(int), default=None, metavar="N",
                   help="stop a solver run after N time steps, recorded timed-out (default: "
                   "per tier, 20x the case's estimate at most; 0: no limit)")
    p.add_argument("--max-wall", type=_limit(float), default=None, metavar="SECONDS",
                   help="stop a run after this many wall-clock seconds, recorded timed-out "
                   "(default per tier: smoke 600, quick 10800, paper 172800; 0: no limit); a "
                   "step that never returns is killed in its worker process")
    p.add_argument("--isolate", action="store_true",
                   help="run every run in a supervised child process even with --jobs 1, so "
                   "a crash (segfault) or a hang costs only that run (solvers that need it, "
                   "such as PySPH, always are)")


def _limit(kind: type) -> Any:
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not value >= 0 or value != value or value == float("inf"):
            raise argparse.ArgumentTypeError(f"{text!r} is not allowed: a number >= 0 "
                                             "(0: no limit)")
        return value

    return parse


def with_limits(tasks: list[Task], args: argparse.Namespace) -> list[Task]:
    """The tasks with the command line's run limits and isolation set."""
    import dataclasses

    changes: dict[str, Any] = {}
    if getattr(args, "max_steps", None) is not None:
        changes["max_steps"] = args.max_steps
    if getattr(args, "max_wall", None) is not None:
        changes["max_wall_s"] = args.max_wall
    if getattr(args, "isolate", False):
        changes["isolate"] = True
    return [dataclasses.replace(t, **changes) for t in tasks] if changes else tasks


def retry_rule(args: argparse.Namespace) -> Any:
    if not args.retry_failed:
        return None
    return lambda record: record.get("status") not in ("completed", "unsupported")


def lock_command(args: argparse.Namespace) -> str:
    return f"mpsbench validate {args.case} --tier {args.tier}"


def parse_overrides(case: Case, items: list[str]) -> dict[str, Sequence[Any]]:
    out: dict[str, Sequence[Any]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UsageError(f"--set {item!r}: expected KEY=VALUE")
        param = case.param(key.strip())
        out[param.name] = [param.parse(v) for v in value.split(",")]
    return out


def default_out(name: str, tier: str) -> Path:
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("reports") / f"{name}-{tier}-{stamp}"


def default_all_out(tier: str, root: Path = Path("reports")) -> Path:
    """``reports/<YYYYmmdd-HHMM>-<tier>``; a suffix keeps two runs in one minute apart."""
    base = root / f"{_dt.datetime.now().strftime('%Y%m%d-%H%M')}-{tier}"
    path, k = base, 2
    while path.exists():
        path, k = base.with_name(f"{base.name}-{k}"), k + 1
    return path


def default_solver() -> tuple[str, str]:
    """The solver of a ``validate`` without ``--solver`` and the line that says so: numba (the
    fast backend, results held against the reference by its tests) when it loads, else the
    reference backend with the reason."""
    from mpsbench.run.protocol import SOLVERS

    try:
        SOLVERS.get("numba")
    except Exception as exc:  # noqa: BLE001 - unavailable for any reason: say which, go on
        return "reference", f"solver: reference (numba is unavailable: {exc})"
    return "numba", "solver: numba (the default when it is installed; --solver reference for " \
        "the reference backend)"


def cmd_validate(args: argparse.Namespace) -> int:
    from mpsbench.cases import CASES, case_order, get_case
    from mpsbench.results.records import canonical_solver

    if args.list:
        for name in case_order(CASES.names()):
            try:
                case = get_case(name)
                print(f"{name:<12} {case.title}")
            except Exception as exc:  # noqa: BLE001
                print(f"{name:<12} [unavailable] {exc}")
        return 0
    if not args.case:
        raise UsageError("give a case name or 'all' (see --list)")
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs = {args.jobs} is not allowed: an integer >= 1")
    # unknown or broken solver, unknown option or bad value: usage error before any run
    args.solver_note = ""
    if not args.solver:
        default, args.solver_note = default_solver()
        args.solver = [default]
    solvers = list(dict.fromkeys(canonical_solver(s) for s in args.solver))
    if args.case == "all":
        if args.set:
            raise UsageError("--set applies to one case; run 'mpsbench validate CASE --set ...'")
        return validate_all(args, solvers)
    return validate_one(args, solvers)


def _say_solver(args: argparse.Namespace) -> None:
    if getattr(args, "solver_note", ""):
        print(args.solver_note, file=sys.stderr)


def _manifest(args: argparse.Namespace, solvers: list[str], jobs: int) -> dict[str, Any]:
    from mpsbench.results.records import environment

    return {
        "command": " ".join(["mpsbench validate", args.case, "--tier", args.tier]
                            + [f"--solver {s}" for s in solvers] + [f"--jobs {jobs}"]),
        "case": args.case, "tier": args.tier, "solvers": solvers, "jobs": jobs,
        "strict_claims": bool(args.strict_claims),
        "started": _dt.datetime.now().isoformat(timespec="seconds"),
        "environment": environment(solvers), "cases": [],
    }


def validate_one(args: argparse.Namespace, solvers: list[str]) -> int:
    from mpsbench.cases import get_case
    from mpsbench.results.folder import MANIFEST, write_top_level
    from mpsbench.results.guard import check_run_count, grid_size, guard_tasks
    from mpsbench.results.lock import folder_lock
    from mpsbench.results.records import atomic_write_text
    from mpsbench.results.sections import safe_render_case
    from mpsbench.results.sweep import plan, run_tasks

    case = get_case(args.case)
    overrides = parse_overrides(case, args.set)
    check_run_count(grid_size(case, args.tier, overrides) * len(solvers), args.yes,
                    f"{case.name} at tier {args.tier}")
    tasks = with_limits(plan(case, solvers, args.tier, overrides), args)
    frames = vtu_frames(args)
    for task in tasks:
        task.frames = frames
    out = Path(args.out) if args.out else default_out(args.case, args.tier)
    jobs = args.jobs or 1
    guard_tasks(tasks, jobs=jobs, yes=args.yes)
    manifest = _manifest(args, solvers, jobs)
    t0 = time.perf_counter()
    with folder_lock(out, lock_command(args)):
        _say_solver(args)
        print(f"{case.name}: {len(tasks)} runs -> {out}", file=sys.stderr)
        executor = executor_for(args, jobs)
        progress = progress_for(args, tasks)
        try:
            records = run_tasks(tasks, out, jobs=jobs, force=args.force, progress=progress,
                                retry=frames_retry(retry_rule(args), frames, lambda r: out),
                                executor=executor)
        finally:
            progress.close()
            if executor is not None:
                executor.close()
        if frames:
            write_paraview(out, records, out)
        section = safe_render_case(case, records, out)
        manifest.update(wall_s=round(time.perf_counter() - t0, 1),
                        cases=[{"name": case.name, "error": section.error}])
        atomic_write_text(out / MANIFEST, json.dumps(manifest, indent=1))
        ok = write_top_level(out, [section], manifest, [p.name for p in case.params],
                             write_results=False)
        ci_outputs(args, [section], manifest)
    print_verdicts([section])
    note = _claims_note([section], args.strict_claims)
    if note:
        print(note.lstrip("; "))
    print(f"report: {os.path.join(str(out), 'report.md')}")
    print(f"index:  {out / 'index.html'}")
    return 0 if ok else 1


def validate_all(args: argparse.Namespace, solvers: list[str]) -> int:
    from mpsbench.cases import CASES, case_order, get_case
    from mpsbench.results.guard import check_run_count, guard_tasks
    from mpsbench.results.lock import folder_lock
    from mpsbench.results.sections import CaseSection
    from mpsbench.results.sweep import plan

    out = Path(args.out) if args.out else default_all_out(args.tier)
    jobs = auto_jobs(args.jobs)
    manifest = _manifest(args, solvers, jobs)
    t0 = time.perf_counter()
    cases: list[Case] = []
    broken: dict[str, CaseSection] = {}
    tasks: list[Task] = []
    names = case_order(CASES.names())
    check_run_count(sum(_grid_size(name, args.tier) for name in names) * len(solvers), args.yes,
                    f"validate all at tier {args.tier}")
    for name in names:
        try:
            case = get_case(name)
            case_tasks = plan(case, solvers, args.tier)
        except Exception as exc:  # noqa: BLE001 - one broken case fails itself, not the run
            broken[name] = CaseSection(name, name, error=f"case unavailable: {exc}")
            print(f"{name}: cannot run: {exc}", file=sys.stderr)
            continue
        cases.append(case)
        tasks += case_tasks
        print(f"{name}: {len(case_tasks)} runs", file=sys.stderr)
    guard_tasks(tasks, jobs=jobs, yes=args.yes)
    tasks = with_limits(tasks, args)
    frames = vtu_frames(args)
    for task in tasks:
        task.frames = frames
    with folder_lock(out, lock_command(args)):
        return _validate_all_locked(args, out, jobs, manifest, t0, names, cases, broken, tasks)


def _grid_size(name: str, tier: str) -> int:
    from mpsbench.cases import get_case
    from mpsbench.results.guard import grid_size

    try:
        return grid_size(get_case(name), tier)
    except Exception:  # noqa: BLE001 - a broken case is reported (and planned) below
        return 0


def _validate_all_locked(args: argparse.Namespace, out: Path, jobs: int,
                         manifest: dict[str, Any], t0: float, names: list[str],
                         cases: list[Case], broken: dict[str, CaseSection],
                         tasks: list[Task]) -> int:
    from mpsbench.cases import get_case
    from mpsbench.results.folder import MANIFEST, write_top_level
    from mpsbench.results.records import atomic_write_text
    from mpsbench.results.render_pool import render_cases
    from mpsbench.results.sections import verdict
    from mpsbench.results.sweep import run_tasks

    _say_solver(args)
    print(f"validate all: {len(tasks)} runs of {len(cases)} cases x "
          f"{len(manifest['solvers'])} solver(s), tier {args.tier}, {jobs} job(s) -> {out}",
          file=sys.stderr)
    manifest["cases"] = [{"name": n, "error": broken[n].error if n in broken else ""}
                         for n in names]
    atomic_write_text(out / MANIFEST, json.dumps(manifest, indent=1))
    folder = {c.name: out / c.name for c in cases}
    frames = tasks[0].frames if tasks else 0
    executor = executor_for(args, jobs)
    progress = progress_for(args, tasks)
    try:
        order = heavy_first(tasks, getattr(progress, "costs", None))
        records = run_tasks(order, out, jobs=jobs, force=args.force,
                            progress=progress, task_dir=lambda t: folder[t.case],
                            retry=frames_retry(retry_rule(args), frames,
                                               lambda r: folder[str(r["case"])]),
                            executor=executor)
    finally:
        progress.close()
        if executor is not None:
            executor.close()
    if frames:
        for case in cases:
            write_paraview(folder[case.name],
                           [r for r in records if r.get("case") == case.name], out)
    loaded = [get_case(name) for name in names if name not in broken]
    rendered = iter(render_cases(
        [(case, [r for r in records if r.get("case") == case.name], folder[case.name])
         for case in loaded], jobs))
    sections: list[CaseSection] = [broken[name] if name in broken else next(rendered)
                                   for name in names]
    for sec in sections:
        if sec.error and sec.name not in broken:
            print(f"{sec.name}: {sec.error}", file=sys.stderr)
    manifest.update(wall_s=round(time.perf_counter() - t0, 1),
                    finished=_dt.datetime.now().isoformat(timespec="seconds"),
                    cases=[{"name": s.name, "error": s.error} for s in sections])
    atomic_write_text(out / MANIFEST, json.dumps(manifest, indent=1))
    params = [p.name for c in cases for p in c.params]
    ok = write_top_level(out, sections, manifest, params)
    ci_outputs(args, sections, manifest)
    print_verdicts(sections)
    print(f"{verdict(ok)}: {sum(s.passed for s in sections)}/{len(sections)} cases pass "
          f"their gates in {manifest['wall_s']:.0f} s{_claims_note(sections, args.strict_claims)}")
    print(f"summary: {out / 'summary.md'}")
    print(f"index:   {out / 'index.html'}")
    return 0 if ok else 1


def ci_outputs(args: argparse.Namespace, sections: list[CaseSection],
               manifest: dict[str, Any]) -> None:
    """The outputs for CI: ``--junit-xml`` and the job summary when ``$GITHUB_STEP_SUMMARY`` is
    set (:mod:`mpsbench.results.junit`, :mod:`mpsbench.results.step_summary`)."""
    from mpsbench.results.junit import write_junit
    from mpsbench.results.step_summary import append_step_summary, validation_summary

    if args.junit_xml:
        try:
            print(f"junit:  {write_junit(args.junit_xml, sections, manifest)}")
        except OSError as exc:
            raise UsageError(f"--junit-xml {args.junit_xml}: cannot write: {exc}") from None
    append_step_summary(validation_summary(sections, manifest))


def heavy_first(tasks: list[Task], costs: dict[str, float] | None = None) -> list[Task]:
    """Submission order: cases with fewer runs first (tiers are sized so each case takes a
    similar time, so fewer runs means longer ones); the many short runs then fill the workers
    at the end instead of one long run keeping a worker busy after the others are done.

    With ``costs`` (estimated work per run id, the progress display's), one run of every case
    and solver goes ahead of all of that, the one of median work: the display learns from it
    what a unit of work costs there (a diffusion particle-step is 10-30x cheaper than a
    flow's), so its ETA holds from the first seconds rather than from the start of the last
    case.  The median run rather than the cheapest, because a run's fixed costs (building the
    problem, the analysis) weigh in it as in most of the case's runs: the cheapest runs of
    the quick tier overstated their case's rate up to 2.2x.
    """
    count: dict[str, int] = {}
    for t in tasks:
        count[t.case] = count.get(t.case, 0) + 1
    order = sorted(tasks, key=lambda t: count[t.case])  # stable: a case's own order is kept
    if not costs:
        return order
    groups: dict[tuple[str, str], list[Task]] = {}
    for t in order:
        if t.run_id in costs:
            groups.setdefault((t.case, t.solver), []).append(t)
    first: set[int] = set()
    for group in groups.values():
        group.sort(key=lambda t: costs[t.run_id])  # stable: of equal costs, the first
        first.add(id(group[(len(group) - 1) // 2]))
    return sorted(order, key=lambda t: id(t) not in first)  # stable: the probes, then the rest


def print_verdicts(sections: list[CaseSection]) -> None:
    """Plain text for the terminal: per case and solver its gates, then its claims."""
    from mpsbench.results.case_report import plain_check_lines
    from mpsbench.results.sections import verdict

    for sec in sections:
        if sec.error:
            print(f"FAIL {sec.name}: {sec.error}")
        for s in sec.solvers:
            r = s.rendered
            print(f"{verdict(r.passed and not sec.error)} {sec.name} [{s.solver}]: "
                  f"{len(r.records)} runs, {r.completed} completed")
            if r.note:
                print(f"  ({r.note})")
            for line in plain_check_lines(r.checks):
                print("  " + line)
            for why in r.failures:
                if not why.startswith("gate failed"):
                    print(f"  {why}")


def _claims_note(sections: list[CaseSection], strict: bool) -> str:
    from mpsbench.results.sections import claim_counts, exit_ok

    claims = [c for sec in sections for s in sec.solvers for c in s.rendered.claims]
    if not claims:
        return ""
    note = f"; claims: {claim_counts(claims)}"
    if strict and not exit_ok(sections, True) and exit_ok(sections, False):
        note += " (--strict-claims: a refuted claim fails the run)"
    return note
