"""Water jet: gates, claims, tables and plain-word findings from the run records
(docs/method.md 6c, 8).

Gates (they decide the exit status): the free-streamline reference solution reproduces the
table of docs/method.md 6c and its momentum balance; no fluid particle crosses the plate in any
stabilized run.  Claims: C4 (the stabilization halves the pressure noise), C4b (with it the
plate Cp is within 0.1 RMS of the free-streamline solution: the case's first acceptance
criterion, a claim since docs/method.md section 8 decided so) and C5 (number density near n0,
no penetration).  The plate-pressure comparison uses u_num from the l0 and cfl refinement sets
of the acceptance run (docs/method.md section 9).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import CaseCheck, Claim
from mpsbench.cases import analysis as an
from mpsbench.cases.checks import below, decide
from mpsbench.cases.refinement import NumericalUncertainty

from ..paper import C4, C5
from .metrics import TABLE_CP, TABLE_XB, free_streamline_cp, stabilization_viscosity
from .params import PARAMS

NOISE_MEASURES = {
    "noise_spatial": "spatial pressure noise",
    "noise_temporal": "temporal stagnation-pressure noise",
    "density_drift_mean": "mean number-density drift",
}
# parameters that only matter when the stabilization is on: left out of the model key
_STAB_ONLY = ("stabilization", "alpha_s", "stabilization_walls")
_SKIP = {"case", "solver", "solver_version", "tier", "run_id", "status", "reason"}


completed = an.completed_records

CP_LIMIT = 0.1  # the case's first acceptance criterion, now claim C4b
NOISE_FACTOR = 2.0  # "greatly reduces": at least halved (C4)
DRIFT_FACTOR = 2.0  # number density "kept near n0": its mean drift at least halved (C5)
C4B = Claim("C4b", "With the stabilization the jet's plate pressure agrees with the "
            "free-streamline solution (Cp RMS error < 0.1 over 0 <= x/b <= 2, the case's first "
            "acceptance criterion).", "docs/method.md 6c (the case's first acceptance "
            "criterion, after Xu & Jin 2016)")
HEADLINE_METRICS = ("cp_rms_error", "cp_stagnation", "plate_force", "noise_spatial",
                    "noise_temporal", "density_drift_mean")


def resolution(r: dict[str, Any]) -> int:
    return int(round(r["b"] / r["l0"]))


DEFAULT_CFL = 0.2


def default_cfl(r: dict[str, Any]) -> bool:
    return an.matches(r, {"cfl": DEFAULT_CFL}) if "cfl" in r else True


def is_acceptance(r: dict[str, Any]) -> bool:
    """The acceptance model: stabilization on, pgm1, WF2, l0 = b/20, no collision model, at
    the default time step (cfl 0.2)."""
    return (
        bool(r.get("stabilization")) and r.get("gradient") == "pgm1" and r.get("weight") == "wf2"
        and resolution(r) == 20 and not r.get("collision_distance")
        and is_default_stabilization(r) and default_cfl(r)
    )


def twin(records: list[dict[str, Any]], run: dict[str, Any]) -> dict[str, Any] | None:
    """The unstabilized run with the same other parameters as a stabilized ``run``."""
    return next((off for off, on in pairs(records) if on is run), None)


fmt = an.fmt


DEFAULT_ALPHA_S = 0.01


def is_default_stabilization(r: dict[str, Any]) -> bool:
    """alpha_s 0.01 with wall and dummy particles in the sum (docs/method.md 5 defaults)."""
    return r.get("alpha_s", DEFAULT_ALPHA_S) == DEFAULT_ALPHA_S and r.get(
        "stabilization_walls", True) is not False


def variant(r: dict[str, Any]) -> str:
    """How a stabilized run departs from the default stabilization ('' if it does not)."""
    if not r.get("stabilization") or is_default_stabilization(r):
        return ""
    parts = []
    if r.get("alpha_s", DEFAULT_ALPHA_S) != DEFAULT_ALPHA_S:
        parts.append(f"alpha_s {r['alpha_s']:g}")
    if r.get("stabilization_walls", True) is False:
        parts.append("no wall neighbours in the stabilization")
    return ", ".join(parts)


def stabilization_re(r: dict[str, Any]) -> float:
    """U b / nu_s of a record (recomputed from its mean time step if the metric is missing)."""
    v = r.get("stabilization_re")
    if v is not None and math.isfinite(v):
        return float(v)
    if not r.get("stabilization") or not r.get("n_steps") or not r.get("alpha_s"):
        return math.nan
    dt = r["t_end"] * r["b"] / r["U"] / r["n_steps"]
    nu_s = stabilization_viscosity(r["weight"], r["re_ratio"], r["l0"], r["alpha_s"], dt)
    return float(r["U"] * r["b"] / nu_s)


def label(r: dict[str, Any]) -> str:
    cd = r.get("collision_distance") or 0.0
    coll = f", alpha_c {cd:g}" if cd else ""
    var = variant(r)
    cfl = "" if default_cfl(r) else f", cfl {r['cfl']:g}"
    return f"{r['gradient']}, {r['weight'].upper()}, b/{resolution(r)}{coll}{cfl}" + (
        f" [{var}]" if var else "")


def _model_key(r: dict[str, Any], params: list[str]) -> tuple[Any, ...]:
    return tuple((k, repr(r.get(k))) for k in params if k not in _STAB_ONLY)


def _params(records: list[dict[str, Any]]) -> list[str]:
    return [p.name for p in PARAMS if any(p.name in r for r in records)]


def pairs(records: list[dict[str, Any]]) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """(off, on) record pairs that differ only in the stabilization settings."""
    done = completed(records)
    params = _params(done)
    off = {_model_key(r, params): r for r in done if not r.get("stabilization")}
    out = []
    for r in done:
        if r.get("stabilization"):
            k = _model_key(r, params)
            if k in off:
                out.append((off[k], r))
    out.sort(key=lambda p: (resolution(p[0]), p[0]["gradient"], p[0]["weight"],
                            p[0].get("collision_distance") or 0.0, label(p[1])))
    return out


def factor(off: Any, on: Any) -> float:
    """Reduction factor off / on (> 1: the stabilization reduces the measure)."""
    if off is None or on is None or not on or not math.isfinite(off) or not math.isfinite(on):
        return math.nan
    return float(off) / float(on)


def noise_table(records: list[dict[str, Any]]) -> pd.DataFrame:
    rows = []
    for off, on in pairs(records):
        row: dict[str, Any] = {"model": label(on)}
        for m in NOISE_MEASURES:
            row[f"{m} off"] = off.get(m)
            row[f"{m} on"] = on.get(m)
            row[f"{m} off/on"] = factor(off.get(m), on.get(m))
        row["penetrations off"] = off.get("penetrations")
        row["penetrations on"] = on.get("penetrations")
        rows.append(row)
    return pd.DataFrame(rows).set_index("model") if rows else pd.DataFrame()


PLATE_COLUMNS = ("cp_rms_error", "cp_max_error", "cp_stagnation", "plate_force",
                 "near_wall_cp", "near_wall_cp_eos", "sheet_speed",
                 "stabilization_re", "penetrations",
                 "noise_spatial", "noise_temporal", "density_drift_mean", "density_drift_max",
                 "cp_stagnation_drift", "wall_time_s")


def run_table(records: list[dict[str, Any]]) -> pd.DataFrame:
    rows = []
    for r in sorted(completed(records), key=lambda r: (resolution(r), r["gradient"], r["weight"],
                                                      r.get("collision_distance") or 0.0,
                                                      bool(r["stabilization"]))):
        row: dict[str, Any] = {"model": label(r),
                               "stabilization": "on" if r["stabilization"] else "off"}
        row.update({c: r.get(c) for c in PLATE_COLUMNS})
        row["stabilization_re"] = stabilization_re(r)
        rows.append(row)
    return pd.DataFrame(rows).set_index(["model", "stabilization"]) if rows else pd.DataFrame()


def collision_groups(records: list[dict[str, Any]]) -> dict[tuple[Any, ...], list[dict[str, Any]]]:
    """Runs that differ only in the collision distance (at least two distances)."""
    done = completed(records)
    params = [p for p in _params(done) if p != "collision_distance"]
    groups: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for r in done:
        key = tuple((k, repr(r.get(k))) for k in params)
        groups.setdefault(key, []).append(r)
    return {
        k: sorted(v, key=lambda r: r.get("collision_distance") or 0.0)
        for k, v in groups.items()
        if len({r.get("collision_distance") for r in v}) >= 2
    }


def collision_table(records: list[dict[str, Any]]) -> pd.DataFrame:
    rows = []
    for group in collision_groups(records).values():
        for r in group:
            rows.append({
                "model": f"{r['gradient']}, {r['weight'].upper()}, b/{resolution(r)}",
                "stabilization": "on" if r["stabilization"] else "off",
                "alpha_c": r.get("collision_distance") or 0.0,
                **{c: r.get(c) for c in ("noise_spatial", "noise_temporal", "density_drift_mean",
                                         "density_drift_max", "penetrations", "cp_rms_error",
                                         "cp_stagnation", "sheet_speed", "nn_distance_mean",
                                         "close_fraction")},
            })
    if not rows:
        return pd.DataFrame()
    return pd.DataFrame(rows).set_index(["model", "stabilization", "alpha_c"])


# ---------------------------------------------------------------------- gates
def analytic_gate() -> CaseCheck:
    """The free-streamline solution against docs/method.md's table and its momentum balance."""
    table_err = float(np.max(np.abs(free_streamline_cp(TABLE_XB) - TABLE_CP)))
    x = np.linspace(0.0, 20.0, 200001)
    integral = 2.0 * float(np.trapezoid(free_streamline_cp(x), x))
    ok = table_err < 6e-4 and abs(integral - 2.0) < 1e-6
    return CaseCheck(
        "free-streamline reference solution", ok,
        f"max |Cp - table| = {table_err:.1e} at x/b = 0..2 (table rounded to 1e-3); "
        f"integral of Cp d(x/b) = {integral:.7f} (momentum balance: 2)")


def gates(records: list[dict[str, Any]]) -> list[CaseCheck]:
    out = [analytic_gate()]
    stab = [r for r in completed(records) if r.get("stabilization")]
    name = "no particle crosses the plate with the stabilization on"
    if not stab:
        out.append(CaseCheck(name, None, "no stabilized run completed"))
        return out
    worst = max(stab, key=lambda r: r.get("penetrations") or 0)
    out.append(CaseCheck(
        name, (worst.get("penetrations") or 0) == 0,
        f"max penetrations over {len(stab)} stabilized runs = {worst.get('penetrations')} "
        f"({worst['run_id']})", runs=tuple(str(r["run_id"]) for r in stab)))
    return out


# ---------------------------------------------------------------------- claims
def default_pairs(records: list[dict[str, Any]]) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """(off, on) pairs with the default stabilization and no collision model."""
    return [(off, on) for off, on in pairs(records)
            if is_default_stabilization(on) and not on.get("collision_distance")]


def claims(records: list[dict[str, Any]], unc: NumericalUncertainty) -> list[CaseCheck]:
    return [_c4(records), _c4b(records, unc), _c5(records)]


def _c4(records: list[dict[str, Any]]) -> CaseCheck:
    rule = (f"every stabilization on/off pair (default stabilization, no collision model): the "
            f"spatial pressure noise and the temporal stagnation-pressure noise both reduced at "
            f"least {NOISE_FACTOR:g}-fold (off/on >= {NOISE_FACTOR:g})")
    prs = default_pairs(records)
    if not prs:
        return C4.no_data(rule, "stabilization on/off pairs")
    outcomes, parts = [], []
    for off, on in prs:
        fs = [factor(off.get(m), on.get(m)) for m in ("noise_spatial", "noise_temporal")]
        outcomes += [f >= NOISE_FACTOR if math.isfinite(f) else None for f in fs]
        parts.append(f"{label(on)}: {fs[0]:.2f}x / {fs[1]:.2f}x")
    text = "spatial / temporal factor " + "; ".join(parts)
    return C4.verdict(decide(outcomes), rule, text,
                      [r["run_id"] for p in prs for r in p])


def _c4b(records: list[dict[str, Any]], unc: NumericalUncertainty) -> CaseCheck:
    rule = (f"the acceptance run (stabilization on, pgm1, WF2, b/20, no collision, cfl "
            f"{DEFAULT_CFL:g}): Cp RMS error + u_num < {CP_LIMIT:g} supported, Cp RMS error - "
            f"u_num >= {CP_LIMIT:g} refuted, else (or not converged) inconclusive")
    acc = [r for r in completed(records) if is_acceptance(r)]
    if not acc:
        return C4B.no_data(rule, "the acceptance run (quick or paper tier)")
    outcomes, parts = [], []
    for r in acc:
        u = unc.of(r, "cp_rms_error")
        outcomes.append(below(u.value, CP_LIMIT, u.u, converged=u.converged))
        off = twin(records, r)
        parts.append(f"Cp RMS error {u.text()} ({u.detail()})"
                     + (f"; without stabilization {unc.of(off, 'cp_rms_error').text()}"
                        if off is not None else ""))
    return C4B.verdict(decide(outcomes), rule, "; ".join(parts), [r["run_id"] for r in acc])


def _c5(records: list[dict[str, Any]]) -> CaseCheck:
    rule = (f"every stabilization on/off pair (default stabilization, no collision model): no "
            f"fluid particle below the plate with the stabilization (and not more than "
            f"without), and the mean number-density drift |n/n0 - 1| reduced at least "
            f"{DRIFT_FACTOR:g}-fold")
    prs = default_pairs(records)
    if not prs:
        return C5.no_data(rule, "stabilization on/off pairs")
    outcomes, parts = [], []
    for off, on in prs:
        f = factor(off.get("density_drift_mean"), on.get("density_drift_mean"))
        pen_on, pen_off = on.get("penetrations") or 0, off.get("penetrations") or 0
        outcomes += [f >= DRIFT_FACTOR if math.isfinite(f) else None,
                     pen_on == 0 and pen_on <= pen_off]
        parts.append(f"{label(on)}: drift {fmt(off.get('density_drift_mean'))} -> "
                     f"{fmt(on.get('density_drift_mean'))} ({f:.2f}x), penetrations "
                     f"{pen_off} -> {pen_on}")
    return C5.verdict(decide(outcomes), rule, "; ".join(parts),
                      [r["run_id"] for p in prs for r in p])


# ---------------------------------------------------------------------- tables
def headline_table(records: list[dict[str, Any]], unc: NumericalUncertainty) -> pd.DataFrame:
    """The acceptance run and its unstabilized twin: the plate and noise measures with their
    u_num (l0 and cfl refinement sets; "not converged" where a sequence is not monotone).  The
    penetration counts are in the ``noise`` table and the gate."""
    rows = []
    for on in (r for r in completed(records) if is_acceptance(r)):
        for run, state in ((twin(records, on), "off"), (on, "on")):
            if run is None:
                continue
            row: dict[str, Any] = {"model": label(run), "stabilization": state}
            row.update({m: unc.of(run, m).text() for m in HEADLINE_METRICS})
            rows.append(row)
    return pd.DataFrame(rows).set_index(["model", "stabilization"]) if rows else pd.DataFrame()


def dt_table(records: list[dict[str, Any]]) -> pd.DataFrame:
    """Runs that differ only in cfl: the plate Cp and the noise against the time step."""
    params = [p.name for p in PARAMS if p.name != "cfl"]
    groups: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for r in completed(records):
        groups.setdefault(tuple(repr(r.get(k)) for k in params), []).append(r)
    rows = []
    for group in groups.values():
        if len({r.get("cfl") for r in group}) < 2:
            continue
        for r in sorted(group, key=lambda r: -float(r["cfl"])):
            rows.append({"model": label({**r, "cfl": DEFAULT_CFL}),
                         "stabilization": "on" if r["stabilization"] else "off",
                         "cfl": r["cfl"], "stabilization_re": stabilization_re(r),
                         **{m: r.get(m) for m in HEADLINE_METRICS}})
    return pd.DataFrame(rows).set_index(["model", "stabilization", "cfl"]) if rows \
        else pd.DataFrame()


def tables(records: list[dict[str, Any]],
           unc: NumericalUncertainty | None = None) -> dict[str, pd.DataFrame]:
    out: dict[str, pd.DataFrame] = {}
    if unc is not None:
        head = headline_table(records, unc)
        if not head.empty:
            out["headline_with_u_num"] = head
    out.update({"noise": noise_table(records), "plate_cp": run_table(records)})
    dt = dt_table(records)
    if not dt.empty:
        out["time_step"] = dt
    coll = collision_table(records)
    if not coll.empty:
        out["collision"] = coll
    return out
