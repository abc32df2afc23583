"""Hydrostatic tank: a water column at rest under gravity stays at rest (docs/method.md 6 e).

Adami, Hu & Adams (2012, J. Comput. Phys. 231:7057) for SPH and Shibata et al. (2015) for MPS
use the column at rest as the first test of a wall treatment and a pressure gradient: nothing
should move, the pressure should be rho0 g (H - y) (:mod:`.reference`).  A WC-MPS column is
released from the square lattice, with the lattice's number density n0 everywhere: the fluid
first compresses under its weight (about rho0 g H / (rho0 c0^2) = 0.5 % of H at c0 =
10 sqrt(2 g H)), rings acoustically and, if the scheme damps it, settles.  Without the velocity
stabilization the ringing does not settle: the lattice melts into a churning state whose RMS
speed grows (issue 17: 0.28 m/s after 2 s at l0 = 0.01 m), the surface rises, and with some
models the run diverges; that is what the case shows beside the stabilized rest.

Geometry: a column ``width`` x ``height`` (0.2 m x 0.3 m) fills a tank of that width
(:func:`mpsbench.physics.particles.tank`: one wall row and three dummy rows) whose walls reach
``height`` + 0.1 m; the column is nx x ny particles with nx = round(width / l0), ny =
round(height / l0), so the simulated column is H = ny l0 high.  Probes every ``SAMPLE_EVERY``
s: the RMS speed of the fluid, the free surface (mean of the nx highest particles + l0/2), and
the fluid pressure in horizontal layers of height l0.  The pressure metrics average the layers
over the second half of the run (the settled window; see :mod:`.metrics`).
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
from mpsbench.physics.config import STABILIZATION_RATES, FlowPhysics, Models, TimeStepping
from mpsbench.physics.particles import Box, Kind, Particles, block, tank
from mpsbench.run.estimate import RunEstimate, flow_dt, pairs_for, steps_for
from mpsbench.run.probes import Callback, LayerAverage
from mpsbench.run.protocol import Problem
from mpsbench.run.runner import run

from . import metrics as hm
from .metrics import RECOMMENDED
from .reference import RHO0, G

SAMPLE_EVERY = 0.01  # s
WALL_HEADROOM = 0.1  # m of tank wall above the column
WINDOW_FROM = 0.5  # the settled window is [WINDOW_FROM * T, T]

PARAMS = (
    Param("laplacian", "xu-jin", "Laplacian model (viscous term)", kind=str,
          choices=an.laplacian_names()),
    Param("weight", "wf2", "weighting function", kind=str, choices=an.weight_names()),
    Param("gradient", "pgm1", "pressure gradient model", kind=str, choices=an.gradient_names()),
    Param("re_ratio", 2.1, "r_e / l0 (number density, gradient, Laplacian, stabilization)",
          minimum=1.0, exclusive_minimum=True, maximum=6.0),
    Param("l0", 0.02, "particle spacing", unit="m", minimum=0.0, exclusive_minimum=True,
          maximum=0.05),
    Param("stabilization", True, "velocity stabilization (Xu & Jin 2016)", kind=bool),
    Param("alpha_s", 0.01, "stabilization coefficient", minimum=0.0, maximum=1.0),
    Param("stabilization_rate", "step", "what alpha_s is per: step (each time step, the "
          "paper's form) or acoustic (each acoustic step cfl l0 / c0: the damping of a WC-MPS "
          "run whatever the scheme's step)", kind=str, choices=STABILIZATION_RATES),
    Param("height", 0.3, "column height", unit="m", minimum=0.05, maximum=2.0),
    Param("width", 0.2, "column (and tank) width", unit="m", minimum=0.05, maximum=2.0),
    Param("end_time", 1.0, "simulated time", unit="s", minimum=0.05, maximum=20.0),
    Param("c0_factor", 10.0, "sound speed c0 = factor * sqrt(2 g H)", minimum=2.0,
          maximum=50.0),
    Param("cfl", 0.2, "dt = cfl l0 / (c0 + |u|max)", minimum=1e-3, maximum=1.0),
    Param("nu", 1e-6, "kinematic viscosity", unit="m^2/s", minimum=0.0, maximum=1e-2),
)
STAB_ONLY = ("alpha_s", "stabilization_rate")

# The recommended configuration (metrics.RECOMMENDED, the dam break's IWC-MPS: xu-jin +
# stabilization, WF2, PGM1, r_e = 2.1 l0) is the gated one; its floor-pressure error gets u_num
# from l0 = 0.04, 0.03, 0.02 m (ratios 1.33 and 1.5; the coarse levels cost a fifth of the
# 0.02 m run, a finer one would cost twice it: the quick tier's budget).  At 0.04 m the column
# is 8 rows (H = 0.32 m): every metric is relative to the simulated H.
REFINEMENT_L0 = (0.04, 0.03)

TIERS: dict[str, list[Grid]] = {
    # seconds: the recommended configuration with and without stabilization, coarse and short
    "smoke": [{"l0": [0.03], "end_time": [0.3], "stabilization": [True, False]}],
    # the rest against the melting at l0 = 0.02 m over 1 s, and the refinement set
    "quick": [
        {"l0": [0.02], "stabilization": [True, False]},
        RefinementGrid({k: [v] for k, v in RECOMMENDED.items()} | {"l0": list(REFINEMENT_L0)}),
    ],
    # every Laplacian and PGM, with and without stabilization, at 0.02 and 0.01 m over 2 s
    "paper": [
        {"laplacian": list(an.MODELS), "gradient": list(an.GRADIENT_MODELS),
         "stabilization": [True, False], "l0": [0.02, 0.01], "end_time": [2.0]},
        RefinementGrid({k: [v] for k, v in RECOMMENDED.items()}
                       | {"l0": [0.04, 0.03], "end_time": [2.0]}),
    ],
}

METRICS = {
    "column_height": "H, simulated column height ny l0 [m]",
    "floor_pressure_error": "p_fit(0) / (rho0 g H) - 1: the line through the time-averaged "
                            "layer pressures (layers below H - 3 l0, second half of the run) at "
                            "the floor [-]",
    "pressure_gradient_error": "-slope of that line / (rho0 g) - 1 [-]",
    "pressure_profile_error": "RMS over the layers of (p_k - rho0 g (H - y_k)) / (rho0 g H), "
                              "time-averaged layers, second half of the run [-]",
    "pressure_fluctuation": "standard deviation in time of the bottom layer's pressure over "
                            "the second half, / (rho0 g H) [-]",
    "rms_speed_late": "mean over the second half of the fluid's RMS speed [m/s]",
    "rms_speed_end": "RMS speed of the fluid at the end [m/s]",
    "rms_speed_late_ratio": "rms_speed_late / sqrt(2 g H) [-]",
    "settling_time": "first time from which the RMS speed stays below 1 % of sqrt(2 g H) "
                     "(empty: never) [s]",
    "surface_rise": "free surface at the end (mean of the nx highest particles + l0/2) "
                    "minus H [m]",
    "surface_rise_max": "highest fluid particle + l0/2 at the end minus H [m]",
    "particles_lost": "fluid particles whose centre is beyond a wall line at the end [-]",
}

COMPARE: dict[str, tuple[str, float]] = {
    "column_height": ("equal", 0.0),
    "floor_pressure_error": ("info", 0.0),  # signed; held through the gates
    "pressure_gradient_error": ("info", 0.0),
    "surface_rise": ("info", 0.0),
    "surface_rise_max": ("info", 0.0),
    "settling_time": ("info", 0.0),
    "rms_speed_late": ("lower", 0.10),
    "rms_speed_end": ("info", 0.0),
    "rms_speed_late_ratio": ("lower", 0.10),
    "pressure_fluctuation": ("lower", 0.10),
    "particles_lost": ("lower", 0.0),
}


def _counts(params: dict[str, Any]) -> tuple[int, int, float]:
    l0 = float(params["l0"])
    return max(2, round(params["width"] / l0)), max(2, round(params["height"] / l0)), l0


def build(params: dict[str, Any]) -> Problem:
    nx, ny, l0 = _counts(params)
    width, height = nx * l0, ny * l0
    column = block(0.0, 0.0, nx, ny, l0)
    walls = tank(width, height + WALL_HEADROOM, l0)
    margin = 10 * l0
    box = Box((-margin, -margin), (width + margin, height + WALL_HEADROOM + 0.5 * height))
    physics = FlowPhysics(rho0=RHO0, nu=params["nu"], gravity=(0.0, -G),
                          c0=params["c0_factor"] * hm.speed_scale(height),
                          stabilization=params["stabilization"], alpha_s=params["alpha_s"],
                          stabilization_rate=params["stabilization_rate"])
    models = Models(weight=params["weight"], laplacian=params["laplacian"],
                    gradient=params["gradient"], re_ratio=params["re_ratio"])
    return Problem(Particles.concat([column, walls]), box, l0, physics, models,
                   TimeStepping(cfl=params["cfl"]), name="hydrostatic")


class HydrostaticCase(Case):
    name = "hydrostatic"
    title = "Hydrostatic tank: a water column at rest under gravity (Adami et al. 2012)"
    order = 50
    description = (
        "A 0.2 m x 0.3 m water column released at rest in a tank of its width, under gravity.  "
        "It should stay at rest with p = rho0 g (H - y): RMS speed over time, settling, "
        "free-surface rise, particles lost, the layer pressure profile and the floor pressure "
        "against the hydrostatic law, with and without the velocity stabilization "
        "(docs/method.md 6 e)."
    )
    params = PARAMS
    tiers = TIERS
    metrics = METRICS
    compare = COMPARE
    headline = "floor_pressure_error_with_u_num"
    inactive_without = {"stabilization": STAB_ONLY}
    refinements = (Refinement("l0", ("floor_pressure_error", "rms_speed_late"), SPACE,
                              order=1.0),)

    def estimate(self, params: dict[str, Any]) -> RunEstimate:
        """Column and tank particles (four boundary layers), acoustic steps at |u| = 0."""
        nx, ny, l0 = _counts(params)
        walls_h = (ny * l0 + WALL_HEADROOM) / l0
        particles = nx * ny + 4 * (nx + 8) + 8 * int(walls_h + 1)
        c0 = params["c0_factor"] * hm.speed_scale(ny * l0)
        steps = steps_for(params["end_time"], flow_dt(l0, c0, 0.0, params["cfl"]))
        return RunEstimate(particles, pairs_for(particles, params["re_ratio"]), steps)

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        problem = build(params)
        nx, ny, l0 = _counts(params)
        width, height = nx * l0, ny * l0
        edges = l0 * np.arange(0, ny + 4)  # layers to 3 l0 above the column, for a risen surface

        def speed(s: Any) -> tuple[float, float]:
            st = s.state()
            f = st.kind == Kind.FLUID
            v2 = np.sum(st.vel[f] ** 2, axis=1)
            return float(np.sqrt(np.mean(v2))), hm.surface_height(st.pos[f, 1], nx, l0)

        motion = Callback("motion", speed, every=SAMPLE_EVERY)
        layers = LayerAverage("pressure", 1, list(edges), "pressure", every=SAMPLE_EVERY)
        res = run(solver, problem, end_time=float(params["end_time"]), probes=[motion, layers])
        metrics: dict[str, Any] = {k: math.nan for k in self.metrics}
        metrics["column_height"] = height
        t = np.asarray(motion.t, float)
        if not len(t):
            return CaseRun(metrics, [res])
        mot = np.asarray(motion.values, float)
        rms, surface = mot[:, 0], mot[:, 1]
        p_layers = np.asarray(layers.values, float)
        t_layers = np.asarray(layers.t, float)
        start = WINDOW_FROM * float(t[-1])
        centres = 0.5 * (edges[1:] + edges[:-1])
        p_mean = hm.window_mean(t_layers, p_layers, start)
        scale = RHO0 * G * height
        metrics.update(hm.pressure_metrics(centres, p_mean, height, l0, RHO0))
        late = t_layers >= start - 1e-12
        metrics["pressure_fluctuation"] = float(np.nanstd(p_layers[late, 0]) / scale)
        v_ref = hm.speed_scale(height)
        metrics["rms_speed_late"] = float(np.mean(rms[t >= start - 1e-12]))
        metrics["rms_speed_late_ratio"] = metrics["rms_speed_late"] / v_ref
        metrics["rms_speed_end"] = float(rms[-1])
        metrics["settling_time"] = hm.settling_time(t, rms, hm.SETTLE_FRACTION * v_ref)
        metrics["surface_rise"] = float(surface[-1] - height)
        final = res.final
        if final is not None:
            f = final.kind == Kind.FLUID
            metrics["surface_rise_max"] = float(final.pos[f, 1].max() + 0.5 * l0 - height)
            metrics["particles_lost"] = hm.lost_particles(final.pos[f], width)
        arrays = {"t": t, "rms_speed": rms, "surface": surface, "layer_y": centres,
                  "layer_p_mean": p_mean, "layer_t": t_layers, "bottom_p": p_layers[:, 0]}
        return CaseRun(metrics, [res], arrays)

    # ------------------------------------------------------------------ report
    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        from .analysis import gates

        return gates(self.model_records(records))

    def claims(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        from .analysis import claims

        return claims(self.model_records(records))

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


CASE = HydrostaticCase()
