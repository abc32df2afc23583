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
import pandas as pd

from mpsbench.cases import Case, CaseCheck, CaseRun, Param
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

from .. import _common as cm

L = 1.0e-3  # m, gap between the plates
NU = 1.0e-6  # m^2/s
RHO = 1000.0  # kg/m^3
U = 1.25e-5  # m/s, speed of the upper plate
C0 = 10.0 * U  # m/s (without drift)
SMOKE_DRIFT = 4.0e-3  # m/s: 4.5e-4 m (the L/20 strip width, 9 l0) in 0.1125 s
TIMES = (0.0225, 0.045, 0.1125)  # s, Morris et al.'s profile times
END_TIME = TIMES[-1]
STEADY_RUN_TIME = 0.3  # s
MOVING_TAG = 1

# Tolerances that decide pass or fail (issue 4 acceptance; default wall treatment, L/40).
HEADLINE_N = 40
BEST_MODEL, BEST_WEIGHT, BEST_RE, BEST_MAX_L2 = "xu-jin", "wf2", 3.1, 0.01
RATE_MODELS, RATE_RE, RATE_MIN_L2 = ("khayyer-gotoh", "xu-jin-analytic"), 2.1, 0.05
CONVERGING_MODELS, MIN_REDUCTION = ("xu-jin", "koshizuka-oka"), 1.5


def sound_speed(params: dict[str, Any]) -> float:
    """c0 = 10 x the largest speed, U + drift (docs/method.md: c0 >= 10 U_max)."""
    return 10.0 * (U + float(params.get("drift", 0.0)))


def time_key(t: float) -> str:
    return f"l2_error_t{t:g}"


def series(y: np.ndarray | float, t: float, u_wall: float = U, gap: float = L,
           nu: float = NU) -> np.ndarray:
    """Exact start-up Couette velocity u(y, t) [m/s] (terms while exp(...) > 1e-17)."""
    y = np.asarray(y, dtype=float)
    if t <= 0:
        return np.where(y >= gap, u_wall, 0.0)
    rate = math.pi**2 * nu * t / gap**2
    n_max = min(100_000, max(1, math.ceil(math.sqrt(40.0 / rate))))
    n = np.arange(1, n_max + 1)
    exponent = -(n**2) * rate
    decay = np.where(exponent > -700.0, np.exp(np.maximum(exponent, -700.0)), 0.0)
    coef = (2.0 * u_wall / (n * math.pi)) * (-1.0) ** n * decay
    return u_wall * y / gap + np.sin(np.multiply.outer(y, n) * math.pi / gap) @ coef


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
        Param("laplacian", "xu-jin", "Laplacian model", kind=str, choices=cm.laplacian_names()),
        Param("weight", "wf2", "weighting function", kind=str, choices=cm.weight_names()),
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
            # periodic crossing: every particle crosses the x edges about once by t = 0.1125 s
            {"laplacian": ["xu-jin"], "weight": ["wf2"], "re_ratio": [3.1], "l0": [L / 20],
             "steady": [False], "drift": [SMOKE_DRIFT]},
        ],
        # the full model x WF x radius grid at L/20 and L/40 (steady state at r_e/l0 = 3.1),
        # and the mirror treatment at r_e/l0 = 3.1
        "quick": [
            {"laplacian": list(cm.MODELS), "weight": list(cm.WFS),
             "re_ratio": [2.1, 2.5, 3.5, 4.0], "l0": [L / 20, L / 40], "steady": [False]},
            {"laplacian": list(cm.MODELS), "weight": list(cm.WFS), "re_ratio": [3.1],
             "l0": [L / 20, L / 40]},
            {"laplacian": list(cm.MODELS), "weight": list(cm.WFS), "re_ratio": [3.1],
             "l0": [L / 20, L / 40], "wall_velocity": ["mirror"], "steady": [False]},
        ],
        # everything, both wall treatments, each with its dt check; the offset placement for
        # the two consistent models
        "paper": [
            {"laplacian": list(cm.MODELS), "weight": list(cm.WFS),
             "re_ratio": list(cm.RE_RATIOS), "l0": [L / 20, L / 40],
             "wall_velocity": ["prescribed", "mirror"], "dt_check": [True]},
            {"laplacian": ["xu-jin", "koshizuka-oka"], "weight": list(cm.WFS),
             "re_ratio": [3.1], "l0": [L / 20, L / 40],
             "wall_velocity": ["prescribed", "mirror"], "wall_row": ["offset"],
             "dt_check": [True]},
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
    headline = f"l2_error_t0.1125_L-{HEADLINE_N}_prescribed"
    accuracy = ("l2_error", "l2_error_steady", "linf_error")

    # ------------------------------------------------------------------ running
    def build(self, params: dict[str, Any]) -> tuple[Problem, np.ndarray]:
        """The problem and the y of the fluid rows."""
        l0 = float(params["l0"])
        n = round(L / l0)
        if abs(n * l0 - L) > 1e-9 * L:
            raise ConfigError(f"parameter l0 = {l0!r} is not allowed: L/N = {L:g}/N m for a "
                              "whole number N")
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
        n = round(L / float(params["l0"]))
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

    # ------------------------------------------------------------------ checks
    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        df = _default_walls(_with_n(cm.completed(records)))
        head = df[df["n"] == HEADLINE_N] if not df.empty else df
        out = []
        sel = head[(head["laplacian"] == BEST_MODEL) & (head["weight"] == BEST_WEIGHT)
                   & np.isclose(head["re_ratio"], BEST_RE)] if not head.empty else head
        out.append(_bound(f"{BEST_MODEL} / {BEST_WEIGHT} at r_e/l0 = {BEST_RE:g} below "
                          f"{BEST_MAX_L2:.0%} (L/{HEADLINE_N}, t = {END_TIME:g} s, prescribed "
                          "walls)", sel, upper=BEST_MAX_L2))
        sel = head[head["laplacian"].isin(RATE_MODELS) & np.isclose(head["re_ratio"], RATE_RE)
                   ] if not head.empty else head
        out.append(_bound(f"{' and '.join(RATE_MODELS)} above {RATE_MIN_L2:.0%} for every WF "
                          f"at r_e/l0 = {RATE_RE:g} (diffusion-rate error; L/{HEADLINE_N}, "
                          "prescribed walls)", sel, lower=RATE_MIN_L2))
        out.append(self._reduction_check(df))
        return out

    def _reduction_check(self, df: pd.DataFrame) -> CaseCheck:
        name = (f"L/20 -> L/40 reduces the {' and '.join(CONVERGING_MODELS)} errors at least "
                f"{MIN_REDUCTION:g}x (t = {END_TIME:g} s, prescribed walls)")
        conv = convergence_table(df)
        if conv.empty:
            return CaseCheck(name, None, "needs L/20 and L/40 runs")
        conv = conv[conv["model"].isin(CONVERGING_MODELS) & (conv["n_coarse"] == 20)
                    & (conv["n_fine"] == 40)]
        if conv.empty:
            return CaseCheck(name, None, "needs L/20 and L/40 runs of those models")
        worst = cm.row_min(conv, "reduction")
        bad = conv[conv["reduction"] < MIN_REDUCTION]
        detail = (f"{len(conv)} model/WF/radius groups; smallest reduction "
                  f"{worst['reduction']:.2f}x ({worst['model']}, {worst['weight']}, r_e/l0 = "
                  f"{worst['re_ratio']:g}: {cm.pct(worst['error_coarse'])} -> "
                  f"{cm.pct(worst['error_fine'])})")
        if not bad.empty:
            detail += "; below: " + ", ".join(
                f"{r.model}/{r.weight}/{r.re_ratio:g} = {r.reduction:.2f}x"
                for r in bad.itertuples())
        return CaseCheck(name, bad.empty, detail)

    # ------------------------------------------------------------------ tables
    def tables(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        df = _with_n(cm.completed(records))
        if df.empty:
            return {}
        out: dict[str, Any] = {}
        for key, g in _treatment_groups(df):
            out[f"l2_error_t{END_TIME:g}_{key}"] = cm.pivot(g, "l2_error")
        for key, g in _treatment_groups(df):
            if g["l2_error_steady"].notna().any():
                out[f"l2_error_steady_{key}"] = cm.pivot(g, "l2_error_steady")
        for key, g in _treatment_groups(df):
            if g["n"].iloc[0] == df["n"].max():
                loc = location_table(g)
                if not loc.empty:
                    out[f"error_location_{key}"] = loc.set_index("model")
        conv = convergence_table(df)
        if not conv.empty:
            out["convergence"] = conv.set_index(conv.columns[0])
        tt = time_table(df)
        if not tt.empty:
            out["time_stepping"] = tt.set_index(tt.columns[0])
        return {k: v for k, v in out.items() if not v.empty}

    # ------------------------------------------------------------------ figures
    def figures(self, records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
                outdir: Path) -> list[Path]:
        df = _with_n(cm.completed(records))
        if df.empty:
            return []
        out: list[Path | None] = []
        finest = df["n"].max()
        for key, g in _treatment_groups(df):
            if g["n"].iloc[0] == finest:
                out.append(_fig_profiles(g, arrays, outdir, key))
                out.append(_fig_error_profiles(g, arrays, outdir, key))
        out.append(_fig_error_vs_re(df[df["n"] == finest], outdir, finest))
        if df["n"].nunique() > 1:
            out.append(_fig_convergence(df, outdir))
        return [p for p in out if p is not None]

    # ------------------------------------------------------------------ findings
    def findings(self, records: list[dict[str, Any]]) -> str:
        df = _with_n(cm.completed(records))
        if df.empty:
            return "No run completed."
        lines = []
        finest = df["n"].max()
        for key, g in _treatment_groups(df):
            if g["n"].iloc[0] == finest:
                lines.append(_summary_line(g, key))
                loc = _location_line(g)
                if loc:
                    lines.append(loc)
        line = _treatment_line(df)
        if line:
            lines.append(line)
        d = _default_walls(df)
        if not d.empty:
            line = cm.weight_ratio_line(d[d["n"] == d["n"].max()], "l2_error",
                                        f"L/{d['n'].max()}, prescribed walls")
            if line:
                lines.append(line)
        lines += _convergence_lines(convergence_table(df))
        steady = df[df["l2_error_steady"].notna()] if "l2_error_steady" in df else df.iloc[:0]
        if not steady.empty:
            parts = []
            for (wv, model), g in steady.groupby(["wall_velocity", "laplacian"]):
                parts.append(f"{model} ({wv}) {cm.span(g['l2_error_steady'], cm.pct)}")
            lines.append(
                "- **Steady state** (every Laplacian is exact for a linear profile in the "
                "interior, so this is the wall treatment's error): " + "; ".join(parts) + ".")
        tt = time_table(df)
        if not tt.empty:
            worst = cm.row_max(tt, "time_error_share")
            lines.append(
                f"- **Time stepping** ({len(tt)} runs with a dt check): halving dt moves the "
                f"t = {END_TIME:g} s profile by {cm.span(tt['dt_halving_change'], cm.pct)} of "
                "||u_exact||; forward Euler's error (about twice that) is "
                f"{cm.span(tt['time_error_share'], lambda v: f'{100 * v:.0f}%')} of the "
                f"run's error, at most for {worst['model']} / {worst['weight']} / "
                f"{worst['re_ratio']:g} ({worst['wall_velocity']}, L/{worst['n']}).")
        if (df["wall_row"] == "offset").any():
            lines.append(
                "- **wall_row = offset** puts the first boundary row l0/2 outside the plate; "
                "with prescribed velocities the no-slip point follows that row, so the channel "
                "is effectively l0 wider than L (see the module docstring).")
        return "\n".join(lines)


# ---------------------------------------------------------------------- analysis helpers
def profile_metrics(rows: np.ndarray, u: np.ndarray, re: float) -> dict[str, float]:
    """Errors of the profiles ``u`` (one row per time of TIMES) at the fluid rows ``rows``."""
    out: dict[str, float] = {}
    for k, t in enumerate(TIMES):
        exact = series(rows, t)
        out[time_key(t)] = float(np.linalg.norm(u[k] - exact) / np.linalg.norm(exact))
    exact = series(rows, END_TIME)
    err = u[-1] - exact
    near = np.minimum(rows, L - rows) <= re * (1 + 1e-9)
    norm = float(np.linalg.norm(exact))
    total = float(np.sum(err**2))
    out.update(
        l2_error=out[time_key(END_TIME)],
        linf_error=float(np.max(np.abs(err))) / U,
        l2_error_near_wall=float(np.sqrt(np.sum(err[near] ** 2))) / norm,
        l2_error_interior=float(np.sqrt(np.sum(err[~near] ** 2))) / norm,
        wall_error_share=float(np.sum(err[near] ** 2)) / total if total > 0 else 0.0,
        wall_row_share=float(near.mean()),
        max_error_y=float(rows[np.argmax(np.abs(err))] / L),
    )
    return out


def _spacing(params: dict[str, Any]) -> float:
    return L / round(L / float(params["l0"]))


def _with_n(df: pd.DataFrame) -> pd.DataFrame:
    """Add ``n`` = L / l0 (an integer, for grouping without float trouble)."""
    if df.empty:
        return df
    # records written before the drift parameter have no drift column: no drift
    drift = df["drift"].fillna(0.0) if "drift" in df else 0.0
    return df.assign(n=(L / df["l0"]).round().astype(int), drift=drift)


def _default_walls(df: pd.DataFrame) -> pd.DataFrame:
    if df.empty:
        return df
    return df[(df["wall_velocity"] == "prescribed") & (df["wall_row"] == "on-plate")
              & (df["jitter"] == 0) & (df["drift"] == 0)]


def _treatment_groups(df: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """Groups of one resolution and wall treatment, named like ``L-40_prescribed``."""
    out = []
    for (n, wv, wr, jit, dr), g in df.groupby(["n", "wall_velocity", "wall_row", "jitter",
                                               "drift"]):
        key = f"L-{n}_{wv}" + ("" if wr == "on-plate" else f"_{wr}") + (
            "" if jit == 0 else f"_jitter-{jit:g}") + ("" if dr == 0 else f"_drift-{dr:g}")
        out.append((key, g))
    order = {"prescribed": 0, "mirror": 1}
    return sorted(out, key=lambda kv: (-kv[1]["n"].iloc[0], kv[1]["jitter"].iloc[0],
                                       kv[1]["drift"].iloc[0],
                                       kv[1]["wall_row"].iloc[0] != "on-plate",
                                       order.get(kv[1]["wall_velocity"].iloc[0], 2)))


def location_table(g: pd.DataFrame) -> pd.DataFrame:
    """Where the t = 0.1125 s error sits, per model / WF / radius."""
    cols = ["laplacian", "weight", "re_ratio", "l2_error", "l2_error_near_wall",
            "l2_error_interior", "wall_error_share", "wall_row_share"]
    if g.empty:
        return pd.DataFrame()
    t = cm.sort_models(g[cols + (["solver"] if cm.several_solvers(g) else [])], ["re_ratio"])
    t = t.assign(where=np.where(t["wall_error_share"] > 0.5, "near the walls", "interior"))
    return t.rename(columns={"laplacian": "model"}).reset_index(drop=True)


def convergence_table(df: pd.DataFrame) -> pd.DataFrame:
    """L/20 -> L/40 (or whatever resolutions there are): order and error reduction."""
    if df.empty:
        return pd.DataFrame()
    keys = (["solver"] if cm.several_solvers(df) else []) + [
        "laplacian", "weight", "re_ratio", "wall_velocity", "wall_row", "jitter"]
    t = cm.observed_orders(df, "l2_error", keys)
    if t.empty:
        return t
    t = t.assign(reduction=t["error_coarse"] / t["error_fine"],
                 n_coarse=(L / t["l0_coarse"]).round().astype(int),
                 n_fine=(L / t["l0_fine"]).round().astype(int))
    t = cm.sort_models(t, ["wall_row", "wall_velocity", "re_ratio"])
    t = t.rename(columns={"laplacian": "model"})
    lead = [c for c in ("solver", "model", "weight", "re_ratio", "wall_velocity", "wall_row",
                        "jitter", "observed_order", "reduction") if c in t.columns]
    return t[lead + [c for c in t.columns if c not in lead]].reset_index(drop=True)


def time_table(df: pd.DataFrame) -> pd.DataFrame:
    """Runs with a dt check: the change on halving dt against the run's error."""
    if df.empty or "dt_halving_change" not in df or df["dt_halving_change"].notna().sum() == 0:
        return pd.DataFrame()
    cols = (["solver"] if cm.several_solvers(df) else []) + [
        "laplacian", "weight", "re_ratio", "wall_velocity", "wall_row", "n", "c_nu", "dt",
        "l2_error", "dt_halving_change"]
    t = df[df["dt_halving_change"].notna()][cols]
    t = t.assign(time_error=2.0 * t["dt_halving_change"])
    t = t.assign(time_error_share=t["time_error"] / t["l2_error"])
    t = cm.sort_models(t, ["wall_velocity", "n", "re_ratio"])
    return t.rename(columns={"laplacian": "model"}).reset_index(drop=True)


def _bound(name: str, sel: pd.DataFrame, upper: float | None = None,
           lower: float | None = None) -> CaseCheck:
    if sel.empty:
        return CaseCheck(name, None, "no such runs in this study")
    vals = sel["l2_error"].to_numpy(float)
    bad = sel[vals >= upper] if upper is not None else sel[vals <= lower]
    parts = ", ".join(f"{r.laplacian}/{r.weight}/{r.re_ratio:g} {cm.pct(r.l2_error)}"
                      for r in cm.sort_models(sel).itertuples())
    return CaseCheck(name, bad.empty, parts)


def _summary_line(g: pd.DataFrame, key: str) -> str:
    n = g["n"].iloc[0]
    best = cm.row_min(g, "l2_error")
    parts = []
    for model in sorted(g["laplacian"].unique(), key=cm.model_sort_key):
        m = g[g["laplacian"] == model]
        parts.append(f"{model} {cm.span(m['l2_error'], cm.pct)}")
    wins = ""
    cells = g.groupby(["weight", "re_ratio"])
    if cells.ngroups > 1 and g["laplacian"].nunique() > 1:
        winners = pd.Series([str(cm.row_min(c, "l2_error")["laplacian"]) for _, c in cells])
        wins = "  Smallest error per (WF, r_e/l0) cell: " + ", ".join(
            f"{m} in {k} of {len(winners)}" for m, k in winners.value_counts().items()) + "."
    treatment = key.split("_", 1)[1].replace("_", ", ")
    return (f"- **L/{n}, {treatment} walls, t = {END_TIME:g} s**: best {best['laplacian']} / "
            f"{best['weight']} at r_e/l0 = {best['re_ratio']:g} ({cm.pct(best['l2_error'], 3)}). "
            "Error range per model: " + "; ".join(parts) + "." + wins)


def _location_line(g: pd.DataFrame) -> str:
    parts = []
    for model in sorted(g["laplacian"].unique(), key=cm.model_sort_key):
        m = g[g["laplacian"] == model]
        share = m["wall_error_share"]
        where = ("near the walls" if (share > 0.5).all() else "in the interior"
                 if (share <= 0.5).all() else "near the walls or in the interior, by radius")
        peak = m["max_error_y"].dropna() if "max_error_y" in m else m.iloc[:0, 0]
        at = f"; largest error at y/L = {cm.span(peak, lambda v: f'{v:.2f}')}" if len(peak) else ""
        parts.append(f"{model} {where} ({cm.span(share, lambda v: f'{100 * v:.0f}%')} of the "
                     f"squared error next to the plates{at})")
    rows = cm.span(g["wall_row_share"], lambda v: f"{100 * v:.0f}%")
    return (f"  - Where the error sits (rows within r_e of a plate, {rows} of the rows): "
            + "; ".join(parts) + ".")


def _treatment_line(df: pd.DataFrame) -> str:
    """Prescribed against mirror walls on the same cells (finest spacing)."""
    d = df[(df["n"] == df["n"].max()) & (df["wall_row"] == "on-plate") & (df["jitter"] == 0)]
    keys = ["laplacian", "weight", "re_ratio"]
    pre = d[d["wall_velocity"] == "prescribed"].groupby(keys)["l2_error"].first()
    mir = d[d["wall_velocity"] == "mirror"].groupby(keys)["l2_error"].first()
    both = pd.concat([pre.rename("p"), mir.rename("m")], axis=1, join="inner").dropna()
    if both.empty:
        return ""
    parts = []
    for model in sorted(both.index.get_level_values(0).unique(), key=cm.model_sort_key):
        b = both.loc[model]
        parts.append(f"{model} {cm.span(b['p'], cm.pct)} -> {cm.span(b['m'], cm.pct)}")
    return (f"- **Prescribed -> mirror walls** (L/{d['n'].max()}, same cells): " + "; ".join(parts)
            + ".  Where mirroring shrinks the error, the prescribed error was made at the "
            "plates (the dummy rows carry the plate velocity instead of the extrapolated "
            "profile) even though it spreads across the gap as a lag of the whole profile; "
            "what mirroring leaves is the Laplacian's own error.")


def _convergence_lines(conv: pd.DataFrame) -> list[str]:
    if conv.empty:
        return []
    lines = []
    for (wv, wr), c in conv.groupby(["wall_velocity", "wall_row"], sort=False):
        parts = []
        for model in sorted(c["model"].unique(), key=cm.model_sort_key):
            r = c[c["model"] == model]
            parts.append(f"{model} {cm.span(r['reduction'], lambda v: f'{v:.2f}x')} "
                         f"(order {cm.span(r['observed_order'], lambda v: f'{v:.2f}', ' to ')})")
        n0, n1 = c["n_coarse"].iloc[0], c["n_fine"].iloc[0]
        where = str(wv) + ("" if wr == "on-plate" else f", {wr}")
        lines.append(f"- **L/{n0} -> L/{n1} ({where} walls)**: error reduction " + "; ".join(parts)
                     + ".")
    return lines


# ---------------------------------------------------------------------- figures
def _pick(g: pd.DataFrame, weight: str = "wf2", re: float = 3.1) -> tuple[pd.DataFrame, str, float]:
    w = weight if weight in set(g["weight"]) else g["weight"].iloc[0]
    sub = g[g["weight"] == w]
    r = min(sub["re_ratio"].unique(), key=lambda x: abs(x - re))
    return sub[np.isclose(sub["re_ratio"], r)], w, float(r)


def _fig_profiles(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path,
                  key: str) -> Path | None:
    sub, w, re = _pick(g)
    models = sorted(sub["laplacian"].unique(), key=cm.model_sort_key)
    fig, axes = cm.figure(1, len(models), width=3.8, height=4.2)
    yy = np.linspace(0.0, L, 201)
    colours = ["tab:blue", "tab:orange", "tab:green", "k"]
    for col, model in enumerate(models):
        ax = axes[0, col]
        run_rec = sub[sub["laplacian"] == model].iloc[0]
        data = arrays(str(run_rec["run_id"]))
        for k, t in enumerate(TIMES):
            ax.plot(series(yy, t) / U, yy / L, "-", color=colours[k], lw=1,
                    label=f"exact t = {t:g} s")
            if "u" in data:
                ax.plot(data["u"][k] / U, data["y"] / L, "o", ms=3, color=colours[k], mfc="none")
        ax.plot(yy / L, yy / L, "-", color="k", lw=1, label="exact steady")
        if "u_steady" in data:
            ax.plot(data["u_steady"] / U, data["y"] / L, "o", ms=3, color="k", mfc="none")
        ax.set_title(f"{model}\nL2 error at {END_TIME:g} s: {cm.pct(run_rec['l2_error'])}",
                     fontsize=9)
        ax.set_xlabel("u / U")
        ax.set_xlim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("y / L")
    axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Couette: u(y) (circles: particles, lines: series solution); {w}, "
                 f"r_e/l0 = {re:g}, {key.replace('_', ', ').replace('L-', 'L/')} walls")
    return cm.save(fig, outdir / f"profiles_{key}.png")


def _fig_error_profiles(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]],
                        outdir: Path, key: str) -> Path | None:
    """The shape of the error across the gap, e(y) / max|e|, per model (legend: max|e| / U)."""
    weights = sorted(g["weight"].unique())
    fig, axes = cm.figure(1, len(weights), width=5.0, height=4.2)
    for col, w in enumerate(weights):
        sub, _, re = _pick(g, w)
        ax = axes[0, col]
        for model in sorted(sub["laplacian"].unique(), key=cm.model_sort_key):
            rec = sub[sub["laplacian"] == model].iloc[0]
            data = arrays(str(rec["run_id"]))
            if "u" not in data:
                continue
            err = (data["u"][-1] - series(data["y"], END_TIME)) / U
            top = float(np.max(np.abs(err))) or 1.0
            ax.plot(err / top, data["y"] / L, "-o", ms=2.5, color=cm.colour(model),
                    label=f"{model} (max |e| = {top:.2g} U, {100 * rec['wall_error_share']:.0f}%"
                          " of e^2 in grey)")
        l0 = float(sub["l0"].iloc[0])
        band = re * l0 / L
        for lo, hi in ((0.0, band), (1.0 - band, 1.0)):
            ax.axhspan(lo, hi, color="0.85", zorder=0)
        ax.axvline(0.0, color="k", lw=0.7)
        ax.set_xlim(-1.05, 1.05)
        ax.set_xlabel(f"(u - u_exact) / max|u - u_exact| at t = {END_TIME:g} s")
        ax.set_title(f"{w}, r_e/l0 = {re:g} (grey: within r_e of a plate)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=1)
    axes[0, 0].set_ylabel("y / L")
    fig.suptitle(f"Couette: shape of the error across the gap, "
                 f"{key.replace('_', ', ').replace('L-', 'L/')} walls")
    return cm.save(fig, outdir / f"error_profiles_{key}.png")


def _fig_error_vs_re(df: pd.DataFrame, outdir: Path, n: int) -> Path:
    groups = [(k, g) for k, g in _treatment_groups(df)]
    fig, axes = cm.figure(1, len(groups), width=5.2)
    for col, (key, g) in enumerate(groups):
        ax = axes[0, col]
        cm.plot_vs_re(ax, g, "l2_error")
        ax.set_title(key.replace("_", ", ").replace("L-", "L/") + " walls")
        ax.set_ylabel(f"relative L2 error at t = {END_TIME:g} s")
    axes[0, -1].legend(fontsize=7)
    fig.suptitle(f"Couette: error against r_e/l0 per model and WF (L/{n})")
    return cm.save(fig, outdir / f"error_vs_re_L-{n}.png")


def _fig_convergence(df: pd.DataFrame, outdir: Path) -> Path | None:
    d = _default_walls(df)
    if d.empty or d["n"].nunique() < 2:
        return None
    return cm.convergence_figure(
        d, "l2_error", convergence_table(d),
        f"Couette: relative L2 error at t = {END_TIME:g} s against l0 (prescribed walls, "
        "wall row on the plate); legend: observed order", outdir / "convergence.png",
        whole=L, symbol="L", slope=1.0)


CASE = CouetteCase()
