"""Start-up Couette flow between parallel plates against the series solution (docs/method.md 6 b).

Morris et al. (1997) parameters: gap L = 1e-3 m, nu = 1e-6 m^2/s, rho0 = 1000 kg/m^3; the plate
at y = 0 is fixed, the plate at y = L moves at U = 1.25e-5 m/s in x from t = 0; x is periodic.
Exact: u(y, t) = U y/L + sum_n (2U/(n pi)) (-1)^n sin(n pi y/L) exp(-n^2 pi^2 nu t / L^2).

Geometry.  Each plate is one row of wall particles plus dummy rows behind it (enough rows to
fill the support, at least 3 dummy rows); every boundary row carries its plate's velocity.
``wall_row`` places the first boundary row:

* ``on-plate`` (default, the MPS convention of wall particles on the wall surface): wall rows at
  y = 0 and y = L, fluid rows at y = l0, 2 l0, ..., L - l0.
* ``offset`` (:func:`mpsbench.physics.particles.wall_layers`' convention, the plate on the line
  half a spacing outside the last fluid row): fluid rows at l0/2, ..., L - l0/2, wall rows at
  -l0/2 and L + l0/2.

With ``wall_velocity = prescribed`` (every boundary row carries the plate velocity) the discrete
no-slip point sits at the first boundary row, so ``offset`` puts it l0/2 outside each plate: the
simulated gap is L + l0 and the profile is off by about l0/(2L) relative (3 % at L/40), an
error of the geometry, not of the Laplacian.  ``mirror`` reflects boundary velocities through
the plate line and suits both placements.

``drift`` adds a uniform x velocity to the fluid and both plates: by Galilean invariance the
profile relative to it is the same (the metrics subtract it), while every particle crosses the
periodic x edges; the smoke tier's drift run holds a backend's periodic wrap (its errors equal
the run without drift to round-off).

The flow is one-dimensional: every fluid row keeps one velocity, so the periodic strip is only
as wide as the neighbour search allows (2 (r_e + l0/2) + l0) and u(y) is the mean over each row
(:class:`mpsbench.run.probes.LayerAverage`).  Gravity is off, c0 = 10 U (docs/method.md: c0 >=
10 U_max; the pressure stays essentially uniform) and dt is the fraction ``c_nu`` = 0.25 of the
backend's explicit viscous limit.  Forward Euler's error is first order in dt and, after the
impulsive start, not negligible against the smallest errors: at L/40, r_e/l0 = 3.1, WF2, xu-jin,
going from c_nu = 0.5 to 0.25 to 0.125 gives 0.204 %, 0.212 %, 0.217 % with prescribed walls
(the dt -> 0 limit is about 0.221 %) and 0.113 %, 0.104 %, 0.099 % with mirrored ones (about
0.094 %).  With ``dt_check`` the transient is repeated at c_nu / 2 and ``dt_halving_change``
records how far the t = 0.1125 s profile moved (the time error at c_nu is about twice that).

Steady state: a second run starts from the exact steady profile U y/L and runs
``STEADY_RUN_TIME`` = 0.3 s (three diffusion times L^2/(pi^2 nu), at c_nu >= 0.5: the steady
state of forward Euler does not depend on dt); it drifts to the model's own
discrete steady state, and ``l2_error_steady`` is its distance from U y/L.  The slowest
component of that drift has reached 1 - exp(-pi^2 nu t / L^2) = 95 % of its final value by then,
the faster (near-wall) ones all of it.  (From rest, the exact profile needs about 0.9 s to come
within 1e-4 U of linear: three times the cost.)
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
from mpsbench.physics.config import FlowPhysics, Models, TimeStepping, WallMotion
from mpsbench.physics.particles import Box, Kind, Particles, block, jitter, wall_layers
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
from . import analysis, figures
from .analysis import HEADLINE_N
from .metrics import (
    END_TIME,
    MOVING_TAG,
    NU,
    RHO,
    SMOKE_DRIFT,
    STEADY_RUN_TIME,
    TIMES,
    L,
    U,
    profile_metrics,
    series,
    sound_speed,
    time_key,
)

__all__ = ["CASE", "L", "U", "profile_metrics", "series", "time_key"]

IGNORE = ("steady", "dt_check")  # they do not change the transient's error
# The refinement sets of the headline cell (xu-jin, WF2, r_e/l0 = 3.1, prescribed walls):
# L/80 (with L/20 and L/40: three spacings) and c_nu / 2, c_nu / 4 at L/40 (three time steps).
REFINEMENT_GRIDS: list[Grid] = [
    RefinementGrid(laplacian=["xu-jin"], weight=["wf2"], re_ratio=[3.1], l0=[L / 80],
                   steady=[False]),
    RefinementGrid(laplacian=["xu-jin"], weight=["wf2"], re_ratio=[3.1], l0=[L / 40],
                   c_nu=[0.125, 0.0625], steady=[False]),
]


class CouetteCase(Case):
    name = "couette"
    title = "Start-up Couette flow (Morris et al. 1997) against the series solution"
    order = 20
    description = (
        f"Plates at y = 0 (fixed) and y = L = {L:g} m (moving at U = {U:g} m/s from t = 0), "
        f"x-periodic, nu = {NU:g} m^2/s.  Velocity profiles u(y) at t = 0.0225, 0.045 and "
        "0.1125 s and at steady state against the series solution; relative L2 error per time, "
        "where the error sits (next to the plates or in the interior), and the change from "
        "L/20 to L/40 (docs/method.md 6 b)."
    )
    params = (
        Param("laplacian", "xu-jin", "Laplacian model", kind=str, choices=an.laplacian_names()),
        Param("weight", "wf2", "weighting function", kind=str, choices=an.weight_names()),
        Param("re_ratio", 3.1, "r_e / l0 of the Laplacian and the number density",
              minimum=1.0, exclusive_minimum=True, maximum=8.0),
        Param("l0", L / 40, "particle spacing; L/l0 must be a whole number (L = 1e-3 m)",
              unit="m", minimum=0.0, exclusive_minimum=True, maximum=L / 8),
        Param("wall_velocity", "prescribed", "viscous boundary velocity: every boundary row "
              "carries the plate velocity, or velocities mirrored through the plate",
              kind=str, choices=("prescribed", "mirror")),
        Param("wall_row", "on-plate", "first boundary row on the plate line, or half a "
              "spacing outside it", kind=str, choices=("on-plate", "offset")),
        Param("steady", True, "also run the steady-state comparison", kind=bool),
        Param("c_nu", 0.25, "time step as a fraction of the explicit viscous stability limit",
              minimum=0.0, exclusive_minimum=True, maximum=0.9),
        Param("dt_check", False, "repeat the transient at c_nu/2 and record the change",
              kind=bool),
        Param("jitter", 0.0, "uniform random displacement of the fluid particles", unit="l0",
              minimum=0.0, maximum=0.3),
        Param("seed", 1, "seed of the jitter", kind=int, minimum=0),
        Param("drift", 0.0, "uniform x velocity added to the fluid and both plates (Galilean "
              "invariance: the profile relative to it is unchanged, while particles cross the "
              "periodic edges); c0 = 10 (U + drift)", unit="m/s", minimum=0.0, maximum=0.1),
    )
    tiers = {
        # seconds: L/20 with both wall treatments, plus the headline cell at L/40
        "smoke": [
            {"laplacian": ["xu-jin", "khayyer-gotoh"], "weight": ["wf2"], "re_ratio": [3.1],
             "l0": [L / 20], "wall_velocity": ["prescribed", "mirror"], "dt_check": [True]},
            {"laplacian": ["xu-jin"], "weight": ["wf2"], "re_ratio": [3.1], "l0": [L / 40],
             "steady": [False]},
            # periodic crossing: every particle crosses the x edges once by t = 0.1125 s
            {"laplacian": ["xu-jin"], "weight": ["wf2"], "re_ratio": [3.1], "l0": [L / 20],
             "steady": [False], "drift": [SMOKE_DRIFT]},
        ],
        # the full model x WF x radius grid at L/20 and L/40 (steady state at r_e/l0 = 3.1),
        # and the mirror treatment at r_e/l0 = 3.1
        "quick": [
            {"laplacian": list(an.MODELS), "weight": list(an.WFS),
             "re_ratio": [2.1, 2.5, 3.5, 4.0], "l0": [L / 20, L / 40], "steady": [False]},
            {"laplacian": list(an.MODELS), "weight": list(an.WFS), "re_ratio": [3.1],
             "l0": [L / 20, L / 40]},
            {"laplacian": list(an.MODELS), "weight": list(an.WFS), "re_ratio": [3.1],
             "l0": [L / 20, L / 40], "wall_velocity": ["mirror"], "steady": [False]},
            *REFINEMENT_GRIDS,
        ],
        # everything, both wall treatments, each with its dt check; the offset placement for
        # the two consistent models
        "paper": [
            {"laplacian": list(an.MODELS), "weight": list(an.WFS),
             "re_ratio": list(RE_RATIOS), "l0": [L / 20, L / 40],
             "wall_velocity": ["prescribed", "mirror"], "dt_check": [True]},
            {"laplacian": ["xu-jin", "koshizuka-oka"], "weight": list(an.WFS),
             "re_ratio": [3.1], "l0": [L / 20, L / 40],
             "wall_velocity": ["prescribed", "mirror"], "wall_row": ["offset"],
             "dt_check": [True]},
            *REFINEMENT_GRIDS,
        ],
    }
    metrics = {
        "l2_error": "relative L2 error of u(y) at t = 0.1125 s: ||u - u_exact|| / ||u_exact|| "
                    "over the fluid rows (-)",
        **{time_key(t): f"relative L2 error of u(y) at t = {t:g} s (-)" for t in TIMES},
        "l2_error_steady": "relative L2 error of the steady profile against U y/L; empty "
                           "without steady (-)",
        "linf_error": "max |u - u_exact| / U at t = 0.1125 s (-)",
        "l2_error_near_wall": "part of l2_error from the rows within r_e of a plate: "
                              "sqrt(sum over those rows of e^2) / ||u_exact|| (-)",
        "l2_error_interior": "part of l2_error from the other rows (the two parts add in "
                             "quadrature to l2_error) (-)",
        "wall_error_share": "fraction of the squared error at t = 0.1125 s in the rows within "
                            "r_e of a plate (-)",
        "wall_row_share": "fraction of the fluid rows within r_e of a plate (-)",
        "max_error_y": "y / L of the row with the largest |u - u_exact| at t = 0.1125 s (-)",
        "dt": "mean time step of the transient run: 0.1125 s / steps (s)",
        "dt_halving_change": "||u(c_nu) - u(c_nu/2)|| / ||u_exact|| at t = 0.1125 s; empty "
                             "without dt_check (-)",
        "max_v": "largest |v| of a fluid particle at t = 0.1125 s, over U (-)",
        "n_rows": "fluid rows across the gap (-)",
    }
    compare = {
        "wall_error_share": ("info", 0.0),
        "wall_row_share": ("info", 0.0),
        "max_error_y": ("info", 0.0),
        "dt": ("equal", 0.01),
        "max_v": ("info", 0.0),
        "dt_halving_change": ("info", 0.0),
        "n_rows": ("equal", 0.0),
    }
    headline = f"l2_error_with_u_num_L-{HEADLINE_N}_prescribed"
    accuracy = ("l2_error", "l2_error_steady", "linf_error")
    # u_num of the t = 0.1125 s error (docs/method.md section 9): in l0 (c_nu fixed, so dt
    # shrinks with l0^2; theoretical order 1 with prescribed walls, whose error at the plates is
    # first order, and 2 with mirrored ones) and in c_nu (forward Euler: order 1 in dt)
    refinements = (
        Refinement("l0", ("l2_error",), SPACE, order=1.0, ignore=IGNORE,
                   where={"wall_velocity": "prescribed"}),
        Refinement("l0", ("l2_error",), SPACE, order=2.0, ignore=IGNORE,
                   where={"wall_velocity": "mirror"}),
        Refinement("c_nu", ("l2_error",), TIME, order=1.0, ignore=IGNORE),
    )

    # ------------------------------------------------------------------ running
    def build(self, params: dict[str, Any]) -> tuple[Problem, np.ndarray]:
        """The problem and the y of the fluid rows."""
        n = _rows(params)
        l0 = L / n
        re = float(params["re_ratio"])
        nx = math.ceil(2.0 * (re + 0.5)) + 1
        width = nx * l0
        n_dummy = max(3, math.ceil(re) - 1)
        if params["wall_row"] == "on-plate":
            fluid = block(0.0, 0.5 * l0, nx, n - 1, l0)
            bottom = wall_layers(0.0, width, 0.5 * l0, l0, 1, n_dummy, "below")
            top = wall_layers(0.0, width, L - 0.5 * l0, l0, 1, n_dummy, "above", (U, 0.0))
            for wall in (bottom, top):  # the plate line is the first boundary row
                wall.fields["wall_dist"] = wall.fields["wall_dist"] - 0.5 * l0
            rows = l0 * np.arange(1, n)
        else:
            fluid = block(0.0, 0.0, nx, n, l0)
            bottom = wall_layers(0.0, width, 0.0, l0, 1, n_dummy, "below")
            top = wall_layers(0.0, width, L, l0, 1, n_dummy, "above", (U, 0.0))
            rows = l0 * (np.arange(n) + 0.5)
        bottom.fields["wall_tag"] = np.zeros(bottom.n)
        top.fields["wall_tag"] = np.full(top.n, float(MOVING_TAG))
        p = Particles.concat([fluid, bottom, top])
        if params["jitter"] > 0:
            jitter(p, params["jitter"] * l0, int(params["seed"]), where=p.kind == Kind.FLUID)
        margin = (n_dummy + 2) * l0
        box = Box((0.0, -margin), (width, L + margin), (True, False))
        drift = float(params["drift"])
        if drift:
            p.vel[:, 0] += drift  # fluid and both plates
        physics = FlowPhysics(rho0=RHO, nu=NU, gravity=(0.0, 0.0), c0=sound_speed(params),
                              wall_velocity=params["wall_velocity"])
        models = Models(weight=params["weight"], laplacian=params["laplacian"], re_ratio=re,
                        n0_from="lattice" if params["jitter"] > 0 else "initial")
        motions = (WallMotion(MOVING_TAG, (U + drift, 0.0)),) + (
            (WallMotion(0, (drift, 0.0)),) if drift else ())
        problem = Problem(p, box, l0, physics, models, TimeStepping(c_nu=params["c_nu"]),
                          wall_motions=motions, name="couette")
        return problem, rows

    def estimate(self, params: dict[str, Any]) -> RunEstimate:
        """The particles of :meth:`build`; steps at the viscous limit on the lattice."""
        n = _rows(params)
        l0, re = L / n, float(params["re_ratio"])
        nx = math.ceil(2.0 * (re + 0.5)) + 1
        walls = 2 * nx * (1 + max(3, math.ceil(re) - 1))
        particles = nx * (n - 1 if params["wall_row"] == "on-plate" else n) + walls
        rho = lattice_laplacian_bound(params["weight"], params["laplacian"], re) / l0**2

        def steps(c_nu: float, duration: float) -> int:
            return steps_for(duration, flow_dt(l0, sound_speed(params), U + params["drift"],
                                               0.2, NU, c_nu, rho))

        total, runs = steps(params["c_nu"], END_TIME), 1
        if params["dt_check"]:
            total, runs = total + steps(0.5 * params["c_nu"], END_TIME), runs + 1
        if params["steady"]:
            total, runs = total + steps(max(params["c_nu"], 0.5), STEADY_RUN_TIME), runs + 1
        return RunEstimate(particles, pairs_for(particles, re), total, solver_runs=runs)

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        result, rows, u = self._transient(params, solver)
        results = [result]
        metrics: dict[str, Any] = {k: math.nan for k in self.metrics}
        metrics["n_rows"] = len(rows)
        if u is None:
            return CaseRun(metrics, results)
        metrics.update(profile_metrics(rows, u, params["re_ratio"] * _spacing(params)))
        metrics["dt"] = END_TIME / result.n_steps
        final = result.final
        if final is not None:
            fluid = final.kind == Kind.FLUID
            metrics["max_v"] = float(np.max(np.abs(final.vel[fluid, 1]))) / U
        arrays = {"y": rows, "times": np.asarray(TIMES), "u": u}
        if params["dt_check"]:
            half, _, u_half = self._transient({**params, "c_nu": 0.5 * params["c_nu"]}, solver)
            results.append(half)
            if u_half is not None:
                exact = series(rows, END_TIME)
                metrics["dt_halving_change"] = float(np.linalg.norm(u[-1] - u_half[-1])
                                                     / np.linalg.norm(exact))
        if params["steady"]:
            steady, u_steady = self._steady(params, solver, rows)
            results.append(steady)
            if u_steady is not None:
                exact = U * rows / L
                metrics["l2_error_steady"] = float(np.linalg.norm(u_steady - exact)
                                                   / np.linalg.norm(exact))
                arrays["u_steady"] = u_steady
        return CaseRun(metrics, results, arrays)

    def _transient(self, params: dict[str, Any], solver: str
                   ) -> tuple[RunResult, np.ndarray, np.ndarray | None]:
        """The start-up run from rest: the result, the fluid rows and u at TIMES (None if the
        run did not complete)."""
        problem, rows = self.build(params)
        l0 = problem.l0
        edges = np.concatenate([rows - 0.5 * l0, [rows[-1] + 0.5 * l0]])
        probe = LayerAverage("u", 1, list(edges), "u", at=list(TIMES))
        result = run(solver, problem, end_time=END_TIME, probes=[probe])
        if not result.ok or len(probe.values) != len(TIMES):
            return result, rows, None
        return result, rows, np.asarray(probe.values, float) - params["drift"]

    def _steady(self, params: dict[str, Any], solver: str,
                rows: np.ndarray) -> tuple[RunResult, np.ndarray | None]:
        # the steady state of forward Euler does not depend on dt: take the larger of c_nu
        # and 0.5 (half the stability limit)
        problem, _ = self.build({**params, "c_nu": max(params["c_nu"], 0.5)})
        p = problem.particles
        fluid = p.kind == Kind.FLUID
        # start from the exact steady profile
        p.vel[fluid, 0] = U * p.pos[fluid, 1] / L + params["drift"]
        l0 = problem.l0
        edges = np.concatenate([rows - 0.5 * l0, [rows[-1] + 0.5 * l0]])
        probe = LayerAverage("u", 1, list(edges), "u", at=[STEADY_RUN_TIME])
        result = run(solver, problem, end_time=STEADY_RUN_TIME, probes=[probe])
        if not result.ok or not probe.values:
            return result, None
        return result, np.asarray(probe.values[-1], float) - params["drift"]

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


def _rows(params: dict[str, Any]) -> int:
    """N = L / l0, refused unless a whole number (the plates must sit on the lattice)."""
    l0 = float(params["l0"])
    n = round(L / l0)
    if n < 1 or abs(n * l0 - L) > 1e-9 * L:
        raise ConfigError(f"parameter l0 = {l0!r} is not allowed: L/N = {L:g}/N m for a "
                          "whole number N")
    return n


def _spacing(params: dict[str, Any]) -> float:
    return L / _rows(params)


CASE = CouetteCase()
