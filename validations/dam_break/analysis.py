"""Dam break: gates, claims, tables and plain-word findings from the run records
(docs/method.md 6d, 8, 9).

Gates (they decide the exit status; tolerances unchanged): every run of the model grid
completes; the IWC-MPS surge-front RMS error (T <= 3) is below 0.3 at l0 <= 5 mm (Koshizuka &
Oka geometry).  The runs of the refinement grids (cfl 0.1) are reported with their status and
make their refinement sets "not converged" when they diverge (docs/method.md section 9): a
model that does not run through at a smaller time step is a finding about the model.

Validation (V&V 20, docs/method.md section 9): per metric E = S - D against
u_val = sqrt(u_num^2 + u_D^2), with u_num from the l0 and cfl refinement sets of the tier and
u_D the data's uncertainty (:mod:`mpsbench.validations.experiments`: half a mark spacing for
Martin & Moyce, the half-width of the 2.5-97.5 % band for Lobovsky et al.).

Claims: C6 (IWC-MPS agrees with the experiments: every validation verdict of its finest run of
each geometry) and C7 (IWC-MPS's wall-pressure noise at least halved against WC-MPS's).
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from mpsbench.cases import CaseCheck
from mpsbench.cases import analysis as an
from mpsbench.cases.checks import decide
from mpsbench.cases.refinement import NumericalUncertainty, validate
from mpsbench.cases.uncertainty import AGREES, MODEL_ERROR

from .. import experiments
from ..paper import C6, C7
from .geometry import GEOMETRIES

KO, LOB = "koshizuka-oka", "lobovsky"
FRONT_RMS_GATE = 0.3
GATE_L0 = 0.005  # m: the gate applies to IWC-MPS runs at this spacing or finer
DEFAULT_CFL = 0.2
NOISE_FACTOR = 2.0  # C7: "greatly eliminated" read as at least halved
SENSORS = (1, 2, 3, 4)
MODEL_COLUMNS = [
    "variant",
    "laplacian",
    "weight",
    "re_ratio",
    "gradient",
    "stabilization",
    "stabilization_walls",
    "stabilization_rate",
    "l0",
    "cfl",
]
KO_METRICS = (
    "front_rms_error",
    "front_mean_offset",
    "front_arrival_T",
    "height_rms_error",
    "height_mean_offset",
)
LOB_METRICS = tuple(f"peak_p_sensor{k}" for k in SENSORS)
# the defaults of the models a variant stands for (other values make a run a variation)
DEFAULT_MODELS = {
    "weight": "wf2",
    "re_ratio": 2.1,
    "gradient": "pgm1",
    "re_ratio_laplacian": 0.0,
    "gate_delay": 0.0,
    "stabilization_walls": True,
    "stabilization_rate": "step",
}

_num = an.num
_ok = an.is_completed


def label(r: dict[str, Any]) -> str:
    """A short model label: variant, and what differs from the variant's usual models."""
    parts = [str(r.get("variant"))]
    if r.get("variant") == "custom":
        parts.append(f"{r.get('laplacian')}{'+stab' if r.get('stabilization') else ''}")
    if r.get("weight") != "wf2":
        parts.append(str(r.get("weight")))
    if _num(r.get("re_ratio")) != 2.1:
        parts.append(f"re={r.get('re_ratio')}")
    if r.get("gradient") != "pgm1":
        parts.append(str(r.get("gradient")))
    if r.get("stabilization") and r.get("stabilization_walls") is False:
        parts.append("no-wall-stab")
    if r.get("stabilization") and r.get("stabilization_rate") == "acoustic":
        parts.append("acoustic-stab")
    if r.get("collision"):
        parts.append("collision")
    parts.append(f"l0={_num(r.get('l0')) * 1000:g}mm")
    if "cfl" in r and not an.matches(r, {"cfl": DEFAULT_CFL}):
        parts.append(f"cfl={_num(r.get('cfl')):g}")
    return " ".join(parts)


def own_models(geometry: Any) -> dict[str, Any]:
    """The settings of the variants' own models in ``geometry``: :data:`DEFAULT_MODELS` and the
    collision model as that geometry's tiers run it (``Geometry.collision``)."""
    geo = GEOMETRIES.get(str(geometry))
    return DEFAULT_MODELS | {"collision": geo.collision if geo else False}


def is_default(r: dict[str, Any], variant: str | None = None) -> bool:
    """A run of a variant's own models (no variation of the weight, gradient, walls...) in its
    geometry (:func:`own_models`)."""
    ok = r.get("variant") in (("wc-mps", "iwc-mps") if variant is None else (variant,))
    own = own_models(r.get("geometry"))
    return ok and all(r.get(k, v) == v for k, v in own.items())


def runs(
    records: list[dict[str, Any]],
    geometry: str,
    *,
    default_cfl: bool = False,
    default_models: bool = False,
) -> list[dict[str, Any]]:
    out = [r for r in an.completed_records(records) if r.get("geometry") == geometry]
    if default_cfl:
        out = [r for r in out if an.matches(r, {"cfl": DEFAULT_CFL})]
    if default_models:
        out = [r for r in out if is_default(r)]
    return sorted(
        out, key=lambda r: (-_num(r.get("l0")), str(r.get("variant")), -_num(r.get("cfl")))
    )


# ---------------------------------------------------------------------- gates
def gates(
    records: list[dict[str, Any]], model: list[dict[str, Any]] | None = None
) -> list[CaseCheck]:
    """The gates on the model grid ``model`` (default: all ``records``); the refinement runs
    that did not complete are named in the detail."""
    model = records if model is None else model
    ids = {r.get("run_id") for r in model}
    extra_bad = [r for r in records if not _ok(r) and r.get("run_id") not in ids]
    out = []
    bad = [r for r in model if not _ok(r)]
    detail = f"{len(model) - len(bad)}/{len(model)} runs of the model grid completed" + (
        "; " + "; ".join(f"{label(r)} ({r.get('geometry')}): {r.get('status')}" for r in bad)
        if bad
        else ""
    )
    if extra_bad:
        detail += "; refinement runs not completed (their sets are not converged): " + "; ".join(
            f"{label(r)}: {r.get('status')} ({r.get('reason', '')})" for r in extra_bad
        )
    out.append(CaseCheck("every run of the model grid completes (no divergence)", not bad, detail))
    gated = [
        r
        for r in model
        if r.get("geometry") == KO
        and r.get("variant") == "iwc-mps"
        and _num(r.get("l0")) <= GATE_L0 * (1 + 1e-9)
    ]
    done = [r for r in gated if _ok(r) and math.isfinite(_num(r.get("front_rms_error")))]
    name = f"IWC-MPS surge front RMS |Z - Z_exp| (T <= 3) < {FRONT_RMS_GATE} at l0 <= 5 mm"
    if not gated:
        out.append(
            CaseCheck(
                name,
                None,
                "no IWC-MPS Koshizuka-Oka run at l0 <= 5 mm in this "
                "study (the quick tier has them)",
            )
        )
    else:
        vals = [(label(r), _num(r.get("front_rms_error"))) for r in done]
        passed = len(done) == len(gated) and all(v < FRONT_RMS_GATE for _, v in vals)
        out.append(
            CaseCheck(
                name,
                passed,
                "; ".join(f"{n}: {v:.3f}" for n, v in vals) or "no completed run",
                runs=tuple(r["run_id"] for r in gated),
            )
        )
    return out


# ---------------------------------------------------------------------- validation
def validation_rows(
    records: list[dict[str, Any]], unc: NumericalUncertainty, runs_: list[dict[str, Any]]
) -> list[dict[str, Any]]:
    """E = S - D, u_num, u_D, u_val and the verdict of every validation metric of ``runs_``."""
    rows = []
    for r in runs_:
        if r.get("geometry") == KO:
            items = [
                ("front mean offset (Z)", "front_mean_offset", 0.0, experiments.MARTIN_MOYCE_U_Z),
                ("front RMS |Z - Z_exp|", "front_rms_error", 0.0, experiments.MARTIN_MOYCE_U_Z),
                (
                    "wall arrival T",
                    "front_arrival_T",
                    _num(r.get("front_arrival_T_exp")),
                    experiments.martin_moyce_u_T(_wall_z(r)),
                ),
                (
                    "height mean offset (H*)",
                    "height_mean_offset",
                    0.0,
                    experiments.MARTIN_MOYCE_U_H,
                ),
                ("height RMS |H* - H*_exp|", "height_rms_error", 0.0, experiments.MARTIN_MOYCE_U_H),
            ]
        else:
            band = experiments.lobovsky_bands()
            items = []
            for k in SENSORS:
                s = _num(r.get(f"peak_p_sensor{k}"))
                if math.isfinite(s):
                    items.append(
                        (
                            f"peak p* sensor {k}",
                            f"peak_p_sensor{k}",
                            float(band["median"][k - 1]),
                            experiments.lobovsky_u_peak(k, s),
                        )
                    )
        for name, metric, data, u_data in items:
            u = unc.of(r, metric)
            if not (math.isfinite(u.value) and math.isfinite(data)):
                continue
            v = validate(u, data, u_data)
            rows.append(
                {
                    "model": label(r),
                    "quantity": name,
                    "S": v.simulated,
                    "D": v.data,
                    "E": v.error,
                    "u_num": u.u_text(),
                    "u_D": v.u_data,
                    "u_val": v.u_val,
                    "verdict": v.verdict,
                    "run_id": r["run_id"],
                    "_converged": u.converged,
                }
            )
    return rows


def _wall_z(r: dict[str, Any]) -> float:
    """Z of the far wall: tank length / simulated column width."""
    return GEOMETRIES[KO].tank_length / _num(r.get("column_width"))


def finest(records: list[dict[str, Any]], geometry: str, variant: str) -> dict[str, Any] | None:
    """The finest run of a variant's own models at the default cfl."""
    cands = [r for r in runs(records, geometry, default_cfl=True) if is_default(r, variant)]
    return min(cands, key=lambda r: _num(r.get("l0"))) if cands else None


# ---------------------------------------------------------------------- claims
def claims(records: list[dict[str, Any]], unc: NumericalUncertainty) -> list[CaseCheck]:
    return [_c6(records, unc), _c7(records)]


def _c6(records: list[dict[str, Any]], unc: NumericalUncertainty) -> CaseCheck:
    rule = (
        "IWC-MPS (its own models, default cfl; Lobovsky: collision model on), finest l0 of "
        "each geometry: every "
        "validation metric (Martin & Moyce front offset, front RMS, wall arrival T, height "
        "offset and RMS; Lobovsky first-impact peaks) agrees within u_val = sqrt(u_num^2 + "
        "u_D^2) (supported); one with |E| > u_val and a converged u_num refutes; otherwise "
        "(u_num not converged or not measured) inconclusive"
    )
    chosen = [r for r in (finest(records, g, "iwc-mps") for g in (KO, LOB)) if r is not None]
    rows = validation_rows(records, unc, chosen)
    if not rows:
        return C6.no_data(rule, "IWC-MPS runs of the dam break")
    outcomes = [
        True
        if row["verdict"] == AGREES
        else False
        if row["verdict"] == MODEL_ERROR and row["_converged"]
        else None
        for row in rows
    ]
    counts: dict[str, int] = {}
    for row in rows:
        counts[row["verdict"]] = counts.get(row["verdict"], 0) + 1
    decisive = [
        f"{row['quantity']} ({row['model']}): E = {row['E']:+.3g}, u_val = "
        f"{an.fmt(row['u_val'])}"
        + ("" if row["verdict"] == MODEL_ERROR else f" ({row['verdict']})")
        for row in rows
        if row["verdict"] != AGREES
    ]
    agree = [
        f"{row['quantity']} E = {row['E']:+.3g} (u_val {an.fmt(row['u_val'])})"
        for row in rows
        if row["verdict"] == AGREES
    ]
    words = {AGREES: "agree within u_val", MODEL_ERROR: "model error"}
    text = (
        f"{an.plural(len(rows), 'metric')}: "
        + ", ".join(f"{n} {words.get(v, v)}" for v, n in counts.items())
        + (f". Not agreeing: {'; '.join(decisive)}" if decisive else "")
        + (f". Agreeing: {'; '.join(agree)}" if agree else "")
    )
    return C6.verdict(decide(outcomes), rule, text, [r["run_id"] for r in chosen])


def _c7(records: list[dict[str, Any]]) -> CaseCheck:
    rule = (
        f"Lobovsky geometry, each l0 with both variants (own models, collision model on, "
        f"default cfl): the "
        f"post-impact wall-pressure noise of WC-MPS at least {NOISE_FACTOR:g} times "
        "IWC-MPS's at every sensor"
    )
    lob = runs(records, LOB, default_cfl=True, default_models=True)
    by_l0: dict[float, dict[str, dict[str, Any]]] = {}
    for r in lob:
        by_l0.setdefault(_num(r.get("l0")), {})[str(r["variant"])] = r
    pairs = [(v["wc-mps"], v["iwc-mps"]) for v in by_l0.values() if len(v) == 2]
    if not pairs:
        return C7.no_data(rule, "WC-MPS and IWC-MPS runs of the Lobovsky geometry")
    outcomes, parts = [], []
    for wc, iwc in pairs:
        fs = []
        for k in SENSORS:
            a, b = _num(wc.get(f"noise_sensor{k}")), _num(iwc.get(f"noise_sensor{k}"))
            f = a / b if math.isfinite(a) and math.isfinite(b) and b > 0 else math.nan
            fs.append(f)
            outcomes.append(f >= NOISE_FACTOR if math.isfinite(f) else None)
        parts.append(
            f"l0 = {_num(wc['l0']) * 1000:g} mm: WC/IWC noise "
            + ", ".join(an.fmt(f, 3) for f in fs)
            + " (sensors 1-4)"
        )
    return C7.verdict(
        decide(outcomes), rule, "; ".join(parts), [r["run_id"] for p in pairs for r in p]
    )


# ---------------------------------------------------------------------- tables
def _ko_table(records: list[dict[str, Any]]) -> pd.DataFrame:
    rows = []
    for r in runs(records, KO):
        row = {c: r.get(c) for c in MODEL_COLUMNS}
        for c in (
            "front_rms_error",
            "front_max_error",
            "front_mean_offset",
            "front_arrival_T",
            "front_arrival_T_exp",
            "height_rms_error",
            "height_mean_offset",
            "wall_time_s",
        ):
            row[c] = r.get(c)
        rows.append(row)
    return pd.DataFrame(rows)


def headline_table(records: list[dict[str, Any]], unc: NumericalUncertainty) -> pd.DataFrame:
    """Both variants (own models) at every l0 and cfl of the tier: the Martin & Moyce metrics
    with their u_num (l0 and dt components)."""
    rows = []
    for r in runs(records, KO, default_models=True):
        row: dict[str, Any] = {"model": label(r)}
        row.update({m: unc.of(r, m).text() for m in KO_METRICS})
        rows.append(row)
    return pd.DataFrame(rows).set_index("model") if rows else pd.DataFrame()


def time_step_table(records: list[dict[str, Any]]) -> pd.DataFrame:
    """The runs that differ only in cfl (the dt refinement of the headline models), with
    their status: a run that diverged after the measured windows still has its metrics."""
    every = sorted(
        (r for r in records if r.get("geometry") == KO and is_default(r)),
        key=lambda r: (str(r.get("variant")), -_num(r.get("l0")), -_num(r.get("cfl"))),
    )
    rows = []
    for r in every:
        same = [q for q in every if q["variant"] == r["variant"] and an.matches(q, {"l0": r["l0"]})]
        if len({q.get("cfl") for q in same}) < 2:
            continue
        rows.append(
            {
                "variant": r["variant"],
                "l0 [mm]": _num(r["l0"]) * 1000,
                "cfl": r["cfl"],
                "status": r.get("status"),
                **{m: r.get(m) for m in KO_METRICS},
                "wall_time_s": r.get("wall_time_s"),
                "reason": r.get("reason") or "",
            }
        )
    return pd.DataFrame(rows).set_index(["variant", "l0 [mm]", "cfl"]) if rows else pd.DataFrame()


def _lob_table(records: list[dict[str, Any]]) -> pd.DataFrame:
    band = experiments.lobovsky_bands()
    rows = []
    for r in runs(records, LOB):
        for k in range(4):
            s = k + 1
            rows.append(
                {
                    "model": label(r),
                    "sensor": s,
                    "z_mm": band["z"][k] * 1000,
                    "peak_p*": r.get(f"peak_p_sensor{s}"),
                    "peak_p*_1ms": r.get(f"peak_p_filtered_sensor{s}"),
                    "t*_peak": r.get(f"peak_tstar_sensor{s}"),
                    "exp_2.5%": band["lo"][k],
                    "exp_median": band["median"][k],
                    "exp_97.5%": band["hi"][k],
                    "in_band": r.get(f"in_band_sensor{s}"),
                    "noise": r.get(f"noise_sensor{s}"),
                    "t*_impact": r.get("impact_tstar"),
                }
            )
    return pd.DataFrame(rows)


def tables(records: list[dict[str, Any]], unc: NumericalUncertainty) -> dict[str, pd.DataFrame]:
    out = {}
    head = headline_table(records, unc)
    if not head.empty:
        out["surge_front_with_u_num"] = head
    dt = time_step_table(records)
    if not dt.empty:
        out["time_step"] = dt
    chosen = [
        r
        for v in ("wc-mps", "iwc-mps")
        for g in (KO, LOB)
        if (r := finest(records, g, v)) is not None
    ]
    val = pd.DataFrame(validation_rows(records, unc, chosen))
    if not val.empty:
        out["validation"] = val.drop(columns=["_converged", "run_id"]).set_index(
            ["model", "quantity"]
        )
    ko = _ko_table(records)
    if not ko.empty:
        out["surge_front_errors"] = ko
    lob = _lob_table(records)
    if not lob.empty:
        out["impact_pressure"] = lob
    return out


# ---------------------------------------------------------------------- findings
def _fmt(v: Any, spec: str = ".3f") -> str:
    f = _num(v)
    return format(f, spec) if math.isfinite(f) else "n/a"


def findings(records: list[dict[str, Any]], unc: NumericalUncertainty) -> str:
    lines: list[str] = []
    ko = runs(records, KO)
    if ko:
        exp_arrival = next((r.get("front_arrival_T_exp") for r in ko), None)
        lines.append(
            "**Surge front (Martin & Moyce, T <= 3).** RMS and max of |Z - Z_exp|, the signed mean "
            "offset (> 0: the simulated front runs ahead of the experiment) and the time T at "
            f"which the front reaches the far wall (experiment: T = {_fmt(exp_arrival, '.2f')}; "
            "published particle simulations run 0.2-0.3 ahead in Z, partly the gate opening). "
            "A small RMS with a negative offset and a late arrival is a damped front, not a "
            "better model.  Each number carries its u_num (l0 and dt refinement sets, "
            "docs/method.md section 9)."
        )
        lines.append("")
        for r in ko:
            lines.append(
                f"- {label(r)}: front RMS {unc.of(r, 'front_rms_error').text()}, max "
                f"{_fmt(r.get('front_max_error'))}, mean offset "
                f"{unc.of(r, 'front_mean_offset').text()}, arrival T "
                f"{unc.of(r, 'front_arrival_T').text()}; column height H* RMS "
                f"{unc.of(r, 'height_rms_error').text()} (offset "
                f"{unc.of(r, 'height_mean_offset').text()})."
            )
        lines += _time_step_lines(records)
        held = [r for r in ko if _num(r.get("height_mean_offset")) > 0.1]
        if held:
            walls = all(r.get("stabilization") and r.get("stabilization_walls") for r in held)
            lines.append("")
            lines.append(
                f"The column height stays well above the experiment (H* offset > 0.1) in "
                f"{', '.join(label(r) for r in held)}: the water is held at the back wall"
                + (
                    " by the stabilization summing over wall particles (it acts as wall friction; "
                    "compare stabilization_walls = false)"
                    if walls
                    else ""
                )
                + ", so a small front error there is partly a damped front."
            )
        lines.append("")
    lines += _validation_lines(records, unc)
    lob = runs(records, LOB)
    if lob:
        lines.append(
            "**Impact pressure (Lobovsky et al., first impact).** Peak p* per sensor against the "
            "measured 2.5-97.5 % band over 100 repeats; noise = RMS of p* minus its moving "
            "average after the impact. Sensors 1 (3 mm) and 2 (15 mm) lie within one kernel "
            "radius of each other at l0 >= 6 mm, so they are not independent measurements there. "
            "Where the surge reaches the wall as a spray of single particles (coarse l0, see the "
            "snapshots), each particle hitting the wall gives a spike: the peak then measures "
            "those spikes more than the impact, and inside-the-band or not is largely chance; "
            "read it with the 1 ms filtered peak (table) and the noise."
        )
        lines.append("")
        for r in lob:
            inside = [str(k) for k in SENSORS if r.get(f"in_band_sensor{k}") is True]
            peaks = ", ".join(unc.of(r, f"peak_p_sensor{k}").text() for k in SENSORS)
            noise = ", ".join(_fmt(r.get(f"noise_sensor{k}"), ".2f") for k in SENSORS)
            lines.append(
                f"- {label(r)}: peak p* (sensors 1-4) = {peaks}; inside the band: "
                f"{', '.join(inside) if inside else 'none'}; noise {noise}; impact at t* = "
                f"{_fmt(r.get('impact_tstar'), '.2f')}."
            )
    return "\n".join(lines)


def _time_step_lines(records: list[dict[str, Any]]) -> list[str]:
    """The dt refinement the tier measured, in words (a finding, not hidden)."""
    table = time_step_table(records)
    if table.empty:
        return []
    out = [
        "",
        "**Time step** (the same runs at smaller cfl; the stabilization is applied once "
        "per step, so its added viscosity grows as dt shrinks, docs/method.md section 5):",
        "",
    ]
    for (variant, l0), g in table.groupby(level=[0, 1], sort=False):
        cells = [
            f"cfl {cfl:g}: front RMS {_fmt(row['front_rms_error'])}, offset "
            f"{_fmt(row['front_mean_offset'], '+.3f')}, arrival T "
            f"{_fmt(row['front_arrival_T'], '.2f')}, height offset "
            f"{_fmt(row['height_mean_offset'], '+.3f')}"
            + (
                ""
                if row["status"] == "completed"
                else f" (the run then {row['status']}: {row['reason']}; its sets are not converged)"
            )
            for cfl, row in g.reset_index().set_index("cfl").iterrows()
        ]
        out.append(f"- {variant}, l0 = {l0:g} mm: " + "; ".join(cells) + ".")
    return out


def _validation_lines(records: list[dict[str, Any]], unc: NumericalUncertainty) -> list[str]:
    chosen = [
        r
        for v in ("wc-mps", "iwc-mps")
        for g in (KO, LOB)
        if (r := finest(records, g, v)) is not None
    ]
    rows = validation_rows(records, unc, chosen)
    if not rows:
        return []
    out = [
        "**Validation** (E = S - D against u_val = sqrt(u_num^2 + u_D^2); u_D: half a mark "
        f"spacing of Martin & Moyce, {experiments.MARTIN_MOYCE_U_Z:.3f} in Z and "
        f"{experiments.MARTIN_MOYCE_U_H:.3f} in H*; Lobovsky: the half-band on the side of "
        "S; table `validation`):",
        "",
    ]
    for model in dict.fromkeys(row["model"] for row in rows):
        cells = [
            f"{row['quantity']} E = {row['E']:+.3g} (u_val {an.fmt(row['u_val'])}): "
            f"{row['verdict']}"
            for row in rows
            if row["model"] == model
        ]
        out.append(f"- {model}: " + "; ".join(cells) + ".")
    return out + [""]
