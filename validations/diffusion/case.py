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
import pandas as pd

from mpsbench.cases import Case, CaseCheck, CaseRun, Grid, Param
from mpsbench.errors import ConfigError
from mpsbench.physics.config import DiffusionPhysics, Models, TimeStepping
from mpsbench.physics.particles import Box, jitter, lattice_in_box
from mpsbench.run.estimate import RunEstimate, diffusion_dt_limit, pairs_for, steps_for
from mpsbench.run.protocol import Problem
from mpsbench.run.runner import run

from .. import _common as cm

KAPPA = math.log(2.0) / (8.0 * math.pi**2)  # m^2/s
END_TIME = 1.0  # s: exp(-8 pi^2 KAPPA END_TIME) = 0.5
EXACT_RATE = 8.0 * math.pi**2 * KAPPA  # 1/s (= ln 2)
FIELD = "phi"

ALL_L0 = (1 / 20, 1 / 40, 1 / 80)
ALL_JITTER = (0.0, 0.05, 0.1)

# Tolerances that decide pass or fail (docs/method.md section 3; issue 4 acceptance).
LATTICE_L0 = 1 / 40
ACCURATE_MODELS = ("xu-jin", "koshizuka-oka")
ACCURATE_MAX_L2 = 0.02  # xu-jin and koshizuka-oka on the lattice at l0 = 1/40: below 2 %
OVERDIFFUSING_MODEL = "khayyer-gotoh"
OVERDIFFUSING_MIN_L2 = 0.30  # khayyer-gotoh over-diffuses two- to three-fold: above 30 %
MIN_LATTICE_ORDER = 1.8  # xu-jin and koshizuka-oka are second order on the lattice
MAX_TIME_ERROR_SHARE = 0.1  # forward Euler error below 10 % of the smallest spatial error


def _full(**extra: list[Any]) -> Grid:
    return {"laplacian": list(cm.MODELS), "weight": list(cm.WFS), "re_ratio": list(cm.RE_RATIOS),
            **extra}


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
        Param("laplacian", "xu-jin", "Laplacian model", kind=str, choices=cm.laplacian_names()),
        Param("weight", "wf2", "weighting function", kind=str, choices=cm.weight_names()),
        Param("re_ratio", 3.1, "r_e / l0 of the Laplacian (and number density)",
              minimum=1.0, exclusive_minimum=True, maximum=8.0),
        Param("l0", 1 / 40, "particle spacing; 1/l0 must be a whole number", unit="m",
              minimum=0.0, exclusive_minimum=True, maximum=0.125),
        Param("jitter", 0.0, "uniform random displacement amplitude", unit="l0",
              minimum=0.0, maximum=0.3),
        Param("seed", 1, "seed of the jitter", kind=int, minimum=0),
        Param("dt", 1e-4, "fixed time step", unit="s", minimum=0.0, exclusive_minimum=True,
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
            {"laplacian": list(cm.MODELS), "weight": list(cm.WFS), "re_ratio": [3.1],
             "l0": [1 / 20, 1 / 40], "jitter": [0.1]},
        ],
        # the whole grid of docs/method.md 6 a, every run with its dt-halving check
        "paper": [_full(l0=list(ALL_L0), jitter=list(ALL_JITTER), dt_check=[True])],
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
    headline = "l2_error_l0-1_40_jitter-0"

    # ------------------------------------------------------------------ running
    def build(self, params: dict[str, Any]) -> Problem:
        """The problem for one parameter set (the particles carry phi0 in ``fields['phi']``)."""
        l0 = float(params["l0"])
        n = round(1.0 / l0)
        if abs(n * l0 - 1.0) > 1e-9:
            raise ConfigError(f"parameter l0 = {l0!r} is not allowed: 1/N for a whole number N")
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
        n = round(1.0 / float(params["l0"]))
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

    # ------------------------------------------------------------------ checks
    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        df = cm.completed(records)
        out = []
        lat = _select(df, jitter=0.0, l0=LATTICE_L0)
        acc = lat[lat["laplacian"].isin(ACCURATE_MODELS)] if not lat.empty else lat
        out.append(_bound_check(
            f"xu-jin and koshizuka-oka below {ACCURATE_MAX_L2:.0%} on the lattice at l0 = 1/40",
            acc, "l2_error", upper=ACCURATE_MAX_L2))
        kg = lat[lat["laplacian"] == OVERDIFFUSING_MODEL] if not lat.empty else lat
        out.append(_bound_check(
            f"khayyer-gotoh above {OVERDIFFUSING_MIN_L2:.0%} on the lattice at l0 = 1/40 "
            "(it over-diffuses)", kg, "l2_error", lower=OVERDIFFUSING_MIN_L2))
        out.append(self._order_check(df))
        out.append(self._time_check(df))
        return out

    def _order_check(self, df: pd.DataFrame) -> CaseCheck:
        name = (f"xu-jin and koshizuka-oka converge at second order on the lattice "
                f"(observed order >= {MIN_LATTICE_ORDER})")
        orders = convergence_table(df)
        if orders.empty:
            return CaseCheck(name, None, "needs two or more l0 on the lattice")
        sel = orders[(orders["jitter"] == 0) & orders["model"].isin(ACCURATE_MODELS)]
        if sel.empty:
            return CaseCheck(name, None, "needs two or more l0 on the lattice")
        worst = cm.row_min(sel, "observed_order")
        ok = bool((sel["observed_order"] >= MIN_LATTICE_ORDER).all())
        return CaseCheck(name, ok, f"{len(sel)} groups, lowest order "
                           f"{worst['observed_order']:.2f} ({worst['model']}, {worst['weight']}, "
                           f"r_e/l0 = {worst['re_ratio']:g})")

    def _time_check(self, df: pd.DataFrame) -> CaseCheck:
        name = (f"time-stepping error (2 x dt-halving change) below "
                f"{MAX_TIME_ERROR_SHARE:.0%} of the smallest spatial error of its group")
        table = time_table(df)
        if table.empty:
            return CaseCheck(name, None, "no run with dt_check")
        worst = cm.row_max(table, "time_error_share")
        ok = bool((table["time_error_share"] < MAX_TIME_ERROR_SHARE).all())
        return CaseCheck(name, ok, f"{len(table)} groups; worst share "
                           f"{worst['time_error_share']:.2%} ({worst['model']}, "
                           f"{worst['weight']}, r_e/l0 = {worst['re_ratio']:g}, jitter "
                           f"{worst['jitter']:g}: time error {worst['time_error']:.2e} vs "
                           f"spatial {worst['smallest_l2_error']:.2e})")

    # ------------------------------------------------------------------ tables
    def tables(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        df = cm.completed(records)
        if df.empty:
            return {}
        out: dict[str, Any] = {}
        for (l0, jit), group in _resolution_groups(df):
            out[f"l2_error_l0-1_{round(1 / l0)}_jitter-{jit:g}"] = cm.pivot(group, "l2_error")
        finest = df["l0"].min()
        for jit in sorted(df["jitter"].unique()):
            group = _select(df, jitter=jit, l0=finest)
            out[f"decay_ratio_l0-1_{round(1 / finest)}_jitter-{jit:g}"] = cm.pivot(
                group, "decay_ratio")
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
        df = cm.completed(records)
        if df.empty:
            return []
        out: list[Path | None] = [
            _fig_error_vs_re(df, l0, outdir) for l0 in sorted(df["l0"].unique(), reverse=True)]
        out += [_fig_convergence(df, jit, outdir) for jit in sorted(df["jitter"].unique())
                if df[df["jitter"] == jit]["l0"].nunique() > 1]
        out.append(_fig_decay_ratio(df, outdir))
        out.append(_fig_error_maps(df, arrays, outdir))
        return [p for p in out if p is not None]

    # ------------------------------------------------------------------ findings
    def findings(self, records: list[dict[str, Any]]) -> str:
        df = cm.completed(records)
        if df.empty:
            return "No run completed."
        lines = []
        for (l0, jit), group in _resolution_groups(df):
            lines.append(_summary_line(group, l0, jit))
        head = _select(df, jitter=0.0, l0=_headline_l0(df))
        line = cm.weight_ratio_line(head, "l2_error",
                                    f"l0 = {cm.fraction(_headline_l0(df))}, regular lattice")
        if line:
            lines.append(line)
        lines += _convergence_lines(convergence_table(df))
        tt = time_table(df)
        if not tt.empty:
            worst = tt["time_error_share"].max()
            verdict = ("the errors above are spatial" if worst < MAX_TIME_ERROR_SHARE else
                       "the time-stepping error is NOT negligible everywhere: use a smaller dt")
            lines.append(
                f"- **Time stepping**: halving dt (= {tt['dt'].max():g} s) moves the end field by "
                f"at most {tt['dt_halving_change'].max():.2e} (forward Euler's error is about "
                f"twice that), at most {worst:.1%} of the smallest spatial error of the same "
                f"model, WF, radius and jitter: {verdict}.")
        return "\n".join(lines)


# ---------------------------------------------------------------------- analysis helpers
def phi0(pos: np.ndarray) -> np.ndarray:
    return np.sin(2 * np.pi * pos[:, 0]) * np.sin(2 * np.pi * pos[:, 1])


def field_errors(
    phi: np.ndarray, exact: np.ndarray, start: np.ndarray, t: float
) -> dict[str, float]:
    """Relative L2 / Linf errors and the decay-rate ratio of an end field."""
    amplitude = float(phi @ start / (start @ start))
    rate = -math.log(amplitude) / t if amplitude > 0 else math.inf
    return {
        "l2_error": float(np.linalg.norm(phi - exact) / np.linalg.norm(exact)),
        "linf_error": float(np.max(np.abs(phi - exact)) / np.max(np.abs(exact))),
        "decay_ratio": rate / EXACT_RATE,
    }


def _select(df: pd.DataFrame, **eq: float) -> pd.DataFrame:
    """Rows whose float columns equal the given values (to rounding)."""
    if df.empty:
        return df
    mask = np.ones(len(df), dtype=bool)
    for col, val in eq.items():
        mask &= np.isclose(df[col].to_numpy(float), val, rtol=1e-9, atol=1e-15)
    return df[mask]


def _headline_l0(df: pd.DataFrame) -> float:
    """l0 = 1/40 when the study has it, else the finest."""
    values = sorted(df["l0"].unique())
    near = [h for h in values if abs(h - LATTICE_L0) < 1e-12]
    return float(near[0] if near else values[0])


def _resolution_groups(df: pd.DataFrame) -> list[tuple[tuple[float, float], pd.DataFrame]]:
    out = []
    for _, group in df.groupby(["l0", "jitter"]):
        l0, jit = float(group["l0"].iloc[0]), float(group["jitter"].iloc[0])
        out.append(((l0, jit), group))
    # jitter first, then coarse to fine
    return sorted(out, key=lambda item: (item[0][1], -item[0][0]))


def _bound_check(name: str, sel: pd.DataFrame, col: str, upper: float | None = None,
                 lower: float | None = None) -> CaseCheck:
    if sel.empty:
        return CaseCheck(name, None, "no such runs in this study")
    vals = sel[col].to_numpy(float)
    if upper is not None:
        bad = sel[vals >= upper]
        ext = cm.row_max(sel, col)
    else:
        bad = sel[vals <= lower]
        ext = cm.row_min(sel, col)
    what = "largest" if upper is not None else "smallest"
    detail = (f"{len(sel)} runs; {what} {ext[col]:.3%} ({ext['laplacian']}, {ext['weight']}, "
              f"r_e/l0 = {ext['re_ratio']:g})")
    if not bad.empty:
        detail += "; out of bounds: " + ", ".join(
            f"{r.laplacian}/{r.weight}/{r.re_ratio:g} = {getattr(r, col):.3%}"
            for r in bad.itertuples())
    return CaseCheck(name, bad.empty, detail)


def convergence_table(df: pd.DataFrame) -> pd.DataFrame:
    """Observed order in l0 per (model, WF, r_e/l0, jitter) (convergence.csv)."""
    keys = ["solver"] if cm.several_solvers(df) else []
    keys += ["laplacian", "weight", "re_ratio", "jitter"]
    if df.empty:
        return pd.DataFrame()
    t = cm.observed_orders(df, "l2_error", keys)
    if t.empty:
        return t
    t = cm.sort_models(t, ["jitter", "re_ratio"]).rename(columns={"laplacian": "model"})
    lead = [c for c in ("solver", "model", "weight", "re_ratio", "jitter", "observed_order")
            if c in t.columns]
    return t[lead + [c for c in t.columns if c not in lead]].reset_index(drop=True)


def time_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per group with a dt check: time error estimate against the group's smallest error."""
    if df.empty or "dt_halving_change" not in df or df["dt_halving_change"].notna().sum() == 0:
        return pd.DataFrame()
    keys = (["solver"] if cm.several_solvers(df) else []) + [
        "laplacian", "weight", "re_ratio", "jitter"]
    rows = []
    for key, g in df.groupby(keys, sort=False):
        checked = g[g["dt_halving_change"].notna()]
        if checked.empty:
            continue
        change = float(checked["dt_halving_change"].max())
        smallest = float(g["l2_error"].min())
        rows.append([*key, float(checked["dt"].max()), change, 2.0 * change, smallest,
                     float(cm.row_min(g, "l2_error")["l0"]),
                     2.0 * change / smallest if smallest > 0 else math.inf])
    cols = [*keys, "dt", "dt_halving_change", "time_error", "smallest_l2_error", "at_l0",
            "time_error_share"]
    t = cm.sort_models(pd.DataFrame(rows, columns=cols), ["jitter", "re_ratio"])
    return t.rename(columns={"laplacian": "model"}).reset_index(drop=True)


def _summary_line(group: pd.DataFrame, l0: float, jit: float) -> str:
    where = f"l0 = {cm.fraction(l0)}, " + ("regular lattice" if jit == 0 else f"jitter {jit:g} l0")
    parts = []
    for model in sorted(group["laplacian"].unique(), key=cm.model_sort_key):
        g = group[group["laplacian"] == model]
        err = cm.span(g["l2_error"], cm.pct)
        rate = cm.span(g["decay_ratio"], lambda v: f"{v:.3f}")
        parts.append(f"{model} {err} (decay ratio {rate})")
    best = cm.row_min(group, "l2_error")
    wins = _wins(group)
    text = (f"- **{where}**: best {best['laplacian']} / {best['weight']} at r_e/l0 = "
            f"{best['re_ratio']:g} ({cm.pct(best['l2_error'], 3)}).  Error range per model: "
            + "; ".join(parts) + ".")
    if wins:
        text += f"  Smallest error per (WF, r_e/l0) cell: {wins}."
    return text


def _wins(group: pd.DataFrame) -> str:
    cells = group.groupby(["weight", "re_ratio"])
    if cells.ngroups < 2 or group["laplacian"].nunique() < 2:
        return ""
    winners = [str(cm.row_min(g, "l2_error")["laplacian"]) for _, g in cells]
    counts = pd.Series(winners).value_counts()
    return ", ".join(f"{m} in {n} of {len(winners)}" for m, n in counts.items())


def _convergence_lines(conv: pd.DataFrame) -> list[str]:
    if conv.empty:
        return []
    lines = []
    for jit in sorted(conv["jitter"].unique()):
        c = conv[conv["jitter"] == jit]
        parts = []
        for model in sorted(c["model"].unique(), key=cm.model_sort_key):
            o = c[c["model"] == model]["observed_order"]
            parts.append(f"{model} {cm.span(o, lambda v: f'{v:.2f}', ' to ')}")
        where = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
        note = ""
        if jit == 0:
            note = ("  Orders near zero belong to models that converge to a wrong decay rate "
                    "(khayyer-gotoh and xu-jin-analytic: an O(1) factor on the lattice, "
                    "docs/method.md section 3).")
        else:
            note = ("  On an irregular cloud the MPS Laplacians lose their second-order "
                    "consistency, so the orders fall below the lattice's; a model with an O(1) "
                    "rate error stays near zero.")
        lines.append(f"- **Observed order in l0, {where}**: " + "; ".join(parts) + "." + note)
    return lines


# ---------------------------------------------------------------------- figures
def _fig_error_vs_re(df: pd.DataFrame, l0: float, outdir: Path) -> Path:
    sub = df[np.isclose(df["l0"], l0)]
    jitters = sorted(sub["jitter"].unique())
    fig, axes = cm.figure(len(jitters), 2, width=5.2)
    for row, jit in enumerate(jitters):
        g = sub[sub["jitter"] == jit]
        where = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
        cm.plot_vs_re(axes[row, 0], g, "l2_error")
        axes[row, 0].set_ylabel("relative L2 error at t_end")
        axes[row, 0].set_title(f"L2 error, l0 = {cm.fraction(l0)}, {where}")
        cm.plot_vs_re(axes[row, 1], g, "linf_error")
        axes[row, 1].set_ylabel("relative Linf error at t_end")
        axes[row, 1].set_title(f"Linf error, l0 = {cm.fraction(l0)}, {where}")
    axes[0, 1].legend(fontsize=7, loc="best")
    fig.suptitle("Diffusion: error against r_e/l0 per model and WF")
    return cm.save(fig, outdir / f"error_vs_re_l0-1_{round(1 / l0)}.png")


def _fig_convergence(df: pd.DataFrame, jit: float, outdir: Path) -> Path:
    sub = df[df["jitter"] == jit]
    where = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
    return cm.convergence_figure(
        sub, "l2_error", convergence_table(sub),
        f"Diffusion: relative L2 error at t_end against l0 ({where}); legend: observed order "
        "between the two finest l0", outdir / f"convergence_jitter-{jit:g}.png", slope=2.0)


def _fig_decay_ratio(df: pd.DataFrame, outdir: Path) -> Path:
    finest = df["l0"].min()
    jitters = sorted(df["jitter"].unique())
    fig, axes = cm.figure(1, len(jitters), width=5.0)
    for col, jit in enumerate(jitters):
        ax = axes[0, col]
        cm.plot_vs_re(ax, _select(df, jitter=jit, l0=finest), "decay_ratio", log=False)
        ax.axhline(1.0, color="k", lw=0.8)
        where = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
        ax.set_title(f"l0 = {cm.fraction(finest)}, {where}")
        ax.set_ylabel("decay rate / exact rate")
    axes[0, -1].legend(fontsize=7, loc="upper right")
    fig.suptitle("Diffusion: measured decay rate over the exact rate 8 pi^2 kappa (1 = exact)")
    return cm.save(fig, outdir / "decay_ratio.png")


def _fig_error_maps(
    df: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path
) -> Path | None:
    """phi - phi_exact over the square for each model: WF2, r_e/l0 = 3.1 (or the nearest),
    l0 = 1/40 (or the nearest), on the lattice and at the largest jitter."""
    weight = "wf2" if "wf2" in set(df["weight"]) else df["weight"].iloc[0]
    sub = df[df["weight"] == weight]
    re = min(sub["re_ratio"].unique(), key=lambda r: abs(r - 3.1))
    sub = sub[sub["re_ratio"] == re]
    l0 = min(sub["l0"].unique(), key=lambda h: abs(math.log(h * 40)))
    sub = sub[np.isclose(sub["l0"], l0)]
    jitters = sorted({min(sub["jitter"]), max(sub["jitter"])})
    models = sorted(sub["laplacian"].unique(), key=cm.model_sort_key)
    if not models:
        return None
    fig, axes = cm.figure(len(jitters), len(models), width=3.6, height=3.3)
    for row, jit in enumerate(jitters):
        for col, model in enumerate(models):
            ax = axes[row, col]
            g = sub[(sub["jitter"] == jit) & (sub["laplacian"] == model)]
            data = arrays(str(g["run_id"].iloc[0])) if len(g) else {}
            if "error" not in data:
                ax.set_axis_off()
                continue
            err = data["error"]
            lim = float(np.max(np.abs(err))) or 1.0
            sc = ax.scatter(data["x"], data["y"], c=err, s=4, cmap="RdBu_r", vmin=-lim, vmax=lim)
            fig.colorbar(sc, ax=ax, shrink=0.85)
            where = "lattice" if jit == 0 else f"jitter {jit:g}"
            ax.set_title(f"{model}, {where}\nL2 {cm.pct(g['l2_error'].iloc[0])}", fontsize=9)
            ax.set_aspect("equal")
            ax.set_xticks([0, 0.5, 1])
            ax.set_yticks([0, 0.5, 1])
    fig.suptitle(f"Diffusion: (phi - phi_exact) / max|phi_exact| at t_end; {weight}, "
                 f"r_e/l0 = {re:g}, l0 = {cm.fraction(l0)} (colour scale per panel)")
    return cm.save(fig, outdir / "error_maps.png")


CASE = DiffusionCase()
