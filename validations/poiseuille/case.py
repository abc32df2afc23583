"""Start-up Poiseuille flow driven by a body force, against the series solution
(docs/method.md 6 f).

Morris, Fox & Zhu (1997) parameters: plates y = 0 and y = L = 1e-3 m at rest, nu = 1e-6 m^2/s,
rho0 = 1000 kg/m^3, body force F = 2e-4 m/s^2 along +x from t = 0 (steady u_max = F L^2 /
(8 nu) = 2.5e-5 m/s), x periodic.  The force is the problem's gravity vector (F, 0): every
backend applies it as the body force it already applies for gravity.

Geometry and wall treatments are those of the Couette case (:mod:`..couette.case`, whose
docstring gives the reasons): a periodic strip 2 (r_e/l0 + 1/2) + 1 columns wide, one wall row
plus dummy rows per plate, ``wall_row`` on-plate (wall rows on y = 0 and y = L) or offset (half a
spacing outside), ``wall_velocity`` prescribed (every boundary particle at rest) or mirror.
c0 = 10 u_max, dt = ``c_nu`` = 0.25 of the explicit viscous limit.  u(y) is the mean u over each
fluid row at t = 0.0225, 0.045 and 0.1125 s.  Steady state: a second run starts from the exact
parabola and runs 0.3 s (three diffusion times) at c_nu >= 0.5; ``l2_error_steady`` is its
distance from the parabola (unlike Couette's line, the parabola has a curvature every Laplacian
must get right in the interior, so this measures the Laplacian and the walls together).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mpsbench.cases import Case, CaseCheck, CaseRun, Grid, Param, RefinementGrid
from mpsbench.cases import analysis as an
from mpsbench.cases.refinement import SPACE, Refinement
from mpsbench.errors import ConfigError
from mpsbench.physics.config import FlowPhysics, Models, TimeStepping
from mpsbench.physics.particles import Box, Particles, block, wall_layers
from mpsbench.run.estimate import (
    RunEstimate,
    flow_dt,
    lattice_laplacian_bound,
    pairs_for,
    steps_for,
)
from mpsbench.run.probes import LayerAverage
from mpsbench.run.protocol import Problem
from mpsbench.run.runner import RunResult, run

from ..paper import RE_RATIOS
from .metrics import (
    C0,
    END_TIME,
    FLOW,
    NU,
    RHO,
    STEADY_RUN_TIME,
    TIMES,
    U_MAX,
    F,
    L,
    profile_metrics,
    steady_error,
    time_key,
)

IGNORE = ("steady",)  # it does not change the transient's error
HEADLINE_N = 40
# The refinement sets of the headline cell (xu-jin, WF2, r_e/l0 = 3.1, prescribed walls): with
# the model grid's L/20 and L/40, L/10 in the quick tier (a fiftieth of the cost of L/80, which
# costs about four L/40 runs: dt falls with l0^2) and L/80 in the paper tier.
HEADLINE: Grid = {"laplacian": ["xu-jin"], "weight": ["wf2"], "re_ratio": [3.1],
                  "steady": [False]}
REFINE_QUICK: Grid = RefinementGrid(HEADLINE | {"l0": [L / 10]})
REFINE_PAPER: Grid = RefinementGrid(HEADLINE | {"l0": [L / 10, L / 80]})

PARAMS = (
    Param("laplacian", "xu-jin", "Laplacian model", kind=str, choices=an.laplacian_names()),
    Param("weight", "wf2", "weighting function", kind=str, choices=an.weight_names()),
    Param("re_ratio", 3.1, "r_e / l0 of the Laplacian and the number density",
          minimum=1.0, exclusive_minimum=True, maximum=8.0),
    Param("l0", L / 40, "particle spacing; L/l0 must be a whole number (L = 1e-3 m)",
          unit="m", minimum=0.0, exclusive_minimum=True, maximum=L / 8),
    Param("wall_velocity", "prescribed", "viscous boundary velocity: boundary rows at rest, "
          "or velocities mirrored through the plate", kind=str,
          choices=("prescribed", "mirror")),
    Param("wall_row", "on-plate", "first boundary row on the plate line, or half a spacing "
          "outside it", kind=str, choices=("on-plate", "offset")),
    Param("steady", True, "also run the steady-state comparison", kind=bool),
    Param("c_nu", 0.25, "time step as a fraction of the explicit viscous stability limit",
          minimum=0.0, exclusive_minimum=True, maximum=0.9),
)

TIERS: dict[str, list[Grid]] = {
    # seconds: L/20 (the steady state of the default cell; khayyer-gotoh; mirrored walls) and
    # the headline cell at L/40
    "smoke": [
        {"l0": [L / 20]},
        {"laplacian": ["khayyer-gotoh"], "l0": [L / 20], "steady": [False]},
        {"l0": [L / 20], "wall_velocity": ["mirror"], "steady": [False]},
        {"l0": [L / 40], "steady": [False]},
    ],
    # every model at WF2, r_e/l0 = 3.1: L/20 (with the steady state) and L/40, the mirror
    # treatment at L/20, and L/10 of the headline cell (its refinement set); the quick tier's
    # budget leaves WF1 and the other radii to the paper tier
    "quick": [
        {"laplacian": list(an.MODELS), "l0": [L / 20]},
        # khayyer-gotoh's 40 % diffusion-rate error at L/20 needs no L/40 run (the smallest
        # dt of the four: a third of the tier's time)
        {"laplacian": ["koshizuka-oka", "xu-jin", "xu-jin-analytic"], "l0": [L / 40],
         "steady": [False]},
        {"laplacian": list(an.MODELS), "l0": [L / 20], "wall_velocity": ["mirror"],
         "steady": [False]},
        REFINE_QUICK,
    ],
    "paper": [
        {"laplacian": list(an.MODELS), "weight": list(an.WFS), "re_ratio": list(RE_RATIOS),
         "l0": [L / 20, L / 40], "wall_velocity": ["prescribed", "mirror"]},
        {"laplacian": ["xu-jin", "koshizuka-oka"], "weight": list(an.WFS), "re_ratio": [3.1],
         "l0": [L / 20, L / 40], "wall_velocity": ["prescribed", "mirror"],
         "wall_row": ["offset"]},
        REFINE_PAPER,
    ],
}

METRICS = {
    "l2_error": "relative L2 error of u(y) at t = 0.1125 s: ||u - u_exact|| / ||u_exact|| "
                "over the fluid rows (-)",
    **{time_key(t): f"relative L2 error of u(y) at t = {t:g} s (-)" for t in TIMES},
    "l2_error_steady": "relative L2 error of the steady profile against F y (L - y) / (2 nu); "
                       "empty without steady (-)",
    "linf_error": "max |u - u_exact| / u_max at t = 0.1125 s (-)",
    "centreline_error": "u / u_exact - 1 at the row nearest y = L/2, t = 0.1125 s (-)",
    "dt": "mean time step of the transient run: 0.1125 s / steps (s)",
    "n_rows": "fluid rows across the gap (-)",
}

COMPARE: dict[str, tuple[str, float]] = {
    "centreline_error": ("info", 0.0),
    "dt": ("equal", 0.01),
    "n_rows": ("equal", 0.0),
}


def _rows(params: dict[str, Any]) -> int:
    n = round(L / float(params["l0"]))
    if abs(n * float(params["l0"]) - L) > 1e-9 * L:
        raise ConfigError(f"parameter l0 = {params['l0']!r} is not allowed: L/N = {L:g}/N m "
                          "for a whole number N")
    return n


def _strip(re: float) -> tuple[int, int]:
    """Strip width in columns and dummy rows per plate (as for Couette)."""
    return math.ceil(2.0 * (re + 0.5)) + 1, max(3, math.ceil(re) - 1)


def build(params: dict[str, Any], c_nu: float | None = None) -> tuple[Problem, np.ndarray]:
    """The problem and the y of the fluid rows."""
    n = _rows(params)
    l0 = L / n
    re = float(params["re_ratio"])
    nx, n_dummy = _strip(re)
    width = nx * l0
    if params["wall_row"] == "on-plate":
        fluid = block(0.0, 0.5 * l0, nx, n - 1, l0)
        bottom = wall_layers(0.0, width, 0.5 * l0, l0, 1, n_dummy, "below")
        top = wall_layers(0.0, width, L - 0.5 * l0, l0, 1, n_dummy, "above")
        for wall in (bottom, top):  # the plate line is the first boundary row
            wall.fields["wall_dist"] = wall.fields["wall_dist"] - 0.5 * l0
        rows = l0 * np.arange(1, n)
    else:
        fluid = block(0.0, 0.0, nx, n, l0)
        bottom = wall_layers(0.0, width, 0.0, l0, 1, n_dummy, "below")
        top = wall_layers(0.0, width, L, l0, 1, n_dummy, "above")
        rows = l0 * (np.arange(n) + 0.5)
    margin = (n_dummy + 2) * l0
    box = Box((0.0, -margin), (width, L + margin), (True, False))
    physics = FlowPhysics(rho0=RHO, nu=NU, gravity=(F, 0.0), c0=C0,
                          wall_velocity=params["wall_velocity"])
    models = Models(weight=params["weight"], laplacian=params["laplacian"], re_ratio=re)
    stepping = TimeStepping(c_nu=params["c_nu"] if c_nu is None else c_nu)
    problem = Problem(Particles.concat([fluid, bottom, top]), box, l0, physics, models,
                      stepping, name="poiseuille")
    return problem, rows


class PoiseuilleCase(Case):
    name = "poiseuille"
    title = "Start-up Poiseuille flow (Morris et al. 1997) against the series solution"
    order = 60
    description = (
        f"Plates at rest at y = 0 and y = L = {L:g} m, body force F = {F:g} m/s^2 along x from "
        f"t = 0, x-periodic, nu = {NU:g} m^2/s (steady u_max = {U_MAX:g} m/s).  Velocity "
        "profiles u(y) at t = 0.0225, 0.045 and 0.1125 s and at steady state against the "
        "series solution; relative L2 error per time, the observed order from L/20 to L/40 "
        "(and L/10, L/80 for the headline cell), with the Couette case's wall treatments "
        "(docs/method.md 6 f)."
    )
    params = PARAMS
    tiers = TIERS
    metrics = METRICS
    compare = COMPARE
    headline = f"l2_error_with_u_num_L-{HEADLINE_N}_prescribed"
    # u_num of the t = 0.1125 s error in l0 at fixed c_nu (dt shrinks with l0^2); order 1
    # assumed with two levels and prescribed walls (their error at the plates is first order),
    # 2 with mirrored ones
    refinements = (
        Refinement("l0", ("l2_error",), SPACE, order=1.0, ignore=IGNORE,
                   where={"wall_velocity": "prescribed"}),
        Refinement("l0", ("l2_error",), SPACE, order=2.0, ignore=IGNORE,
                   where={"wall_velocity": "mirror"}),
    )

    def estimate(self, params: dict[str, Any]) -> RunEstimate:
        """The particles of :func:`build`; steps at the viscous limit on the lattice."""
        n = _rows(params)
        l0, re = L / n, float(params["re_ratio"])
        nx, n_dummy = _strip(re)
        particles = nx * (n - 1 if params["wall_row"] == "on-plate" else n) \
            + 2 * nx * (1 + n_dummy)
        rho = lattice_laplacian_bound(params["weight"], params["laplacian"], re) / l0**2

        def steps(c_nu: float, duration: float) -> int:
            return steps_for(duration, flow_dt(l0, C0, U_MAX, 0.2, NU, c_nu, rho))

        total, runs = steps(params["c_nu"], END_TIME), 1
        if params["steady"]:
            total, runs = total + steps(max(params["c_nu"], 0.5), STEADY_RUN_TIME), runs + 1
        return RunEstimate(particles, pairs_for(particles, re), total, solver_runs=runs)

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        problem, rows = build(params)
        result, u = _profiles(solver, problem, rows, TIMES)
        metrics: dict[str, Any] = {k: math.nan for k in self.metrics}
        metrics["n_rows"] = len(rows)
        results = [result]
        if u is None:
            return CaseRun(metrics, results)
        metrics.update(profile_metrics(rows, u))
        metrics["dt"] = END_TIME / result.n_steps
        arrays = {"y": rows, "times": np.asarray(TIMES), "u": u}
        if params["steady"]:
            # the steady state of forward Euler does not depend on dt: c_nu >= 0.5
            steady, _ = build(params, c_nu=max(params["c_nu"], 0.5))
            p = steady.particles
            fluid = p.fluid
            p.vel[fluid, 0] = FLOW.steady(np.clip(p.pos[fluid, 1], 0.0, L))
            res, u_steady = _profiles(solver, steady, rows, (STEADY_RUN_TIME,))
            results.append(res)
            if u_steady is not None:
                metrics["l2_error_steady"] = steady_error(rows, u_steady[-1])
                arrays["u_steady"] = u_steady[-1]
        return CaseRun(metrics, results, arrays)

    # ------------------------------------------------------------------ report
    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        from .analysis import gates

        return gates(self.model_records(records))

    def tables(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        from .analysis import tables

        return tables(self.model_records(records), self.uncertainty(records))

    def figures(self, records: list[dict[str, Any]],
                arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path) -> list[Path]:
        from .figures import figures

        return figures(self.model_records(records), arrays, outdir, self.uncertainty(records))

    def findings(self, records: list[dict[str, Any]]) -> str:
        from .analysis import findings

        return findings(self.model_records(records), self.uncertainty(records))


def _profiles(solver: str, problem: Problem, rows: np.ndarray, times: tuple[float, ...]
              ) -> tuple[RunResult, np.ndarray | None]:
    """Run to the last of ``times``; u(y) per row at each (None if the run did not complete)."""
    l0 = problem.l0
    edges = np.concatenate([rows - 0.5 * l0, [rows[-1] + 0.5 * l0]])
    probe = LayerAverage("u", 1, list(edges), "u", at=list(times))
    result = run(solver, problem, end_time=times[-1], probes=[probe])
    if not result.ok or len(probe.values) != len(times):
        return result, None
    return result, np.asarray(probe.values, float)


CASE = PoiseuilleCase()
