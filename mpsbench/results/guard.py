"""The size guard: what a plan will cost, checked before any run starts.

``mpsbench validate`` and ``mpsbench study run`` call it after planning and before running:

* more than :data:`MAX_RUNS` runs, or a run of more than :data:`MAX_PARTICLES` particles, is
  refused unless ``--yes`` is given (the run count is taken from the grid before the grid is
  expanded, so a mistyped 560,000-run grid costs nothing);
* a run whose estimated memory exceeds the machine's (or the ``--jobs`` largest runs together)
  is refused, with the numbers: it could only die of MemoryError;
* a fixed time step above the explicit stability limit is refused, with the limit: the
  scheme is unstable there (its highest mode grows every step).

Estimates come from ``Case.estimate(params)`` (:mod:`mpsbench.run.estimate`); a case without
one is counted but not sized.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mpsbench.cases import Case, get_case
from mpsbench.errors import ConfigError, UsageError
from mpsbench.results.records import Task
from mpsbench.run.estimate import RunEstimate

MAX_RUNS = 5000
"""Plans with more runs need ``--yes`` (the built-in paper tiers of all cases stay below)."""
MAX_PARTICLES = 1_000_000
"""Runs with more particles need ``--yes`` (the built-in grids stay below 50,000)."""


def grid_size(case: Case, tier: str, overrides: Mapping[str, Sequence[Any]] | None = None) -> int:
    """Parameter sets of ``case.expand(tier, overrides)`` before duplicates are removed,
    counted without expanding (the product of the list lengths of each grid)."""
    total = 0
    for grid in case.tiers.get(tier, []):
        merged = {**{k: list(v) for k, v in grid.items()},
                  **{k: list(v) for k, v in (overrides or {}).items()}}
        total += math.prod(len(v) for v in merged.values())
    return total


def check_run_count(runs: int, yes: bool, what: str = "the plan") -> None:
    """Refuse more than :data:`MAX_RUNS` runs without ``--yes``."""
    if runs > MAX_RUNS and not yes:
        raise UsageError(f"{what} has {runs:,} runs, more than {MAX_RUNS:,}: check the grid, "
                         "or give --yes to run them all")


@dataclass
class PlanEstimate:
    """The estimates of every run of a plan (runs whose case gives none are ``unknown``)."""

    runs: int
    estimates: list[tuple[Task, RunEstimate]] = field(default_factory=list)

    @property
    def unknown(self) -> int:
        return self.runs - len(self.estimates)

    def largest(self) -> tuple[Task, RunEstimate] | None:
        return max(self.estimates, key=lambda te: te[1].particles, default=None)

    def peak_memory(self, jobs: int) -> int:
        """Bytes in use when the ``jobs`` largest runs run at once."""
        sizes = sorted((e.memory_bytes for _, e in self.estimates), reverse=True)
        return sum(sizes[:max(1, jobs)])

    @property
    def particle_steps(self) -> float:
        return sum(e.particle_steps or 0.0 for _, e in self.estimates)

    def describe(self, jobs: int) -> str:
        if not self.estimates:
            return f"estimate: {self.runs} runs (no size estimate from the case)"
        task, big = self.largest() or (None, None)
        assert big is not None
        steps = f", {self.particle_steps:.3g} particle-steps in all" if self.particle_steps else ""
        unknown = f" ({self.unknown} without an estimate)" if self.unknown else ""
        return (f"estimate: {self.runs} runs{unknown}; largest {big.particles:,} particles, "
                f"{big.pairs:,} pairs, {_gb(big.memory_bytes)}{steps}; "
                f"{_gb(self.peak_memory(jobs))} with {jobs} at once")


def estimate_plan(tasks: Iterable[Task]) -> PlanEstimate:
    """Ask each task's case for its estimate (a case whose estimate fails is not sized: the run
    itself will report the problem)."""
    tasks = list(tasks)
    out = PlanEstimate(len(tasks))
    cases: dict[str, Case | None] = {}
    for task in tasks:
        if task.case not in cases:
            try:
                cases[task.case] = get_case(task.case)
            except Exception:  # noqa: BLE001 - an unloadable case fails its runs, not the plan
                cases[task.case] = None
        case = cases[task.case]
        if case is None:
            continue
        try:
            est = case.estimate(dict(task.params))
        except ConfigError as exc:
            # a value the case refuses (a spacing that does not divide the domain): bad
            # input, stopped before any run, as the parameters' own checks do
            raise UsageError(f"case {task.case}: {exc}") from None
        except Exception:  # noqa: BLE001 - a broken estimate: the run itself says what fails
            est = None
        if est is not None:
            out.estimates.append((task, est))
    return out


def check_plan(plan: PlanEstimate, *, jobs: int = 1, yes: bool = False,
               memory: int | None = None, check_memory: bool = True) -> None:
    """Refuse what cannot work (a fixed dt above the stability limit, more memory than the
    machine has) and, without ``yes``, what is larger than the documented thresholds."""
    too_large = [(task, est) for task, est in plan.estimates if est.dt_too_large]
    if too_large:
        task, est = min(too_large, key=lambda te: te[1].dt_limit or 0.0)
        assert est.dt is not None and est.dt_limit is not None
        others = f" (and {len(too_large) - 1} more runs)" if len(too_large) > 1 else ""
        raise UsageError(
            f"run {task.run_id}{others}: dt = {est.dt:.4g} s is above the explicit stability "
            f"limit {est.dt_limit:.4g} s ({est.dt_rule}): the run is unstable; give dt <= "
            f"{_floor(est.dt_limit)}")
    check_run_count(plan.runs, yes)
    largest = plan.largest()
    if largest is None:
        return
    task, big = largest
    if check_memory:
        memory = memory if memory is not None else machine_memory()
        if memory is not None:
            if big.memory_bytes > memory:
                raise UsageError(
                    f"run {task.run_id}: {big.particles:,} particles and {big.pairs:,} pairs "
                    f"need about {_gb(big.memory_bytes)}, more than this machine's "
                    f"{_gb(memory)}: use a coarser spacing")
            peak = plan.peak_memory(jobs)
            if peak > memory:
                fit = _jobs_that_fit(plan, memory)
                raise UsageError(
                    f"the {min(jobs, len(plan.estimates))} largest runs at once need about "
                    f"{_gb(peak)}, more than this machine's {_gb(memory)}: use --jobs {fit}")
    if big.particles > MAX_PARTICLES and not yes:
        raise UsageError(
            f"run {task.run_id} has {big.particles:,} particles (about {_gb(big.memory_bytes)}"
            f"{_steps(big)}), more than {MAX_PARTICLES:,}: give --yes to run it")


def machine_memory() -> int | None:
    """Physical memory of this machine [bytes], or the cgroup's limit when lower."""
    sizes = []
    try:
        sizes.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        pass
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = Path(path).read_text().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 2**60:
            sizes.append(int(text))
    return min(sizes) if sizes else None


def _jobs_that_fit(plan: PlanEstimate, memory: int) -> int:
    jobs = 1
    while plan.peak_memory(jobs + 1) <= memory and jobs < len(plan.estimates):
        jobs += 1
    return jobs


def _gb(n: float) -> str:
    return f"{n / 2**30:.2f} GB" if n >= 2**30 else f"{n / 2**20:.0f} MB"


def _floor(x: float) -> str:
    """``x`` rounded down to 2 significant digits, as text."""
    exp = math.floor(math.log10(x)) - 1
    return f"{math.floor(x / 10**exp) * 10**exp:.2g}"


def _steps(est: RunEstimate) -> str:
    return f", {est.steps:,} steps" if est.steps else ""


def guard_tasks(tasks: Sequence[Task], *, jobs: int, yes: bool, check_memory: bool = True,
                stream: Any = None) -> PlanEstimate:
    """Estimate ``tasks``, print the estimate (to stderr), apply :func:`check_plan`."""
    import sys

    plan = estimate_plan(tasks)
    print(plan.describe(jobs), file=stream or sys.stderr)
    check_plan(plan, jobs=jobs, yes=yes, check_memory=check_memory)
    return plan
