"""Couette: gates, claims, tables and findings from the run records (docs/method.md 6b, 8).

Gates (unchanged tolerances; L/40, t = 0.1125 s, prescribed on-plate walls): ``xu-jin`` / WF2 /
r_e = 3.1 l0 below 1 %; ``khayyer-gotoh`` and ``xu-jin-analytic`` above 5 % for every WF at
r_e = 2.1 l0 (their diffusion-rate error); L/20 -> L/40 reduces the ``xu-jin`` and
``koshizuka-oka`` errors at least 1.5-fold.

Claims: C2 (LM3 below LM1 and LM2 in every cell), C3 (the WF hardly matters for LM3) and the
viscous half of C8 (LM2's Couette error).  They compare the errors the runs computed at L/40,
which are exact for that spacing; the u_num beside them says how far each is from its
grid-converged value.

The tables and comparisons across models use the model records (``Case.model_records``); the
refinement runs of the headline cell (L/80, c_nu / 2, c_nu / 4) feed its u_num.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import CaseCheck
from mpsbench.cases import analysis as an
from mpsbench.cases.checks import above, below, decide
from mpsbench.cases.refinement import NumericalUncertainty

from ..paper import C2, C3, C8, LM1, LM2, LM3
from .metrics import END_TIME, L

# Gate tolerances (docs/method.md 6b; default wall treatment, L/40)
HEADLINE_N = 40
BEST_MODEL, BEST_WEIGHT, BEST_RE, BEST_MAX_L2 = "xu-jin", "wf2", 3.1, 0.01
RATE_MODELS, RATE_RE, RATE_MIN_L2 = ("khayyer-gotoh", "xu-jin-analytic"), 2.1, 0.05
CONVERGING_MODELS, MIN_REDUCTION = ("xu-jin", "koshizuka-oka"), 1.5
# Claim rules (docs/method.md section 8)
C3_BAND = (0.8, 1.25)  # WF1/WF2 error ratio of LM3 that counts as "insignificant"
C8_MIN_L2 = 0.05  # LM2's error at L/40 in every cell (the gate's diffusion-rate threshold)


def _pct(v: float) -> str:
    return f"{100 * v:.3g}%"


def grid(df: pd.DataFrame) -> pd.DataFrame:
    """The runs at the largest (the tiers' common) c_nu, with ``n`` = L / l0 (the tiers'
    refinement runs are not in the model records at all)."""
    df = _with_n(df)
    if df.empty or "c_nu" not in df:
        return df
    return an.select(df, c_nu=df["c_nu"].max())


def headline(df: pd.DataFrame) -> pd.DataFrame:
    """The default walls at L/40 of the model grid."""
    d = _default_walls(grid(df))
    return d[d["n"] == HEADLINE_N] if not d.empty else d


# ---------------------------------------------------------------------- gates
def gates(records: list[dict[str, Any]]) -> list[CaseCheck]:
    head = headline(an.completed(records))
    where = f"L/{HEADLINE_N}, t = {END_TIME:g} s, prescribed walls"
    return [
        an.Bound(f"{BEST_MODEL} / {BEST_WEIGHT} at r_e/l0 = {BEST_RE:g} below "
                 f"{BEST_MAX_L2:.0%} ({where})", "l2_error",
                 {"laplacian": BEST_MODEL, "weight": BEST_WEIGHT, "re_ratio": BEST_RE},
                 upper=BEST_MAX_L2, fmt=an.pct).check(head),
        an.Bound(f"{' and '.join(RATE_MODELS)} above {RATE_MIN_L2:.0%} for every WF at r_e/l0 "
                 f"= {RATE_RE:g} (diffusion-rate error; L/{HEADLINE_N}, prescribed walls)",
                 "l2_error", {"laplacian": RATE_MODELS, "re_ratio": RATE_RE},
                 lower=RATE_MIN_L2, fmt=an.pct).check(head),
        _reduction_gate(_default_walls(grid(an.completed(records)))),
    ]


# ---------------------------------------------------------------------- claims
def claims(records: list[dict[str, Any]], unc: NumericalUncertainty) -> list[CaseCheck]:
    head = headline(an.completed(records))
    return [_c2(head, unc), _c3(head), _c8(head)]


def _cells(head: pd.DataFrame, model: str) -> dict[tuple[str, float], dict[str, Any]]:
    return {(str(r["weight"]), float(r["re_ratio"])): r
            for r in an.rows(an.select(head, laplacian=model))}


def _c2(head: pd.DataFrame, unc: NumericalUncertainty) -> CaseCheck:
    rule = (f"at L/{HEADLINE_N} (prescribed on-plate walls, t = {END_TIME:g} s), {LM3}'s "
            f"error is below both {LM1}'s and {LM2}'s in every (WF, r_e/l0) cell (the computed "
            "errors at that spacing)")
    lm3, lm1, lm2 = (_cells(head, m) for m in (LM3, LM1, LM2))
    cells = sorted(set(lm3) & set(lm1) & set(lm2))
    if not cells:
        return C2.no_data(rule, f"{LM3}, {LM1} and {LM2} at L/{HEADLINE_N}")
    outcomes, losses = [], []
    for c in cells:
        e3, e1, e2 = (float(m[c]["l2_error"]) for m in (lm3, lm1, lm2))
        outcomes.append(below(e3, min(e1, e2)))
        if e3 >= min(e1, e2):
            losses.append(f"{c[0]}/{c[1]:g}: {LM3} {_pct(e3)} vs {LM1} {_pct(e1)}, "
                          f"{LM2} {_pct(e2)}")
    best = unc.of(lm3[min(cells, key=lambda c: float(lm3[c]['l2_error']))], "l2_error")
    text = (f"{LM3} lowest in {sum(1 for o in outcomes if o)} of {len(cells)} cells"
            + (f"; not in {'; '.join(losses)}" if losses else "")
            + f"; its smallest error {best.text(_pct)}")
    runs = [m[c]["run_id"] for m in (lm3, lm1, lm2) for c in cells]
    return C2.verdict(decide(outcomes), rule, text, runs)


def _c3(head: pd.DataFrame) -> CaseCheck:
    lo, hi = C3_BAND
    rule = (f"{LM3}'s WF1/WF2 error ratio at L/{HEADLINE_N} (prescribed walls) within "
            f"[{lo:g}, {hi:g}] at every r_e/l0")
    ratios = an.weight_ratios(an.select(head, laplacian=LM3), "l2_error")
    if ratios.empty:
        return C3.no_data(rule, f"{LM3} with WF1 and WF2 at L/{HEADLINE_N}")
    outcomes = [lo <= r <= hi for r in ratios["ratio"]]
    worst = ratios.iloc[int(np.argmax(np.abs(np.log(ratios["ratio"].to_numpy(float)))))]
    text = (f"ratio {an.span(ratios['ratio'], lambda v: f'{v:.2f}')} over {len(ratios)} radii; "
            f"furthest from 1 at r_e/l0 = {worst['re_ratio']:g}: WF1 {_pct(worst['wf1'])}, "
            f"WF2 {_pct(worst['wf2'])}")
    runs = list(ratios["run_id_wf1"]) + list(ratios["run_id_wf2"]) \
        if "run_id_wf1" in ratios else []
    return C3.verdict(decide(outcomes), rule, text, runs)


def _c8(head: pd.DataFrame) -> CaseCheck:
    rule = (f"viscous half only: {LM2}'s error at L/{HEADLINE_N} (prescribed walls, t = "
            f"{END_TIME:g} s) above {C8_MIN_L2:.0%} in every (WF, r_e/l0) cell; the pressure "
            "half needs a pressure solve (docs/method.md section 10) and is not tested")
    sel = an.select(head, laplacian=LM2)
    if sel.empty:
        return C8.no_data(rule, f"{LM2} at L/{HEADLINE_N}")
    errs = sel["l2_error"].to_numpy(float)
    outcomes = [above(float(e), C8_MIN_L2) for e in errs]
    text = f"{LM2} error {an.span(errs, _pct)} over {len(errs)} cells"
    return C8.verdict(decide(outcomes), rule, text, sel["run_id"])


# ---------------------------------------------------------------------- helpers
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
    t = an.sort_models(g[cols + (["solver"] if an.several_solvers(g) else [])], ["re_ratio"])
    t = t.assign(where=np.where(t["wall_error_share"] > 0.5, "near the walls", "interior"))
    return t.rename(columns={"laplacian": "model"}).reset_index(drop=True)


def convergence_table(df: pd.DataFrame) -> pd.DataFrame:
    """L/20 -> L/40 (or whatever resolutions there are): order and error reduction."""
    if df.empty:
        return pd.DataFrame()
    keys = (["solver"] if an.several_solvers(df) else []) + [
        "laplacian", "weight", "re_ratio", "wall_velocity", "wall_row", "jitter"]
    t = an.observed_orders(df, "l2_error", keys)
    if t.empty:
        return t
    t = t.assign(reduction=t["error_coarse"] / t["error_fine"],
                 n_coarse=(L / t["l0_coarse"]).round().astype(int),
                 n_fine=(L / t["l0_fine"]).round().astype(int))
    t = an.sort_models(t, ["wall_row", "wall_velocity", "re_ratio"])
    t = t.rename(columns={"laplacian": "model"})
    lead = [c for c in ("solver", "model", "weight", "re_ratio", "wall_velocity", "wall_row",
                        "jitter", "observed_order", "reduction") if c in t.columns]
    return t[lead + [c for c in t.columns if c not in lead]].reset_index(drop=True)


def time_table(df: pd.DataFrame) -> pd.DataFrame:
    """Runs with a dt check: the change on halving dt against the run's error."""
    keys = (["solver"] if an.several_solvers(df) else []) + [
        "laplacian", "weight", "re_ratio", "wall_velocity", "wall_row", "n"]
    t = an.dt_halving_table(df, keys, extra=["c_nu", "dt"], against="run")
    return t.rename(columns={"laplacian": "model"}) if not t.empty else t


def _summary_line(g: pd.DataFrame, key: str) -> str:
    n = g["n"].iloc[0]
    best = an.row_min(g, "l2_error")
    parts = []
    for model in sorted(g["laplacian"].unique(), key=an.model_sort_key):
        m = g[g["laplacian"] == model]
        parts.append(f"{model} {an.span(m['l2_error'], an.pct)}")
    wins = ""
    cells = g.groupby(["weight", "re_ratio"])
    if cells.ngroups > 1 and g["laplacian"].nunique() > 1:
        winners = pd.Series([str(an.row_min(c, "l2_error")["laplacian"]) for _, c in cells])
        wins = "  Smallest error per (WF, r_e/l0) cell: " + ", ".join(
            f"{m} in {k} of {len(winners)}" for m, k in winners.value_counts().items()) + "."
    treatment = key.split("_", 1)[1].replace("_", ", ")
    return (f"- **L/{n}, {treatment} walls, t = {END_TIME:g} s**: best {best['laplacian']} / "
            f"{best['weight']} at r_e/l0 = {best['re_ratio']:g} ({an.pct(best['l2_error'], 3)}). "
            "Error range per model: " + "; ".join(parts) + "." + wins)


def _location_line(g: pd.DataFrame) -> str:
    parts = []
    for model in sorted(g["laplacian"].unique(), key=an.model_sort_key):
        m = g[g["laplacian"] == model]
        share = m["wall_error_share"]
        where = ("near the walls" if (share > 0.5).all() else "in the interior"
                 if (share <= 0.5).all() else "near the walls or in the interior, by radius")
        peak = m["max_error_y"].dropna() if "max_error_y" in m else m.iloc[:0, 0]
        at = f"; largest error at y/L = {an.span(peak, lambda v: f'{v:.2f}')}" if len(peak) else ""
        parts.append(f"{model} {where} ({an.span(share, lambda v: f'{100 * v:.0f}%')} of the "
                     f"squared error next to the plates{at})")
    rows = an.span(g["wall_row_share"], lambda v: f"{100 * v:.0f}%")
    return (f"  - Where the error sits (rows within r_e of a plate, {rows} of the rows): "
            + "; ".join(parts) + ".")


def _treatment_line(df: pd.DataFrame) -> str:
    """Prescribed against mirror walls on the same cells (finest spacing)."""
    d = df[(df["n"] == df["n"].max()) & (df["wall_row"] == "on-plate") & (df["jitter"] == 0)
           & (df["drift"] == 0)]
    keys = ["laplacian", "weight", "re_ratio"]
    pre = d[d["wall_velocity"] == "prescribed"].groupby(keys)["l2_error"].first()
    mir = d[d["wall_velocity"] == "mirror"].groupby(keys)["l2_error"].first()
    both = pd.concat([pre.rename("p"), mir.rename("m")], axis=1, join="inner").dropna()
    if both.empty:
        return ""
    parts = []
    for model in sorted(both.index.get_level_values(0).unique(), key=an.model_sort_key):
        b = both.loc[model]
        parts.append(f"{model} {an.span(b['p'], an.pct)} -> {an.span(b['m'], an.pct)}")
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
        for model in sorted(c["model"].unique(), key=an.model_sort_key):
            r = c[c["model"] == model]
            parts.append(f"{model} {an.span(r['reduction'], lambda v: f'{v:.2f}x')} "
                         f"(order {an.span(r['observed_order'], lambda v: f'{v:.2f}', ' to ')})")
        n0, n1 = c["n_coarse"].iloc[0], c["n_fine"].iloc[0]
        where = str(wv) + ("" if wr == "on-plate" else f", {wr}")
        lines.append(f"- **L/{n0} -> L/{n1} ({where} walls)**: error reduction " + "; ".join(parts)
                     + ".")
    return lines



def _uncertainty_lines(head: pd.DataFrame, unc: NumericalUncertainty) -> list[str]:
    """u_num of the headline cell with its refinement sets, and per model whether the L/40
    errors are within their u_num (discretisation error) or beyond (a model error)."""
    cell = an.select(head, laplacian=BEST_MODEL, weight=BEST_WEIGHT, re_ratio=BEST_RE)
    if cell.empty:
        return []
    u = unc.of(cell.iloc[0].to_dict(), "l2_error")
    lines = [f"- **Numerical uncertainty** (docs/method.md section 9) of {BEST_MODEL} / "
             f"{BEST_WEIGHT} / {BEST_RE:g} at L/{HEADLINE_N}: {u.text(_pct)}; {u.detail(_pct)}."]
    parts = []
    for model in sorted(head["laplacian"].unique(), key=an.model_sort_key):
        vals = [unc.of(r, "l2_error") for r in an.rows(an.select(head, laplacian=model))]
        within = sum(1 for v in vals if v.u is not None and v.value <= v.u)
        beyond = sum(1 for v in vals if v.u is not None and v.value > v.u)
        parts.append(f"{model} {within} within / {beyond} beyond")
    lines.append(f"- **Discretisation or model error** (L/{HEADLINE_N} error against its u_num, "
                 "cells within / beyond; two spacings and the assumed order 1 where the cell "
                 "has no third): " + "; ".join(parts) + ".")
    return lines


def _reduction_gate(df: pd.DataFrame) -> CaseCheck:
    name = (f"L/20 -> L/40 reduces the {' and '.join(CONVERGING_MODELS)} errors at least "
            f"{MIN_REDUCTION:g}x (t = {END_TIME:g} s, prescribed walls)")
    conv = convergence_table(df)
    if conv.empty:
        return CaseCheck(name, None, "needs L/20 and L/40 runs")
    conv = conv[conv["model"].isin(CONVERGING_MODELS) & (conv["n_coarse"] == 20)
                & (conv["n_fine"] == 40)]
    if conv.empty:
        return CaseCheck(name, None, "needs L/20 and L/40 runs of those models")
    worst = an.row_min(conv, "reduction")
    bad = conv[conv["reduction"] < MIN_REDUCTION]
    detail = (f"{len(conv)} model/WF/radius groups; smallest reduction "
              f"{worst['reduction']:.2f}x ({worst['model']}, {worst['weight']}, r_e/l0 = "
              f"{worst['re_ratio']:g}: {an.pct(worst['error_coarse'])} -> "
              f"{an.pct(worst['error_fine'])})")
    if not bad.empty:
        detail += "; below: " + ", ".join(
            f"{r.model}/{r.weight}/{r.re_ratio:g} = {r.reduction:.2f}x"
            for r in bad.itertuples())
    return CaseCheck(name, bad.empty, detail)


def tables(records: list[dict[str, Any]], unc: NumericalUncertainty) -> dict[str, Any]:
    df = grid(an.completed(records))
    if df.empty:
        return {}
    out: dict[str, Any] = {f"l2_error_with_u_num_L-{HEADLINE_N}_prescribed": an.pivot(
        headline(an.completed(records)), "l2_error",
        cell=lambda r: unc.of(r.to_dict(), "l2_error").text(_pct))}
    for key, g in _treatment_groups(df):
        out[f"l2_error_t{END_TIME:g}_{key}"] = an.pivot(g, "l2_error")
    for key, g in _treatment_groups(df):
        if g["l2_error_steady"].notna().any():
            out[f"l2_error_steady_{key}"] = an.pivot(g, "l2_error_steady")
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


def findings(records: list[dict[str, Any]], unc: NumericalUncertainty) -> str:
    df = grid(an.completed(records))
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
        line = an.weight_ratio_line(d[d["n"] == d["n"].max()], "l2_error",
                                    f"L/{d['n'].max()}, prescribed walls")
        if line:
            lines.append(line)
    lines += _convergence_lines(convergence_table(df))
    lines += _uncertainty_lines(headline(an.completed(records)), unc)
    steady = df[df["l2_error_steady"].notna()] if "l2_error_steady" in df else df.iloc[:0]
    if not steady.empty:
        parts = []
        for (wv, model), g in steady.groupby(["wall_velocity", "laplacian"]):
            parts.append(f"{model} ({wv}) {an.span(g['l2_error_steady'], an.pct)}")
        lines.append(
            "- **Steady state** (every Laplacian is exact for a linear profile in the "
            "interior, so this is the wall treatment's error): " + "; ".join(parts) + ".")
    tt = time_table(df)
    if not tt.empty:
        worst = an.row_max(tt, "time_error_share")
        lines.append(
            f"- **Time stepping** ({len(tt)} runs with a dt check): halving dt moves the "
            f"t = {END_TIME:g} s profile by {an.span(tt['dt_halving_change'], an.pct)} of "
            "||u_exact||; forward Euler's error (about twice that) is "
            f"{an.span(tt['time_error_share'], lambda v: f'{100 * v:.0f}%')} of the "
            f"run's error, at most for {worst['model']} / {worst['weight']} / "
            f"{worst['re_ratio']:g} ({worst['wall_velocity']}, L/{worst['n']}).")
    if (df["wall_row"] == "offset").any():
        lines.append(
            "- **wall_row = offset** puts the first boundary row l0/2 outside the plate; "
            "with prescribed velocities the no-slip point follows that row, so the channel "
            "is effectively l0 wider than L (see the module docstring).")
    return "\n".join(lines)


