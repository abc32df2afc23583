"""Poiseuille: gates, tables and findings from the run records (docs/method.md 6 f).

Gates (L/40, t = 0.1125 s, prescribed on-plate walls):

* the recommended cell (``xu-jin`` / WF2 / r_e = 3.1 l0) within ``BEST_MAX_L2`` of the series
  solution.  How the tolerance was chosen: the error of that cell is dominated by the
  first-order error of the prescribed walls (docs/method.md 6 b), about l0 / (2 L) of a
  spacing's lag spread over the profile; Couette's gate for the same cell is 1 %, measured
  0.2 %; here the measured errors are 0.63 % at L/20 and smaller at L/40, so 1 % holds a
  first-order error with a margin of two at L/20 and fails a model whose error does not fall
  with l0;
* L/20 -> L/40 reduces the ``xu-jin`` and ``koshizuka-oka`` errors at least ``MIN_REDUCTION``
  = 1.5-fold (observed order >= 0.58; both are consistent Laplacians, first order at the
  walls).

The observed order in l0 is reported per cell (``convergence`` table) and, for the headline
cell, from L/20, L/40, L/80 with u_num (docs/method.md section 9).  The seed paper has no
Poiseuille case, so no claim is tested here.
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from mpsbench.cases import CaseCheck
from mpsbench.cases import analysis as an
from mpsbench.cases.refinement import NumericalUncertainty

from .metrics import END_TIME, L

HEADLINE_N = 40
BEST = {"laplacian": "xu-jin", "weight": "wf2", "re_ratio": 3.1}
BEST_MAX_L2 = 0.01
CONVERGING_MODELS, MIN_REDUCTION = ("xu-jin", "koshizuka-oka"), 1.5


def _pct(v: float) -> str:
    return f"{100 * v:.3g}%"


def _order(v: float) -> str:
    return f"{v:.2f}"


def grid(df: pd.DataFrame) -> pd.DataFrame:
    """The runs with ``n`` = L / l0 (an integer, for grouping without float trouble)."""
    return df.assign(n=(L / df["l0"]).round().astype(int)) if not df.empty else df


def default_walls(df: pd.DataFrame) -> pd.DataFrame:
    if df.empty:
        return df
    return df[(df["wall_velocity"] == "prescribed") & (df["wall_row"] == "on-plate")]


def headline(df: pd.DataFrame) -> pd.DataFrame:
    d = default_walls(grid(df))
    return d[d["n"] == HEADLINE_N] if not d.empty else d


def gates(records: list[dict[str, Any]]) -> list[CaseCheck]:
    df = an.completed(records)
    return [
        an.Bound(f"xu-jin / WF2 at r_e/l0 = 3.1 within {BEST_MAX_L2:.0%} of the series solution "
                 f"(relative L2, L/{HEADLINE_N}, t = {END_TIME:g} s, prescribed walls)",
                 "l2_error", BEST, upper=BEST_MAX_L2, fmt=an.pct).check(headline(df)),
        _reduction_gate(default_walls(grid(df))),
    ]


def convergence_table(df: pd.DataFrame) -> pd.DataFrame:
    """Observed order and error reduction between successive spacings, per cell."""
    if df.empty:
        return pd.DataFrame()
    keys = (["solver"] if an.several_solvers(df) else []) + [
        "laplacian", "weight", "re_ratio", "wall_velocity", "wall_row"]
    t = an.observed_orders(df, "l2_error", keys)
    if t.empty:
        return t
    t = t.assign(reduction=t["error_coarse"] / t["error_fine"],
                 n_coarse=(L / t["l0_coarse"]).round().astype(int),
                 n_fine=(L / t["l0_fine"]).round().astype(int))
    t = an.sort_models(t, ["wall_row", "wall_velocity", "re_ratio"])
    t = t.rename(columns={"laplacian": "model"})
    lead = [c for c in ("solver", "model", "weight", "re_ratio", "wall_velocity", "wall_row",
                        "observed_order", "reduction") if c in t.columns]
    return t[lead + [c for c in t.columns if c not in lead]].reset_index(drop=True)


def _reduction_gate(df: pd.DataFrame) -> CaseCheck:
    name = (f"L/20 -> L/{HEADLINE_N} reduces the {' and '.join(CONVERGING_MODELS)} errors at "
            f"least {MIN_REDUCTION:g}x (t = {END_TIME:g} s, prescribed walls)")
    conv = convergence_table(df)
    if conv.empty:
        return CaseCheck(name, None, "needs L/20 and L/40 runs")
    conv = conv[conv["model"].isin(CONVERGING_MODELS) & (conv["n_coarse"] == 20)
                & (conv["n_fine"] == HEADLINE_N)]
    if conv.empty:
        return CaseCheck(name, None, "needs L/20 and L/40 runs of those models")
    worst = an.row_min(conv, "reduction")
    bad = conv[conv["reduction"] < MIN_REDUCTION]
    detail = (f"{len(conv)} model/WF/radius groups; smallest reduction {worst['reduction']:.2f}x "
              f"(order {worst['observed_order']:.2f}; {worst['model']}, {worst['weight']}, "
              f"r_e/l0 = {worst['re_ratio']:g}: {an.pct(worst['error_coarse'])} -> "
              f"{an.pct(worst['error_fine'])})")
    if not bad.empty:
        detail += "; below: " + ", ".join(
            f"{r.model}/{r.weight}/{r.re_ratio:g} = {r.reduction:.2f}x" for r in bad.itertuples())
    return CaseCheck(name, bad.empty, detail,
                     rule=f"error(L/20) / error(L/{HEADLINE_N}) >= {MIN_REDUCTION:g}")


def _groups(df: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    out = []
    for (n, wv, wr), g in df.groupby(["n", "wall_velocity", "wall_row"]):
        out.append((f"L-{n}_{wv}" + ("" if wr == "on-plate" else f"_{wr}"), g))
    return sorted(out, key=lambda kv: (-kv[1]["n"].iloc[0], kv[0]))


def tables(records: list[dict[str, Any]], unc: NumericalUncertainty) -> dict[str, Any]:
    df = grid(an.completed(records))
    if df.empty:
        return {}
    out: dict[str, Any] = {f"l2_error_with_u_num_L-{HEADLINE_N}_prescribed": an.pivot(
        headline(df), "l2_error", cell=lambda r: unc.of(r.to_dict(), "l2_error").text(_pct))}
    for key, g in _groups(df):
        out[f"l2_error_t{END_TIME:g}_{key}"] = an.pivot(g, "l2_error")
    for key, g in _groups(df):
        if g["l2_error_steady"].notna().any():
            out[f"l2_error_steady_{key}"] = an.pivot(g, "l2_error_steady")
    conv = convergence_table(df)
    if not conv.empty:
        out["convergence"] = conv.set_index(conv.columns[0])
    return {k: v for k, v in out.items() if not v.empty}


def findings(records: list[dict[str, Any]], unc: NumericalUncertainty) -> str:
    df = grid(an.completed(records))
    if df.empty:
        return "No run completed."
    lines = []
    for key, g in _groups(df):
        best = an.row_min(g, "l2_error")
        parts = [f"{m} {an.span(g[g['laplacian'] == m]['l2_error'], an.pct)}"
                 for m in sorted(g["laplacian"].unique(), key=an.model_sort_key)]
        lines.append(f"- **{key.replace('L-', 'L/').replace('_', ', ')} walls, t = "
                     f"{END_TIME:g} s**: best {best['laplacian']} / {best['weight']} at r_e/l0 = "
                     f"{best['re_ratio']:g} ({an.pct(best['l2_error'], 3)}); per model: "
                     + "; ".join(parts) + ".")
    conv = convergence_table(df)
    for (wv, wr), c in (conv.groupby(["wall_velocity", "wall_row"], sort=False)
                        if not conv.empty else []):
        parts = [f"{m} order " + an.span(c[c["model"] == m]["observed_order"], _order, " to ")
                 for m in sorted(c["model"].unique(), key=an.model_sort_key)]
        lines.append(f"- **Observed order in l0 ({wv}"
                     + ("" if wr == "on-plate" else f", {wr}") + " walls)**: "
                     + "; ".join(parts) + ".")
    cell = an.select(headline(df), **BEST)
    if not cell.empty:
        u = unc.of(cell.iloc[0].to_dict(), "l2_error")
        lines.append(f"- **Numerical uncertainty** of xu-jin / WF2 / 3.1 at L/{HEADLINE_N}: "
                     f"{u.text(_pct)}; {u.detail(_pct)}.")
    steady = df[df["l2_error_steady"].notna()]
    if not steady.empty:
        parts = [f"{m} ({wv}) {an.span(g['l2_error_steady'], an.pct)}"
                 for (wv, m), g in steady.groupby(["wall_velocity", "laplacian"])]
        lines.append("- **Steady state** (the parabola; its curvature is seen by the Laplacian "
                     "in the interior and at the walls): " + "; ".join(parts) + ".")
    return "\n".join(lines)
