"""2-D diffusion on a periodic unit square against the analytical decay (docs/method.md 6 a).

d(phi)/dt = kappa lap(phi) on fixed particles, phi0 = sin(2 pi x) sin(2 pi y) on [0, 1)^2 with
both axes periodic.  The exact solution is phi = exp(-8 pi^2 kappa t) phi0.  kappa is fixed at
ln 2 / (8 pi^2) m^2/s (about 8.78e-3) so that the exact amplitude halves at the end time
t = 1 s (docs/method.md: run to exp(-8 pi^2 kappa t) = 0.5).

Time stepping is the backend's forward Euler with a fixed dt (parameter ``dt``, default 1e-4 s,
10 000 steps).  Its error does not depend on l0: it is about (lambda dt / 2) lambda t for the
decay rate lambda = ln 2 per s, i.e. 2.4e-5 relative at dt = 1e-4 s, while the smallest spatial
error of the grid (xu-jin on the lattice at l0 = 1/80) is about 5e-4.  With ``dt_check`` a run
is repeated at dt/2 and ``dt_halving_change`` records how much the end field moved; forward
Euler's own error is about twice that change.  The stability limit at the strongest operator of
the grid (khayyer-gotoh, WF2, r_e/l0 = 2.1, l0 = 1/80) is above 1e-3 s.

Jittered arrangements displace every particle by a seeded uniform offset in
[-jitter l0, jitter l0]^2.  They use n0 and lambda of the ideal lattice (``n0_from="lattice"``):
on a jittered cloud the particle with the fullest support is one whose neighbours happen to sit
close, and its n0 (with WF1, singular at r = 0, especially) is not the reference density the
models are normalised with.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mpsbench.cases import Case, CaseCheck, CaseRun, Grid, Param, RefinementGrid
from mpsbench.cases import analysis as an
from mpsbench.cases.refinement import SPACE, TIME, Refinement
from mpsbench.errors import ConfigError
from mpsbench.physics.config import DiffusionPhysics, Models, TimeStepping
from mpsbench.physics.particles import Box, jitter, lattice_in_box
from mpsbench.run.estimate import RunEstimate, diffusion_dt_limit, pairs_for, steps_for
from mpsbench.run.protocol import Problem
from mpsbench.run.runner import run

from ..paper import RE_RATIOS
from . import analysis, figures
from .metrics import END_TIME, EXACT_RATE, FIELD, KAPPA, field_errors, phi0

ALL_L0 = (1 / 20, 1 / 40, 1 / 80)
ALL_JITTER = (0.0, 0.05, 0.1)
DT = 1e-4  # s, the default fixed time step


def _full(**extra: list[Any]) -> Grid:
    return {"laplacian": list(an.MODELS), "weight": list(an.WFS), "re_ratio": list(RE_RATIOS),
            **extra}


# Refinement sets of the headline cells (docs/method.md section 9): every model at WF2,
# r_e/l0 = 3.1 on the lattice at l0 = 1/80 (with 1/20 and 1/40: three spacings) and at
# dt/2, dt/4 (l0 = 1/40: three time steps).  The other cells have two spacings.
def _refinement_grids() -> list[Grid]:
    cell: Grid = {"laplacian": list(an.MODELS), "weight": ["wf2"], "re_ratio": [3.1]}
    return [RefinementGrid(cell, l0=[1 / 80]),
            RefinementGrid(cell, l0=[1 / 40], dt=[DT / 2, DT / 4])]


class DiffusionCase(Case):
    name = "diffusion"
    title = "2-D diffusion on a periodic square (analytical decay)"
    order = 10
    description = (
        "d(phi)/dt = kappa lap(phi) on fixed particles in the periodic unit square, "
        "phi0 = sin(2 pi x) sin(2 pi y), run until the exact amplitude has halved "
        f"(t = {END_TIME:g} s, kappa = ln2/(8 pi^2) = {KAPPA:.4g} m^2/s).  Relative L2 and Linf "
        "errors of the end field, the decay-rate ratio (measured / exact), observed order of "
        "convergence in l0, and a dt-halving check of the time-stepping error (docs/method.md 6 a)."
    )
    params = (
        Param("laplacian", "xu-jin", "Laplacian model", kind=str, choices=an.laplacian_names()),
        Param("weight", "wf2", "weighting function", kind=str, choices=an.weight_names()),
        Param("re_ratio", 3.1, "r_e / l0 of the Laplacian (and number density)",
              minimum=1.0, exclusive_minimum=True, maximum=8.0),
        Param("l0", 1 / 40, "particle spacing; 1/l0 must be a whole number", unit="m",
              minimum=0.0, exclusive_minimum=True, maximum=0.125),
        Param("jitter", 0.0, "uniform random displacement amplitude", unit="l0",
              minimum=0.0, maximum=0.3),
        Param("seed", 1, "seed of the jitter", kind=int, minimum=0),
        Param("dt", DT, "fixed time step", unit="s", minimum=0.0, exclusive_minimum=True,
              maximum=0.01),
        Param("dt_check", False, "repeat the run at dt/2 and record the change", kind=bool),
    )
    tiers = {
        # a handful of runs: one radius, WF2, three models, two resolutions
        "smoke": [
            {"laplacian": ["koshizuka-oka", "khayyer-gotoh", "xu-jin"], "weight": ["wf2"],
             "re_ratio": [3.1], "l0": [1 / 20], "dt_check": [True]},
            {"laplacian": ["koshizuka-oka", "khayyer-gotoh", "xu-jin"], "weight": ["wf2"],
             "re_ratio": [3.1], "l0": [1 / 40]},
        ],
        # the full model x WF x radius grid on the lattice at l0 = 1/20 and 1/40 (the time step
        # checked at 1/20: its error does not depend on l0), and jitter 0.1 at r_e/l0 = 3.1
        "quick": [
            _full(l0=[1 / 20], dt_check=[True]),
            _full(l0=[1 / 40]),
            {"laplacian": list(an.MODELS), "weight": list(an.WFS), "re_ratio": [3.1],
             "l0": [1 / 20, 1 / 40], "jitter": [0.1]},
            *_refinement_grids(),
        ],
        # the whole grid of docs/method.md 6 a, every run with its dt-halving check
        "paper": [_full(l0=list(ALL_L0), jitter=list(ALL_JITTER), dt_check=[True]),
                  _refinement_grids()[1]],
    }
    metrics = {
        "l2_error": "relative L2 error of phi at t_end: ||phi - phi_exact|| / ||phi_exact|| (-)",
        "linf_error": "relative Linf error at t_end: max|phi - phi_exact| / max|phi_exact| (-)",
        "decay_ratio": "measured decay rate / exact rate 8 pi^2 kappa; the measured rate is "
                       "-ln(a)/t_end with a the projection of phi on phi0 (-)",
        "dt_halving_change": "||phi(dt) - phi(dt/2)||_2 / ||phi_exact||_2 at t_end; empty "
                             "without dt_check (-)",
        "end_time": "simulated time (s)",
        "kappa": "diffusivity (m^2/s)",
        "n0_from": "where n0 and lambda come from: initial (lattice runs) or lattice (jittered)",
    }
    compare = {
        "decay_ratio": ("equal", 0.01),
        "dt_halving_change": ("info", 0.0),
        "end_time": ("info", 0.0),
        "kappa": ("info", 0.0),
    }
    headline = "l2_error_with_u_num_l0-1_40"
    # u_num of the L2 error and the decay ratio (docs/method.md section 9): in l0 on the
    # lattice (theoretical order 2, used with two spacings) and in dt (forward Euler, order 1)
    refinements = (
        Refinement("l0", ("l2_error", "decay_ratio"), SPACE, order=2.0, ignore=("dt_check",),
                   where={"jitter": 0.0}),
        Refinement("dt", ("l2_error", "decay_ratio"), TIME, order=1.0, ignore=("dt_check",)),
    )

    # ------------------------------------------------------------------ running
    def build(self, params: dict[str, Any]) -> Problem:
        """The problem for one parameter set (the particles carry phi0 in ``fields['phi']``)."""
        n = side_count(params)
        box = Box((0.0, 0.0), (1.0, 1.0), (True, True))
        p = lattice_in_box(box, 1.0 / n)
        if params["jitter"] > 0:
            jitter(p, params["jitter"] / n, int(params["seed"]))
            box.wrap(p.pos)
        p.fields[FIELD] = phi0(p.pos)
        models = Models(
            weight=params["weight"], laplacian=params["laplacian"], re_ratio=params["re_ratio"],
            # a jittered cloud has no interior particle with the lattice's support: use the
            # ideal lattice's n0 and lambda (see the module docstring)
            n0_from="lattice" if params["jitter"] > 0 else "initial",
        )
        return Problem(p, box, 1.0 / n, DiffusionPhysics(kappa=KAPPA, field_name=FIELD), models,
                       TimeStepping(dt=params["dt"]), name="diffusion")

    def estimate(self, params: dict[str, Any]) -> RunEstimate:
        """N^2 particles; the fixed dt against the forward-Euler limit of the lattice (for a
        jittered cloud, the limit of the lattice it was jittered from)."""
        n = side_count(params)
        particles = n * n
        lap, wf, re = params["laplacian"], params["weight"], float(params["re_ratio"])
        dt = float(params["dt"])
        steps, runs = steps_for(END_TIME, dt), 1
        if params["dt_check"]:
            steps, runs = steps + steps_for(END_TIME, 0.5 * dt), 2
        rule = (f"forward Euler, 2 / (kappa rho), rho the spectral radius of {lap} / {wf} at "
                f"r_e/l0 = {re:g} on the lattice of l0 = 1/{n}")
        return RunEstimate(particles, pairs_for(particles, re), steps, dt=dt,
                           dt_limit=diffusion_dt_limit(KAPPA, n, wf, lap, re),
                           dt_rule=rule, solver_runs=runs)

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        problem = self.build(params)
        start = problem.particles.copy()
        result = run(solver, problem, end_time=END_TIME)
        results = [result]
        metrics: dict[str, Any] = {
            "end_time": END_TIME, "kappa": KAPPA, "n0_from": problem.models.n0_from,
            "l2_error": math.nan, "linf_error": math.nan, "decay_ratio": math.nan,
            "dt_halving_change": math.nan,
        }
        arrays: dict[str, np.ndarray] = {}
        if not result.ok or result.final is None:
            return CaseRun(metrics, results)
        start_phi = start.fields[FIELD]
        phi = result.final.fields[FIELD]
        exact = math.exp(-EXACT_RATE * END_TIME) * start_phi
        metrics.update(field_errors(phi, exact, start_phi, END_TIME))
        if params["dt_check"]:
            half = self.build({**params, "dt": 0.5 * params["dt"]})
            second = run(solver, half, end_time=END_TIME)
            results.append(second)
            if second.ok and second.final is not None:
                diff = phi - second.final.fields[FIELD]
                metrics["dt_halving_change"] = float(np.linalg.norm(diff) / np.linalg.norm(exact))
        arrays = {
            "x": start.pos[:, 0].astype(np.float32),
            "y": start.pos[:, 1].astype(np.float32),
            "error": ((phi - exact) / np.max(np.abs(exact))).astype(np.float32),
        }
        return CaseRun(metrics, results, arrays)

    # ------------------------------------------------------------------ report
    # The model grid's tables and comparisons use ``model_records`` (the refinement runs feed
    # u_num only, through ``uncertainty(records)``).
    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        return analysis.gates(self.model_records(records))

    def claims(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        return analysis.claims(self.model_records(records), self.uncertainty(records))

    def tables(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        return analysis.tables(self.model_records(records), self.uncertainty(records))

    def figures(self, records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
                outdir: Path) -> list[Path]:
        return figures.figures(self.model_records(records), arrays, outdir,
                               self.uncertainty(records))

    def findings(self, records: list[dict[str, Any]]) -> str:
        return analysis.findings(self.model_records(records), self.uncertainty(records))


def side_count(params: dict[str, Any]) -> int:
    """N = 1 / l0, refused unless a whole number (the lattice must fill the periodic square)."""
    l0 = float(params["l0"])
    n = round(1.0 / l0)
    if n < 1 or abs(n * l0 - 1.0) > 1e-9:
        raise ConfigError(f"parameter l0 = {l0!r} is not allowed: 1/N for a whole number N")
    return n


CASE = DiffusionCase()

