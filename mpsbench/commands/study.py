"""``mpsbench study run STUDY.toml`` and ``mpsbench study status DIR``.

Output folder of a study::

    OUT/study.toml              a copy of the study file as it was run
    OUT/plan.json               every planned run (case, solver, tier, parameters, run id)
    OUT/<case>/runs/*.json      one record per finished run (atomic writes)
    OUT/<case>/...              results, tables, figures, report.md (as 'mpsbench validate')
    OUT/tolerances.json         the study's tolerance checks

Running the same study again skips every run whose record exists -- the same run by its
identity hash (case, solver, full parameter set), so widening the grid runs only the new
combinations -- and an interrupted study (Ctrl-C, a killed process, a lost machine) resumes
where it stopped.  Two mpsbench processes on the same folder at once are refused
(:mod:`mpsbench.results.lock`, released by the system when the process dies).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mpsbench.errors import UsageError
from mpsbench.results.lock import folder_lock

ORDER = 35

PLAN_FILE = "plan.json"


def register(sub: Any) -> None:
    p = sub.add_parser(
        "study",
        help="run a study file (cases x solvers x parameter grid) and show its progress",
        description="Run parameter studies described in TOML files (see docs/studies.md).",
    )
    ssub = p.add_subparsers(dest="study_command", metavar="ACTION")
    r = ssub.add_parser(
        "run", help="run every run of a study not done yet, then write the reports",
        description="Check the study file, then run every run whose record does not exist yet "
        "(an interrupted study resumes), write the reports and hold the tolerances.",
    )
    r.add_argument("study", metavar="STUDY.toml", help="the study file")
    r.add_argument("--jobs", type=int, default=None,
                   help="parallel runs: worker processes (local) or workers of the local dask "
                   "cluster (default: the file's 'jobs', else 1)")
    r.add_argument("--executor", choices=("local", "dask"), default=None,
                   help="where runs execute (default: the file's 'executor', else local)")
    r.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="dask scheduler address (implies --executor dask); without it "
                   "--executor dask starts a local cluster")
    r.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: the file's 'out', else reports/studies/NAME)")
    r.add_argument("--force", action="store_true", help="re-run runs whose record exists")
    r.add_argument("--retry-failed", action="store_true",
                   help="re-run runs recorded as failed, timed-out or crashed (not diverged "
                   "or unsupported ones)")
    r.add_argument("--dry-run", action="store_true",
                   help="check the file and print the planned runs, run nothing")
    r.add_argument("--no-report", action="store_true",
                   help="keep the records only: skip tables, figures and report.md")
    r.add_argument("--yes", action="store_true",
                   help="run a study above the size guard's thresholds (more than 5,000 runs, "
                   "or a run of more than 1,000,000 particles)")
    from mpsbench.commands.validate import add_limit_options

    add_limit_options(r)
    r.set_defaults(func=cmd_run)
    s = ssub.add_parser(
        "status", help="show done / failed / pending runs of a study folder",
        description="Count the runs of a study folder (or of a study file's default folder) "
        "by state: done (completed, diverged or unsupported), failed (failed, timed-out or "
        "crashed), pending.",
    )
    s.add_argument("target", metavar="DIR|STUDY.toml", help="a study output folder or study file")
    s.add_argument("--out", default=None, metavar="DIR",
                   help="with a study file: its output folder if not the default")
    s.add_argument("--json", action="store_true", help="print JSON")
    s.add_argument("--list", choices=("failed", "pending", "all"), default=None,
                   help="also list the run ids in this state")
    s.set_defaults(func=cmd_status)
    p.set_defaults(func=lambda args: _missing_action(p))


def _missing_action(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


# --------------------------------------------------------------------------- run


def write_plan(out: Path, spec: Any, tasks: list[Any]) -> None:
    from mpsbench.results.records import atomic_write_text

    plan = {
        "study": spec.name,
        "source": str(spec.path),
        "tier": spec.tier,
        "cases": list(spec.cases),
        "solvers": list(spec.solvers),
        "n_runs": len(tasks),
        "runs": [
            {"case": t.case, "solver": t.solver, "tier": t.tier, "run_id": t.run_id,
             "run_hash": t.run_hash, "params": t.params}
            for t in tasks
        ],
    }
    atomic_write_text(out / PLAN_FILE, json.dumps(plan, indent=1, default=str))
    if spec.source:
        atomic_write_text(out / "study.toml", spec.source)


def cmd_run(args: argparse.Namespace) -> int:
    from mpsbench.cases.checks import gates
    from mpsbench.results.case_report import plain_check_lines, write_case_outputs
    from mpsbench.results.executors import ExecutorError, make_executor
    from mpsbench.results.guard import MAX_RUNS, guard_tasks
    from mpsbench.results.records import atomic_write_text
    from mpsbench.results.study_spec import check_tolerances, load_study
    from mpsbench.results.sweep import print_progress, run_tasks

    spec = load_study(args.study, max_runs=None if args.yes else MAX_RUNS)
    jobs = args.jobs if args.jobs is not None else (spec.jobs or 1)
    if jobs < 1:
        raise UsageError(f"--jobs = {jobs} is not allowed: an integer >= 1")
    scheduler = args.scheduler or spec.scheduler
    executor_name = args.executor or ("dask" if args.scheduler else spec.executor) or "local"
    if scheduler and executor_name != "dask":
        raise UsageError("--scheduler goes with --executor dask")
    from mpsbench.commands.validate import with_limits

    out = Path(args.out) if args.out else spec.default_out()
    tasks = with_limits(spec.tasks(), args)
    cases = {c.name: c for c in spec.case_objects()}
    by_case = {name: sum(t.case == name for t in tasks) for name in cases}
    summary = ", ".join(f"{name} {n}" for name, n in by_case.items())
    print(f"study {spec.name}: {len(tasks)} runs ({summary}; tier {spec.tier}; solvers "
          f"{', '.join(spec.solvers)}) -> {out}", file=sys.stderr)
    # workers of a remote scheduler have their own memory: only this machine's is known
    guard_tasks(tasks, jobs=jobs, yes=args.yes, check_memory=not scheduler)
    if args.dry_run:
        for t in tasks:
            print(t.run_id)
        return 0

    def folder(task: Any) -> Path:
        return out / task.case

    def retry(record: dict[str, Any]) -> bool:
        return bool(args.retry_failed) and record.get("status") in BROKEN

    with folder_lock(out, f"mpsbench study run {args.study}"):
        write_plan(out, spec, tasks)
        try:
            executor = make_executor(executor_name, jobs=jobs, scheduler=scheduler,
                                     isolate=bool(args.isolate))
        except (ExecutorError, ValueError) as exc:
            raise UsageError(str(exc)) from None
        print(f"executor: {executor.describe()}", file=sys.stderr)
        with executor:
            try:
                records = run_tasks(
                    tasks, out, force=args.force, progress=print_progress(),
                    executor=executor, task_dir=folder, retry=retry,
                )
            except ExecutorError as exc:
                raise UsageError(str(exc)) from None
        failed_runs = [r for r in records if r.get("status") in BROKEN]
        any_check_failed = False
        if not args.no_report:
            for name, case in cases.items():
                case_records = [r for r in records if r.get("case") == name]
                checks = write_case_outputs(case, case_records, out / name)
                for line in plain_check_lines(checks):
                    print(f"{name}: {line}")
                # gates fail a study; the paper's claims are findings (docs/method.md 8)
                any_check_failed |= any(c.passed is False for c in gates(checks))
        tol = check_tolerances(spec, records)
        if tol:
            atomic_write_text(out / "tolerances.json", json.dumps(
                [{"name": c.name, "passed": c.passed, "detail": c.detail} for c in tol], indent=1))
            for line in plain_check_lines(tol):
                print(line)
            any_check_failed |= any(c.passed is False for c in tol)
    counts = _count(records)
    shown = ", ".join(f"{n} {k}" for k, n in counts.items() if n or k in _SHOWN)
    print(f"study {spec.name}: {shown} -> {out}")
    for r in failed_runs[:10]:
        print(f"  {r.get('status')} {r['run_id']}: {r.get('reason', '')}")
    return 1 if failed_runs or any_check_failed else 0


BROKEN = ("failed", "timed-out", "crashed")
"""Statuses that make ``study run`` exit 1 (a diverged run is a result; an unsupported one
was not made)."""
_SHOWN = ("completed", "diverged", "failed")


def _count(records: list[dict[str, Any]]) -> dict[str, int]:
    out = {"completed": 0, "diverged": 0, "failed": 0, "timed-out": 0, "crashed": 0,
           "unsupported": 0}
    for r in records:
        out[r.get("status", "failed") if r.get("status") in out else "failed"] += 1
    return out


# --------------------------------------------------------------------------- status


def study_status(out: Path, tasks: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    """Runs of a study folder by state.

    ``tasks`` (dicts with case, run_id and, from newer plans, run_hash) defaults to
    ``OUT/plan.json``; without a plan only the records found are counted and ``pending`` is
    None.  A planned run is done when a record of the same run (by ``run_hash``, else by file
    name) is in its case folder.
    """
    from mpsbench.results.records import load_record
    from mpsbench.results.sweep import stored_runs

    if tasks is None:
        plan_path = out / PLAN_FILE
        if plan_path.is_file():
            tasks = _read_plan(plan_path)
    state: dict[str, list[dict[str, Any]]] = {
        "completed": [], "diverged": [], "unsupported": [], "failed": [], "pending": []
    }
    record_files = sorted(out.glob("runs/*.json")) + sorted(out.glob("*/runs/*.json"))
    temp_files = len(list(out.glob("runs/.*.tmp")) + list(out.glob("*/runs/.*.tmp")))
    unreadable = sum(load_record(path) is None for path in record_files)
    matched: set[Path] = set()
    if tasks is not None:
        stored = {case: stored_runs(out / case) for case in {t["case"] for t in tasks}}
        for t in tasks:
            found = stored[t["case"]].get(t.get("run_hash") or "", [])
            path = out / t["case"] / "runs" / f"{t['run_id']}.json"
            rec = found[0][1] if found else load_record(path)
            if rec is None:
                state["pending"].append({"run_id": t["run_id"], "case": t["case"]})
            else:
                matched.update(p for p, _ in found)
                matched.add(path)
                _file(state, rec)
    extra = 0
    for path in record_files:
        if path in matched:
            continue
        rec = load_record(path)
        if rec is None:
            continue
        if tasks is None:
            _file(state, rec)
        else:
            extra += 1
    done = len(state["completed"]) + len(state["diverged"]) + len(state["unsupported"])
    return {
        "folder": str(out),
        "planned": len(tasks) if tasks is not None else None,
        "done": done,
        "completed": len(state["completed"]),
        "diverged": len(state["diverged"]),
        "unsupported": len(state["unsupported"]),
        "failed": len(state["failed"]),
        "pending": len(state["pending"]) if tasks is not None else None,
        "not_in_plan": extra,
        "unreadable": unreadable,
        "temp_files": temp_files,
        "runs": state,
    }


def _read_plan(path: Path) -> list[dict[str, Any]]:
    """The planned runs of a plan.json; UsageError naming the file and the run when it is
    unreadable or a run lacks its case or run id."""
    from mpsbench.registry import name_problem
    from mpsbench.results.records import run_id_problem

    again = "run the study again to rewrite it"
    try:
        runs = json.loads(path.read_bytes().decode("utf-8"))["runs"]
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        raise UsageError(f"{path} is unreadable or truncated: {again}") from None
    if not isinstance(runs, list):
        raise UsageError(f"{path}: 'runs' is not a list: {again}")
    for k, run in enumerate(runs):
        if not isinstance(run, dict):
            raise UsageError(f"{path}: run {k} is not an object: {again}")
        for key in ("case", "run_id"):
            if key not in run:
                raise UsageError(f"{path}: run {k} lacks {key!r}: {again}")
        if name_problem(run["case"]) is not None:
            raise UsageError(f"{path}: run {k}: case = {str(run['case'])[:80]!r} is not "
                             f"allowed: {name_problem(run['case'])}")
        problem = run_id_problem(run["run_id"])
        if problem is not None:
            raise UsageError(f"{path}: run {k}: {problem}")
        if not isinstance(run.get("run_hash", ""), str):
            raise UsageError(f"{path}: run {k}: run_hash is not a string: {again}")
    return runs


def _file(state: dict[str, list[dict[str, Any]]], rec: dict[str, Any]) -> None:
    status = rec.get("status")
    key = status if status in ("completed", "diverged", "unsupported") else "failed"
    state[key].append({"run_id": rec.get("run_id", ""), "case": rec.get("case", ""),
                       "reason": rec.get("reason", "")})


def cmd_status(args: argparse.Namespace) -> int:
    target = Path(args.target)
    tasks = None
    if target.is_file() and target.suffix == ".toml":
        from mpsbench.results.study_spec import load_study

        spec = load_study(target)
        out = Path(args.out) if args.out else spec.default_out()
        tasks = [{"case": t.case, "run_id": t.run_id, "run_hash": t.run_hash}
                 for t in spec.tasks()]
    elif target.is_dir():
        out = target
    else:
        raise UsageError(f"{target}: not a study folder or a .toml study file")
    st = study_status(out, tasks)
    if st["planned"] is None and not (st["done"] or st["failed"]):
        raise UsageError(f"{out}: no {PLAN_FILE} and no run records: not a study folder")
    if args.json:
        print(json.dumps(st, indent=1))
        return 0
    if st["planned"] is not None:
        print(f"{out}: {st['planned']} runs planned")
    else:
        print(f"{out}: no {PLAN_FILE}; counting the records found (pending unknown)")
    extra = f", {st['unsupported']} unsupported" if st["unsupported"] else ""
    print(f"  done     {st['done']:>5}  ({st['completed']} completed, {st['diverged']} diverged"
          f"{extra})")
    print(f"  failed   {st['failed']:>5}")
    if st["pending"] is not None:
        print(f"  pending  {st['pending']:>5}")
    if st["not_in_plan"]:
        print(f"  ({st['not_in_plan']} records of runs no longer in the plan)")
    if st["unreadable"]:
        print(f"  ({st['unreadable']} unreadable record files, treated as pending)")
    if st["temp_files"]:
        print(f"  ({st['temp_files']} temporary files of interrupted writes, ignored)")
    shown = ("failed", "pending") if args.list == "all" else (args.list,) if args.list else ()
    if not args.list:
        for r in st["runs"]["failed"][:10]:
            print(f"  failed: {r['run_id']}: {r['reason']}")
        if st["failed"] > 10:
            print(f"  ... {st['failed'] - 10} more (--list failed)")
    for key in shown:
        for r in st["runs"][key]:
            reason = f": {r['reason']}" if r.get("reason") else ""
            print(f"  {key}: {r['run_id']}{reason}")
    return 0
