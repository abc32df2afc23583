"""Decaying Taylor-Green vortex on a periodic square (docs/method.md 6 g).

Taylor & Green's (1937) single-mode vortex on [0, 1) x [0, 1) m, U = 1 m/s, rho0 = 1000
kg/m^3, nu = U L / Re (:mod:`.reference`): the exact flow keeps its shape and decays as
e^{b t}, b = -8 pi^2 nu / L^2, because the pressure exactly balances the convective term.  A
particle method has to get three things right together here, with no wall to hide behind: the
pressure gradient (it must produce that balance from a pressure built by the equation of
state), the Laplacian (the decay rate) and the particle arrangement (the square lattice is
stretched along the strain axes from the first step; how the disorder grows is what limits a
Lagrangian method here).

Set-up.  A square lattice of N x N fluid particles, N = L / l0, fills the doubly periodic
square; the particles start with the exact velocity at their positions.  Their pressure starts
at zero (the number density of the lattice is n0): a weakly compressible method has no way to
start from the exact pressure, so the run begins with the acoustic transient that builds it
(Mach number U / c0 = 0.1, period about L / c0).  Gravity is off, the equation of state linear
without clipping negative pressures (there is no free surface: the pressure oscillates around
a mean), c0 = 10 U, dt = ``cfl`` l0 / (c0 + |u|max) or the viscous limit.

Measured: every 1/50 of ``end_time`` the kinetic energy; at 0.1, 0.2, 0.5 and 1 times
``end_time`` the velocity error (:mod:`.metrics`); at the end the pressure error (shape, the
background removed), the number density's largest deviation from n0 and the nearest-neighbour
spread and minimum (disorder); over the run the total momentum (a symmetric pressure gradient
and Laplacian conserve it to round-off in a periodic box: the case's gate).
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
from mpsbench.physics.particles import Box, Kind, block
from mpsbench.run.estimate import (
    RunEstimate,
    flow_dt,
    lattice_laplacian_bound,
    pairs_for,
    steps_for,
)
from mpsbench.run.probes import Callback, Snapshot
from mpsbench.run.protocol import Problem
from mpsbench.run.runner import run

from ..paper import RE_RATIOS
from . import metrics as tm
from .metrics import C0, HEADLINE_N, RECOMMENDED, RHO, SIDE, SPEED, TIME_FRACTIONS

STAB_ONLY = ("alpha_s",)
SHIFT_ONLY = ("shifting_coefficient",)

PARAMS = (
    Param("laplacian", "xu-jin", "Laplacian model (viscous term)", kind=str,
          choices=an.laplacian_names()),
    Param("weight", "wf2", "weighting function", kind=str, choices=an.weight_names()),
    Param("gradient", "pgm1", "pressure gradient model", kind=str, choices=an.gradient_names()),
    Param("re_ratio", 3.1, "r_e / l0 (number density, gradient, Laplacian, stabilization)",
          minimum=1.0, exclusive_minimum=True, maximum=6.0),
    Param("l0", SIDE / HEADLINE_N, "particle spacing; L/l0 must be a whole number (L = 1 m)",
          unit="m", minimum=0.0, exclusive_minimum=True, maximum=SIDE / 8),
    Param("reynolds", 100.0, "Reynolds number U L / nu", minimum=1.0, maximum=1e5),
    Param("stabilization", False, "velocity stabilization (Xu & Jin 2016)", kind=bool),
    Param("alpha_s", 0.01, "stabilization coefficient", minimum=0.0, maximum=1.0),
    Param("shifting", False, "particle shifting after the move (docs/method.md 5b)", kind=bool),
    Param("shifting_coefficient", 1.0, "A of the shifting's D = A r_e max|u| dt", minimum=0.0,
          exclusive_minimum=True, maximum=10.0),
    Param("end_time", 1.0, "simulated time (Re = 100: E falls to 0.21 E0 by 1 s)", unit="s",
          minimum=0.01, maximum=20.0),
    Param("cfl", 0.2, "dt = cfl l0 / (c0 + |u|max)", minimum=1e-3, maximum=1.0),
)

# the recommended cell's refinement set: N = 20, 28 and the model grid's 40 (quick); N = 80 in
# the paper tier (4x the particles and 2x the steps of N = 40: 20 s, a third of the case's
# quick-tier budget); the same with particle shifting (docs/method.md 5b).  Every N is a
# multiple of 4, so that the lattice sits the same way in the flow at every level: with N = 2
# (mod 4) a particle sits on each vortex centre, and those lattices melt earlier and lose more
# of the vortex (docs/method.md 6g: 73 % error at T at N = 30 against 29-35 % at N = 28 and 32)
REFINE: Grid = RefinementGrid({k: [v] for k, v in RECOMMENDED.items()}
                              | {"l0": [SIDE / 20, SIDE / 28]})
REFINE_SHIFTED: Grid = REFINE | {"shifting": [True]}
REFINE_PAPER: Grid = RefinementGrid({k: [v] for k, v in RECOMMENDED.items()}
                                    | {"l0": [SIDE / 20, SIDE / 80]})

TIERS: dict[str, list[Grid]] = {
    # seconds: N = 20 over 0.5 s, the recommended cell with and without stabilization, with
    # shifting, and the momentum-conserving gradients (the gate)
    "smoke": [{"l0": [SIDE / 20], "end_time": [0.5], "stabilization": [False, True]},
              {"l0": [SIDE / 20], "end_time": [0.5], "shifting": [True]},
              {"l0": [SIDE / 20], "end_time": [0.5], "gradient": ["pgm2", "pgm3"]}],
    # at N = 40 (Re = 100, 1 s): every Laplacian, the recommended cell with stabilization (the
    # claims' pair) and with shifting, PGM2 and PGM3 (the gate); the refinement sets N = 20,
    # 28, 40 without and with shifting
    "quick": [
        {"laplacian": list(an.MODELS)},
        {"stabilization": [True]},
        {"shifting": [True]},
        {"gradient": ["pgm2", "pgm3"]},
        REFINE,
        REFINE_SHIFTED,
    ],
    # both Reynolds numbers, both weighting functions, every gradient with and without
    # stabilization at N = 20 and 40; every model with shifting at N = 40 and the shifting
    # coefficient; the refinement sets N = 20, 40, 80 without and with shifting
    "paper": [
        {"laplacian": list(an.MODELS), "weight": list(an.WFS),
         "gradient": list(an.GRADIENT_MODELS), "stabilization": [False, True],
         "reynolds": [100.0, 1000.0], "l0": [SIDE / 20, SIDE / 40]},
        {"laplacian": list(an.MODELS), "gradient": list(an.GRADIENT_MODELS),
         "shifting": [True], "reynolds": [100.0, 1000.0]},
        {"shifting": [True], "shifting_coefficient": [0.5, 1.0, 2.0, 4.0],
         "l0": [SIDE / 20, SIDE / 40]},
        REFINE_PAPER | {"reynolds": [100.0, 1000.0], "stabilization": [False, True],
                        "shifting": [False, True]},
        # the interaction radius: the lattice-strain pressure falls with it (docs/method.md 6g)
        {"re_ratio": list(RE_RATIOS), "l0": [SIDE / 20, SIDE / 40]},
    ],
}

METRICS = {
    "velocity_error": "relative L2 velocity error at end_time, ||u - u_exact|| / ||u_exact|| "
                      "at the particles (-)",
    **{tm.time_key(f): f"relative L2 velocity error at {f:g} x end_time (-)"
       for f in TIME_FRACTIONS if f < 1.0},
    "energy_error": "E / E_exact - 1 at end_time, fluid kinetic energy (-)",
    "decay_rate_error": "b_fit / b - 1, b_fit from the kinetic-energy samples (-)",
    "pressure_error": "||(p - mean p) - p_exact|| / ||p_exact|| at end_time (-)",
    "number_density_deviation": "max |n_i / n0 - 1| at end_time (-)",
    "surface_flagged": "share of the particles whose number density is below beta n0 at "
                       "end_time (flagged as free surface; there is none) (-)",
    "disorder": "standard deviation of the nearest-neighbour distance / l0 at end_time (-)",
    "min_spacing": "smallest nearest-neighbour distance / l0 at end_time (-)",
    "momentum_drift": "max over the run of |sum u| / (N_particles U) (-)",
    "n_side": "particles along a side, L / l0 (-)",
}

COMPARE: dict[str, tuple[str, float]] = {
    "energy_error": ("info", 0.0),  # signed
    "decay_rate_error": ("info", 0.0),
    "min_spacing": ("info", 0.0),
    "momentum_drift": ("info", 0.0),  # held by the gate
    "surface_flagged": ("info", 0.0),
    "n_side": ("equal", 0.0),
}


def side_count(params: dict[str, Any]) -> int:
    n = round(SIDE / float(params["l0"]))
    if n < 8 or abs(n * float(params["l0"]) - SIDE) > 1e-9 * SIDE:
        raise ConfigError(f"parameter l0 = {params['l0']!r} is not allowed: L/N = {SIDE:g}/N m "
                          "for a whole number N >= 8")
    return n


def build(params: dict[str, Any]) -> Problem:
    n = side_count(params)
    l0 = SIDE / n
    tg = tm.flow(float(params["reynolds"]))
    p = block(0.0, 0.0, n, n, l0)
    u, v = tg.velocity(p.pos[:, 0], p.pos[:, 1], 0.0)
    p.vel[:, 0], p.vel[:, 1] = u, v
    physics = FlowPhysics(rho0=RHO, nu=tg.nu, gravity=(0.0, 0.0), c0=C0, eos="linear",
                          clip_negative_pressure=False, stabilization=params["stabilization"],
                          alpha_s=params["alpha_s"], shifting=params["shifting"],
                          shifting_coefficient=params["shifting_coefficient"])
    models = Models(weight=params["weight"], laplacian=params["laplacian"],
                    gradient=params["gradient"], re_ratio=params["re_ratio"])
    box = Box((0.0, 0.0), (SIDE, SIDE), (True, True))
    return Problem(p, box, l0, physics, models, TimeStepping(cfl=params["cfl"]),
                   name="taylor-green")


class TaylorGreenCase(Case):
    name = "taylor-green"
    title = "Taylor-Green vortex (periodic, decaying) against the exact solution"
    order = 70
    description = (
        "The decaying 2-D Taylor-Green vortex on a doubly periodic unit square, U = 1 m/s, "
        "Re = 100 (and 1000 in the paper tier), from the square lattice with the exact "
        "velocity and zero pressure: velocity error against the exact field at 0.1-1 x T, "
        "kinetic energy against e^{2 b t}, the pressure's shape, number density and particle "
        "disorder at the end, total momentum, observed order in l0, without and with particle "
        "shifting (docs/method.md 6 g, 5b)."
    )
    params = PARAMS
    tiers = TIERS
    metrics = METRICS
    compare = COMPARE
    headline = f"velocity_error_with_u_num_N-{HEADLINE_N}"
    # u_num of the velocity errors in l0 at fixed cfl (dt falls with l0); order 2 assumed with
    # two levels (a consistent gradient and Laplacian on the lattice)
    inactive_without = {"stabilization": STAB_ONLY, "shifting": SHIFT_ONLY}
    refinements = (Refinement("l0", ("velocity_error", *(tm.time_key(f) for f in TIME_FRACTIONS
                                                         if f < 1.0)), SPACE, order=2.0),)

    def estimate(self, params: dict[str, Any]) -> RunEstimate:
        """N^2 fluid particles; steps at the acoustic or the viscous limit on the lattice."""
        n = side_count(params)
        l0, re = SIDE / n, float(params["re_ratio"])
        nu = SPEED * SIDE / float(params["reynolds"])
        rho = lattice_laplacian_bound(params["weight"], params["laplacian"], re) / l0**2
        dt = flow_dt(l0, C0, SPEED, params["cfl"], nu, 0.5, rho)
        return RunEstimate(n * n, pairs_for(n * n, re), steps_for(params["end_time"], dt))

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        problem = build(params)
        n = side_count(params)
        l0, end = SIDE / n, float(params["end_time"])
        tg = tm.flow(float(params["reynolds"]))
        times = tm.error_times(end)

        def sample(s: Any) -> tuple[float, float]:
            st = s.state()
            f = st.kind == Kind.FLUID
            moment = np.abs(st.vel[f].sum(axis=0)).max() / (f.sum() * SPEED)
            return tm.energy_ratio(tg, st.vel[f], float(s.time)), float(moment)

        energy = Callback("energy", sample, every=end / tm.ENERGY_SAMPLES)
        snaps = Snapshot("snapshots", with_diagnostics=True, at=[0.0, *times])
        res = run(solver, problem, end_time=end, probes=[energy, snaps])
        metrics: dict[str, Any] = {k: math.nan for k in self.metrics}
        metrics["n_side"] = n
        t_e = np.asarray(energy.t, float)
        values = np.asarray(energy.values, float).reshape(-1, 2)
        arrays: dict[str, np.ndarray] = {"t": t_e, "energy_ratio": values[:, 0]}
        if len(t_e):
            metrics["momentum_drift"] = float(values[:, 1].max())
        errors = []
        for t, st in zip(snaps.t[1:], snaps.values[1:], strict=False):
            f = st.kind == Kind.FLUID
            errors.append((t, tm.velocity_error(tg, st.pos[f], st.vel[f], t)))
        for frac, (_, err) in zip(TIME_FRACTIONS, errors, strict=False):
            metrics["velocity_error" if frac == 1.0 else tm.time_key(frac)] = err
        if errors:
            arrays["error_t"] = np.asarray([e[0] for e in errors])
            arrays["velocity_error"] = np.asarray([e[1] for e in errors])
        if not res.ok or len(snaps.values) != len(times) + 1:
            return CaseRun(metrics, [res], arrays)
        first, last = snaps.values[0], snaps.values[-1]
        f = last.kind == Kind.FLUID
        metrics["energy_error"] = float(values[-1, 0] - 1.0)
        metrics["decay_rate_error"] = tm.decay_rate_error(t_e, values[:, 0], tg)
        metrics["pressure_error"] = tm.pressure_error(tg, last.pos[f], last.pressure[f], end)
        n_end = last.fields.get("number_density")
        n_start = first.fields.get("number_density")
        if n_end is not None and n_start is not None:
            ratio = n_end[f] / float(np.mean(n_start[f]))
            metrics["number_density_deviation"] = float(np.max(np.abs(ratio - 1.0)))
            beta = problem.physics.surface_beta  # type: ignore[union-attr]
            metrics["surface_flagged"] = float(np.mean(ratio < beta))
        metrics["disorder"], metrics["min_spacing"] = tm.disorder(last.pos[f], l0)
        arrays.update(x=last.pos[f, 0], y=last.pos[f, 1],
                      speed=np.hypot(last.vel[f, 0], last.vel[f, 1]))
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


CASE = TaylorGreenCase()
