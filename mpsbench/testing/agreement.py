"""Two solvers on the same short problems, particle by particle: ``mpsbench check NAME
--against reference`` and the pytest helper :func:`assert_agrees`.

Each problem of :func:`agreement_problems` both solvers can run is set up on each with the
same fixed time step (the ``against`` solver's stable dt, halved), stepped the same number of
times, and the states compared particle by particle (the contract keeps the problem's particle
order): the largest position difference in units of l0, the largest velocity difference
relative to the largest speed, the largest pressure difference relative to the largest
pressure (at least 1e-6 rho0 c0^2; for diffusion: the field).  Two implementations of the
same scheme agree to round-off over these few dozen steps (the numba backend: about 1e-12);
a different method (an SPH code) does not, and the table says by how much.  Problems one of
them cannot run are listed with the reason.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from mpsbench.physics.config import Models
from mpsbench.physics.particles import Kind
from mpsbench.run.protocol import Capabilities, Problem, UnsupportedProblem

from . import problems
from .checks import SolverSpec, _with_dt, capabilities_of, fresh_solver, solver_label

TOLERANCE = 1e-6
"""Default agreement tolerance of every compared quantity (round-off accumulates to about
1e-12 over these steps between two correct implementations of the same scheme)."""


@dataclass(frozen=True)
class Difference:
    """The largest differences on one problem (NaN where not compared); ``skipped`` says why a
    problem was not run."""

    problem: str
    steps: int = 0
    position: float = math.nan  # max |dr| / l0
    velocity: float = math.nan  # max |du| / max |u|
    pressure: float = math.nan  # max |dp| / max |p| (diffusion: the field)
    skipped: str = ""
    note: str = ""  # the solver under test raised: what and when (a disagreement)

    def worst(self) -> float:
        """The largest of the three (inf when one is not finite; NaN when not compared)."""
        if self.skipped:
            return math.nan
        vals = (self.position, self.velocity, self.pressure)
        return max(v if math.isfinite(v) else math.inf for v in vals)

    def agrees(self, tolerance: float = TOLERANCE) -> bool | None:
        """True within ``tolerance``, False beyond it, None when not compared."""
        if self.skipped:
            return None
        worst = self.worst()
        return bool(worst <= tolerance) if math.isfinite(worst) else False

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _column(**physics: Any) -> Callable[[], Problem]:
    return lambda: problems.column_in_tank_problem(
        models=Models(gradient=physics.pop("gradient", "pgm1")), **physics)


def agreement_problems() -> Iterator[tuple[str, Callable[[], Problem], int]]:
    """(label, builder, steps): a dam break under every gradient and option, periodic flows
    (one crossing the periodic edges, one shifting), a Couette channel, diffusion."""
    for grad in ("pgm1", "pgm2", "pgm3"):
        yield f"column in tank, {grad}", _column(gradient=grad), 40
    yield "column in tank, stabilization", _column(stabilization=True), 40
    yield "column in tank, collision", _column(collision=True), 40
    yield "column in tank, mirror walls", _column(wall_velocity="mirror"), 40
    # a free surface (its particles do not shift) and walls in the shifting's sums
    yield "column in tank, shifting", _column(shifting=True, shifting_coefficient=4.0), 40

    def jittered() -> Problem:
        return problems.periodic_flow_problem(velocity=0.2, models=Models(n0_from="lattice"))

    def crossing() -> Problem:
        pr = problems.periodic_flow_problem(amplitude=0.0, models=Models(n0_from="lattice"))
        pr.particles.vel[:] = (0.5, 0.25)
        return pr

    yield "periodic box, jittered, random velocities", jittered, 40

    def shifted() -> Problem:
        return problems.periodic_flow_problem(velocity=0.2, models=Models(n0_from="lattice"),
                                              shifting=True)

    yield "periodic box, jittered, shifting", shifted, 40
    yield "periodic box, drift across the edges", crossing, 120
    yield ("channel, moving lid (Couette)",
           lambda: problems.channel_problem(top_velocity=(0.01, 0.0)), 40)
    yield "diffusion, jittered periodic", lambda: problems.diffusion_problem(value=None), 20


def _state_difference(a: Any, b: Any, problem: Problem) -> tuple[float, ...]:
    l0 = problem.l0
    field = getattr(problem.physics, "field_name", None)
    # a fluid at rest on a lattice has pressures of round-off size: the floor of the pressure
    # scale is 1e-6 rho0 c0^2 (0.1 Pa for water at c0 = 10 m/s)
    floor = 1e-6 * problem.physics.rho0 * problem.physics.c0**2 if not field else 0.0  # type: ignore[union-attr]
    if a.n != b.n or not np.array_equal(a.kind, b.kind):
        return (math.inf, math.inf, math.inf)
    pos = float(np.abs(a.pos - b.pos).max()) / l0
    speed = float(np.abs(b.vel).max())
    vel = float(np.abs(a.vel - b.vel).max()) / speed if speed > 0 else float(
        np.abs(a.vel - b.vel).max())
    qa, qb = (a.fields[field], b.fields[field]) if field else (a.pressure, b.pressure)
    if not field:  # dummy particles carry no pressure in MPS; compare where both compute one
        keep = a.kind != Kind.DUMMY
        qa, qb = qa[keep], qb[keep]
    scale = max(float(np.abs(qb).max()) if len(qb) else 0.0, floor)
    diff = float(np.abs(qa - qb).max()) if len(qb) else 0.0
    return pos, vel, diff / scale if scale > 0 else diff


def compare_solvers(
    solver: SolverSpec, against: SolverSpec = "reference",
    progress: Callable[[Difference], None] | None = None,
) -> list[Difference]:
    """Run every agreement problem on both solvers; the largest differences of each."""
    caps: list[Capabilities] = [capabilities_of(solver), capabilities_of(against)]
    out = []
    for label, build, steps in agreement_problems():
        problem = build()
        gaps = [g for c in caps for g in c.gaps(problem)]
        if gaps:
            diff = Difference(label, skipped="; ".join(dict.fromkeys(gaps)))
        else:
            diff = _run_pair(label, problem, steps, solver, against)
        if progress is not None:
            progress(diff)
        out.append(diff)
    return out


def _run_pair(label: str, problem: Problem, steps: int, solver: SolverSpec,
              against: SolverSpec) -> Difference:
    ref = fresh_solver(against)
    try:
        ref.setup(problem)
    except UnsupportedProblem as exc:
        return Difference(label, skipped=str(exc))
    dt = 0.5 * float(ref.stable_dt())
    fixed = _with_dt(problem, dt)
    with np.errstate(all="ignore"):  # a blow-up shows as an infinite difference
        states = _run_both(label, fixed, steps, dt, solver, against)
    if isinstance(states, Difference):
        return states
    pos, vel, pres = _state_difference(states[0], states[1], problem)
    return Difference(label, steps, pos, vel, pres)


def _run_both(label: str, fixed: Problem, steps: int, dt: float, solver: SolverSpec,
              against: SolverSpec) -> list[Any] | Difference:
    states = []
    for spec in (solver, against):
        s = fresh_solver(spec)
        try:
            s.setup(fixed)
        except UnsupportedProblem as exc:
            return Difference(label, skipped=str(exc))
        try:
            for _ in range(steps):
                s.step(dt)
        except Exception as exc:  # noqa: BLE001 - reported, the other problems go on
            what = f"{type(exc).__name__}: {exc} (step {s.n_steps + 1})"
            if spec is solver:  # the solver under test could not finish: no agreement
                return Difference(label, steps, math.inf, math.inf, math.inf, note=what)
            return Difference(label, skipped=f"{solver_label(against)} raised {what}")
        states.append(s.state().copy())
    return states


class AgreementError(AssertionError):
    """At least one problem disagrees beyond the tolerance; ``differences`` holds them all."""

    def __init__(self, solver: str, against: str, differences: list[Difference],
                 tolerance: float) -> None:
        self.differences = differences
        bad = [d for d in differences if d.agrees(tolerance) is False]
        lines = [f"{d.problem}: position {d.position:.3g} l0, velocity {d.velocity:.3g}, "
                 f"pressure {d.pressure:.3g}" for d in bad]
        super().__init__(f"{solver} and {against} differ beyond {tolerance:g} on {len(bad)} of "
                         f"{len(differences)} problems:\n  " + "\n  ".join(lines))


def assert_agrees(solver: SolverSpec, against: SolverSpec = "reference",
                  tolerance: float = TOLERANCE) -> list[Difference]:
    """Raise :class:`AgreementError` unless ``solver`` agrees with ``against`` within
    ``tolerance`` on every problem both can run (the pytest helper); return the differences."""
    diffs = compare_solvers(solver, against)
    if any(d.agrees(tolerance) is False for d in diffs):
        raise AgreementError(solver_label(solver), solver_label(against), diffs, tolerance)
    return diffs
