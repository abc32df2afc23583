"""Diffusion: gates, claims, tables and findings from the run records (docs/method.md 6a, 8).

Gates (they decide the exit status): ``xu-jin`` and ``koshizuka-oka`` below 2 % L2 on the
lattice at l0 = 1/40; ``khayyer-gotoh`` above 30 % there (it over-diffuses: the lattice value
of its operator, docs/method.md section 3); ``xu-jin`` and ``koshizuka-oka`` observed order
>= 1.8 on the lattice; the time-stepping error (twice the dt-halving change) below 10 % of the
smallest spatial error of its group.

Claims (the rules are written next to each verdict): C1 (LM3 accurate: its computed errors at
l0 = 1/40), C8 (LM2 not for viscous accuracy: its decay rate, a property of the model, so its
u_num enters; the pressure half needs a pressure solve) and C9 (LM1 inexact: does its decay
rate extrapolate to the exact one?).
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from mpsbench.cases import CaseCheck
from mpsbench.cases import analysis as an
from mpsbench.cases.checks import above, below, decide
from mpsbench.cases.refinement import NumericalUncertainty

from ..paper import C1, C8, C9, LM1, LM2, LM3

# Gate tolerances (docs/method.md 6a; unchanged from the first version of the case)
LATTICE_L0 = 1 / 40
ACCURATE_MODELS = ("xu-jin", "koshizuka-oka")
ACCURATE_MAX_L2 = 0.02  # xu-jin and koshizuka-oka on the lattice at l0 = 1/40: below 2 %
OVERDIFFUSING_MODEL = "khayyer-gotoh"
OVERDIFFUSING_MIN_L2 = 0.30  # khayyer-gotoh over-diffuses two- to three-fold: above 30 %
MIN_LATTICE_ORDER = 1.8  # xu-jin and koshizuka-oka are second order on the lattice
MAX_TIME_ERROR_SHARE = 0.1  # forward Euler error below 10 % of the smallest spatial error

# Claim rules (docs/method.md section 8)
C1_MAX_L2, C1_MIN_ORDER = 0.02, 1.8
C8_MIN_RATE_ERROR = 0.10  # LM2's decay rate off by more than 10 % at the finest lattice l0

GROUP = ["laplacian", "weight", "re_ratio", "jitter"]


def _pct(v: float) -> str:
    return f"{100 * v:.3g}%"


def where(l0: float, jit: float) -> str:
    return f"l0 = {an.fraction(l0)}, " + ("regular lattice" if jit == 0 else f"jitter {jit:g} l0")


def headline_l0(df: pd.DataFrame) -> float:
    """l0 = 1/40 when the study has it, else the finest."""
    values = sorted(df["l0"].unique())
    near = [h for h in values if abs(h - LATTICE_L0) < 1e-12]
    return float(near[0] if near else values[0])


def lattice(df: pd.DataFrame, l0: float | None = None) -> pd.DataFrame:
    """Lattice runs of the model grid (:func:`default_dt`), at ``l0`` if given."""
    if df.empty:
        return df
    sel = an.select(default_dt(df), jitter=0.0)
    return an.select(sel, l0=l0) if l0 is not None else sel


def default_dt(df: pd.DataFrame) -> pd.DataFrame:
    """The runs at the largest (the tiers' common) dt: a study that sweeps dt is shown at one
    (the tiers' dt refinement runs are not in the model records at all)."""
    if df.empty or "dt" not in df:
        return df
    return an.select(df, dt=df["dt"].max())


# ---------------------------------------------------------------------- gates
def gates(records: list[dict[str, Any]]) -> list[CaseCheck]:
    df = default_dt(an.completed(records))
    lat = {"jitter": 0.0, "l0": LATTICE_L0}
    return [
        an.Bound(f"xu-jin and koshizuka-oka below {ACCURATE_MAX_L2:.0%} on the lattice at "
                 "l0 = 1/40", "l2_error", {**lat, "laplacian": ACCURATE_MODELS},
                 upper=ACCURATE_MAX_L2, fmt=_pct).check(df),
        an.Bound(f"khayyer-gotoh above {OVERDIFFUSING_MIN_L2:.0%} on the lattice at l0 = 1/40 "
                 "(it over-diffuses)", "l2_error", {**lat, "laplacian": OVERDIFFUSING_MODEL},
                 lower=OVERDIFFUSING_MIN_L2, fmt=_pct).check(df),
        _order_gate(df),
        _time_gate(df),
    ]


def _order_gate(df: pd.DataFrame) -> CaseCheck:
    name = (f"xu-jin and koshizuka-oka converge at second order on the lattice "
            f"(observed order >= {MIN_LATTICE_ORDER})")
    orders = convergence_table(df)
    sel = orders[(orders["jitter"] == 0) & orders["model"].isin(ACCURATE_MODELS)] \
        if not orders.empty else orders
    if sel.empty:
        return CaseCheck(name, None, "needs two or more l0 on the lattice")
    worst = an.row_min(sel, "observed_order")
    ok = bool((sel["observed_order"] >= MIN_LATTICE_ORDER).all())
    return CaseCheck(name, ok, f"{len(sel)} groups, lowest order "
                     f"{worst['observed_order']:.2f} ({worst['model']}, {worst['weight']}, "
                     f"r_e/l0 = {worst['re_ratio']:g})")


def _time_gate(df: pd.DataFrame) -> CaseCheck:
    name = (f"time-stepping error (2 x dt-halving change) below "
            f"{MAX_TIME_ERROR_SHARE:.0%} of the smallest spatial error of its group")
    table = time_table(df)
    if table.empty:
        return CaseCheck(name, None, "no run with dt_check")
    worst = an.row_max(table, "time_error_share")
    ok = bool((table["time_error_share"] < MAX_TIME_ERROR_SHARE).all())
    return CaseCheck(name, ok, f"{len(table)} groups; worst share "
                     f"{worst['time_error_share']:.2%} ({worst['model']}, "
                     f"{worst['weight']}, r_e/l0 = {worst['re_ratio']:g}, jitter "
                     f"{worst['jitter']:g}: time error {worst['time_error']:.2e} vs "
                     f"spatial {worst['smallest_l2_error']:.2e})")


# ---------------------------------------------------------------------- claims
def claims(records: list[dict[str, Any]], unc: NumericalUncertainty) -> list[CaseCheck]:
    df = an.completed(records)
    return [_c1(df, unc), _c8(df, unc), _c9(df, unc)]


def _c1(df: pd.DataFrame, unc: NumericalUncertainty) -> CaseCheck:
    rule = (f"{LM3} on the regular lattice at l0 = 1/40, every WF and r_e/l0: L2 error "
            f"< {C1_MAX_L2:.0%} (the computed error at that spacing), and observed order in l0 "
            f"(two finest) >= {C1_MIN_ORDER}")
    sel = an.select(lattice(df, LATTICE_L0), laplacian=LM3)
    if sel.empty:
        return C1.no_data(rule, f"{LM3} lattice runs at l0 = 1/40")
    errs = [unc.of(r, "l2_error") for r in an.rows(sel)]
    outcomes = [below(u.value, C1_MAX_L2) for u in errs]
    orders = convergence_table(lattice(df))
    orders = orders[orders["model"] == LM3] if not orders.empty else orders
    outcomes += [bool(o >= C1_MIN_ORDER) for o in orders["observed_order"]] \
        if not orders.empty else [None]
    worst = max(errs, key=lambda u: u.value)
    text = f"{an.plural(len(errs), 'run')}: L2 error up to {worst.text(_pct)}; "
    text += (f"observed order {an.span(orders['observed_order'], lambda v: f'{v:.2f}', ' to ')}"
             f" ({an.plural(len(orders), 'group')})" if not orders.empty
             else "no convergence group")
    return C1.verdict(decide(outcomes), rule, text, sel["run_id"])


def _c8(df: pd.DataFrame, unc: NumericalUncertainty) -> CaseCheck:
    rule = (f"viscous half only: {LM2}'s decay rate on the regular lattice at the finest l0 is "
            f"off by more than {C8_MIN_RATE_ERROR:.0%} (|decay ratio - 1| - u_num > "
            f"{C8_MIN_RATE_ERROR:g}) for every WF and r_e/l0; the pressure half needs a pressure "
            "solve (docs/method.md section 10) and is not tested")
    lat = lattice(df)
    sel = an.select(lat, laplacian=LM2, l0=lat["l0"].min()) if not lat.empty else lat
    if sel.empty:
        return C8.no_data(rule, f"{LM2} lattice runs")
    vals = [unc.of(r, "decay_ratio") for r in an.rows(sel)]
    outcomes = [above(abs(v.value - 1.0), C8_MIN_RATE_ERROR, v.u, converged=v.converged)
                for v in vals]
    closest = min(vals, key=lambda v: abs(v.value - 1.0))
    text = (f"{an.plural(len(vals), 'run')} at {where(float(sel['l0'].iloc[0]), 0)}: decay ratio "
            f"{an.span([v.value for v in vals], lambda x: f'{x:.3f}')} (closest to 1: "
            f"{closest.text(lambda x: f'{x:.3f}')})")
    return C8.verdict(decide(outcomes), rule, text, sel["run_id"])


def _c9(df: pd.DataFrame, unc: NumericalUncertainty) -> CaseCheck:
    rule = (f"'inexact' read as: {LM1}'s decay ratio extrapolated to l0 -> 0 on the regular "
            "lattice (Richardson, from its l0 refinement set) differs from 1 by more than its "
            "u_num, for every WF and r_e/l0 with a refinement set (supported), or agrees with "
            "1 within u_num for one (refuted); 'needs lambda' holds by the model's definition")
    lat = lattice(df)
    sel = an.select(lat, laplacian=LM1, l0=lat["l0"].min()) if not lat.empty else lat
    if sel.empty:
        return C9.no_data(rule, f"{LM1} lattice runs at two or more l0")
    outcomes: list[bool | None] = []
    parts: list[str] = []
    for r in an.rows(sel):
        v = unc.of(r, "decay_ratio")
        s = v.parts.get("l0")
        if s is None:
            continue
        c = s.convergence
        if not c.converged or c.extrapolated is None:
            outcomes.append(None)
            parts.append(f"{r['weight']}/{r['re_ratio']:g}: not converged")
            continue
        u = v.u if v.u is not None else c.u_num or 0.0
        outcomes.append(abs(c.extrapolated - 1.0) > u)
        parts.append(f"{r['weight']}/{r['re_ratio']:g}: {c.extrapolated:.5f} ± {u:.2g}")
    if not outcomes:
        return C9.no_data(rule, f"{LM1} lattice runs at two or more l0")
    text = (f"extrapolated decay ratio (u_num of the finest run; "
            f"{an.plural(len(outcomes), 'group')}): "
            + "; ".join(parts[:6]) + ("; ..." if len(parts) > 6 else ""))
    return C9.verdict(decide(outcomes), rule, text, sel["run_id"])


# ---------------------------------------------------------------------- tables
def convergence_table(df: pd.DataFrame) -> pd.DataFrame:
    """Observed order of the L2 error in l0 per (model, WF, r_e/l0, jitter) at the default dt
    (convergence.csv)."""
    df = default_dt(df)
    keys = (["solver"] if an.several_solvers(df) else []) + GROUP
    if df.empty:
        return pd.DataFrame()
    t = an.observed_orders(df, "l2_error", keys)
    if t.empty:
        return t
    t = an.sort_models(t, ["jitter", "re_ratio"]).rename(columns={"laplacian": "model"})
    lead = [c for c in ("solver", "model", "weight", "re_ratio", "jitter", "observed_order")
            if c in t.columns]
    return t[lead + [c for c in t.columns if c not in lead]].reset_index(drop=True)


def time_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per group with a dt check: time error estimate against the group's smallest error."""
    df = default_dt(df)
    keys = (["solver"] if an.several_solvers(df) else []) + GROUP
    t = an.dt_halving_table(df, keys, against="group-min", extra=["dt"])
    return t.rename(columns={"laplacian": "model"}) if not t.empty else t


def resolution_groups(df: pd.DataFrame) -> list[tuple[tuple[float, float], pd.DataFrame]]:
    """(l0, jitter) groups at the default dt: jitter first, then coarse to fine."""
    out = []
    for _, group in default_dt(df).groupby(["l0", "jitter"]):
        l0, jit = float(group["l0"].iloc[0]), float(group["jitter"].iloc[0])
        out.append(((l0, jit), group))
    return sorted(out, key=lambda item: (item[0][1], -item[0][0]))


def headline_table(df: pd.DataFrame, unc: NumericalUncertainty) -> pd.DataFrame:
    """The L2 error at l0 = 1/40 on the lattice with its u_num (l0 and dt components where the
    tier has the refinement sets, "not converged" where the sequence is not monotone)."""
    sel = lattice(df, headline_l0(df)) if not df.empty else df
    return an.pivot(sel, "l2_error", cell=lambda r: unc.of(r.to_dict(), "l2_error").text(_pct))


def tables(records: list[dict[str, Any]], unc: NumericalUncertainty) -> dict[str, Any]:
    df = an.completed(records)
    if df.empty:
        return {}
    out: dict[str, Any] = {
        f"l2_error_with_u_num_l0-1_{round(1 / headline_l0(df))}": headline_table(df, unc)}
    for (l0, jit), group in resolution_groups(df):
        out[f"l2_error_l0-1_{round(1 / l0)}_jitter-{jit:g}"] = an.pivot(group, "l2_error")
    finest = default_dt(df)["l0"].min()
    for jit in sorted(df["jitter"].unique()):
        group = an.select(default_dt(df), jitter=jit, l0=finest)
        out[f"decay_ratio_l0-1_{round(1 / finest)}_jitter-{jit:g}"] = an.pivot(
            group, "decay_ratio", cell=lambda r: unc.of(r.to_dict(), "decay_ratio").text(
                lambda v: f"{v:.4f}"))
    conv = convergence_table(df)
    if not conv.empty:
        out["convergence"] = conv.set_index(conv.columns[0])
    tt = time_table(df)
    if not tt.empty:
        out["time_stepping"] = tt.set_index(tt.columns[0])
    return {k: v for k, v in out.items() if not v.empty}


# ---------------------------------------------------------------------- findings
def findings(records: list[dict[str, Any]], unc: NumericalUncertainty) -> str:
    df = an.completed(records)
    if df.empty:
        return "No run completed."
    lines = [_summary_line(group, l0, jit) for (l0, jit), group in resolution_groups(df)]
    head = lattice(df, headline_l0(df))
    line = an.weight_ratio_line(head, "l2_error", f"{where(headline_l0(df), 0)}")
    if line:
        lines.append(line)
    lines += _convergence_lines(convergence_table(df))
    lines += _uncertainty_lines(head, unc)
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


def _uncertainty_lines(head: pd.DataFrame, unc: NumericalUncertainty) -> list[str]:
    if head.empty:
        return []
    rows = [unc.of(r, "l2_error") for r in an.rows(an.select(head, laplacian=LM3))]
    if not rows:
        return []
    three = [u for u in rows if u.parts.get("l0") is not None
             and u.parts["l0"].convergence.order_observed]
    measured = [u for u in rows if u.u is not None]
    text = (f"- **Numerical uncertainty** (docs/method.md section 9) of the {LM3} L2 errors at "
            f"l0 = 1/40: u_num {an.span([u.u for u in measured], _pct)} "
            f"({len(measured)} of {len(rows)} cells)" if measured else
            f"- **Numerical uncertainty** of the {LM3} L2 errors at l0 = 1/40: not converged")
    if three:
        c = three[0].parts["l0"].convergence
        text += (f"; where three spacings exist the observed order is {c.order:.2f} and "
                 f"Fs = {c.safety:g} (elsewhere two spacings, assumed order 2, Fs = 3)")
    text += (". The u_num of an error that tends to zero is of its own size: such an error is "
             "discretisation error.")
    return [text, _split_line(head, unc)]


def _split_line(head: pd.DataFrame, unc: NumericalUncertainty) -> str:
    """Per model: in how many cells the L2 error is within its u_num (discretisation error,
    it vanishes with l0) or beyond it (a model error that refinement does not remove)."""
    parts = []
    for model in sorted(head["laplacian"].unique(), key=an.model_sort_key):
        vals = [unc.of(r, "l2_error") for r in an.rows(an.select(head, laplacian=model))]
        within = sum(1 for v in vals if v.u is not None and v.value <= v.u)
        beyond = sum(1 for v in vals if v.u is not None and v.value > v.u)
        parts.append(f"{model} {within} within / {beyond} beyond"
                     + (f" / {len(vals) - within - beyond} not converged"
                        if within + beyond < len(vals) else ""))
    return ("- **Discretisation or model error** (L2 error at l0 = 1/40 against its u_num, cells "
            "within / beyond): " + "; ".join(parts) + ".")


def _summary_line(group: pd.DataFrame, l0: float, jit: float) -> str:
    parts = []
    for model in sorted(group["laplacian"].unique(), key=an.model_sort_key):
        g = group[group["laplacian"] == model]
        err = an.span(g["l2_error"], an.pct)
        rate = an.span(g["decay_ratio"], lambda v: f"{v:.3f}")
        parts.append(f"{model} {err} (decay ratio {rate})")
    best = an.row_min(group, "l2_error")
    wins = _wins(group)
    text = (f"- **{where(l0, jit)}**: best {best['laplacian']} / {best['weight']} at r_e/l0 = "
            f"{best['re_ratio']:g} ({an.pct(best['l2_error'], 3)}).  Error range per model: "
            + "; ".join(parts) + ".")
    if wins:
        text += f"  Smallest error per (WF, r_e/l0) cell: {wins}."
    return text


def _wins(group: pd.DataFrame) -> str:
    cells = group.groupby(["weight", "re_ratio"])
    if cells.ngroups < 2 or group["laplacian"].nunique() < 2:
        return ""
    winners = [str(an.row_min(g, "l2_error")["laplacian"]) for _, g in cells]
    counts = pd.Series(winners).value_counts()
    return ", ".join(f"{m} in {n} of {len(winners)}" for m, n in counts.items())


def _convergence_lines(conv: pd.DataFrame) -> list[str]:
    if conv.empty:
        return []
    lines = []
    for jit in sorted(conv["jitter"].unique()):
        c = conv[conv["jitter"] == jit]
        parts = []
        for model in sorted(c["model"].unique(), key=an.model_sort_key):
            o = c[c["model"] == model]["observed_order"]
            parts.append(f"{model} {an.span(o, lambda v: f'{v:.2f}', ' to ')}")
        if jit == 0:
            note = ("  Orders near zero belong to models that converge to a wrong decay rate "
                    "(khayyer-gotoh and xu-jin-analytic: an O(1) factor on the lattice, "
                    "docs/method.md section 3).")
        else:
            note = ("  On an irregular cloud the MPS Laplacians lose their second-order "
                    "consistency, so the orders fall below the lattice's; a model with an O(1) "
                    "rate error stays near zero.")
        where_ = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
        lines.append(f"- **Observed order in l0, {where_}**: " + "; ".join(parts) + "." + note)
    return lines

