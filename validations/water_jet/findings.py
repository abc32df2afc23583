"""Water jet: the findings in plain words (docs/method.md 6c): what the stabilization does to
the noise and to the plate pressure, where the plate pressure comes from, the time step, the
resolution and alpha_s trends, the collision distance."""

from __future__ import annotations

import math
from typing import Any

from mpsbench.cases import analysis as an
from mpsbench.cases.refinement import NumericalUncertainty, UNum

from .analysis import (
    CP_LIMIT,
    DEFAULT_ALPHA_S,
    NOISE_MEASURES,
    collision_groups,
    completed,
    default_cfl,
    dt_table,
    factor,
    fmt,
    is_acceptance,
    is_default_stabilization,
    label,
    pairs,
    resolution,
    stabilization_re,
)


def _effect(name: str, off: Any, on: Any) -> str:
    f = factor(off, on)
    if not math.isfinite(f):
        return f"{name}: n/a"
    if f > 1.05:
        verdict = f"reduced by a factor {f:.2f}"
    elif f < 1 / 1.05:
        verdict = f"NOT reduced: it grows by a factor {1 / f:.2f}"
    else:
        verdict = "about unchanged"
    return f"{name} {fmt(off)} -> {fmt(on)} ({verdict})"


def findings(records: list[dict[str, Any]], unc: NumericalUncertainty | None = None) -> str:
    lines: list[str] = []
    prs = [p for p in pairs(records) if not p[0].get("collision_distance")]
    if prs:
        lines += ["**What the stabilization does to the noise** (off -> on; factor = off/on):", ""]
        for off, on in prs:
            parts = [_effect(NOISE_MEASURES[m], off.get(m), on.get(m)) for m in NOISE_MEASURES]
            pen = f"penetrations {off.get('penetrations')} -> {on.get('penetrations')}"
            lines.append(f"- {label(on)}: " + "; ".join(parts) + f"; {pen}.")
        lines.append("")
        lines += ["**What it does to the plate pressure** (Cp RMS error over 0 <= x/b <= 2, "
                  "stagnation Cp, sheet speed / U at 1.5-2.5 b; exact: 0, 1, 1). The "
                  "stabilization is applied once per step, so it adds a viscosity "
                  "nu_s = alpha_s l0 sum|W'| r^2 / (4 n0 dt) that grows as dt shrinks; "
                  "Re_s = U b / nu_s below (water: 1e5):", ""]
        for off, on in prs:
            lines.append(
                f"- {label(on)}: off {fmt(off.get('cp_rms_error'))}, "
                f"{fmt(off.get('cp_stagnation'))}, {fmt(off.get('sheet_speed'))}; "
                f"on {fmt(on.get('cp_rms_error'))}, {fmt(on.get('cp_stagnation'))}, "
                f"{fmt(on.get('sheet_speed'))} (Re_s {fmt(stabilization_re(on))})."
            )
        lines.append("")
        lines += _pressure_source_note(prs)
        lines += _wall_neighbour_note(prs)
    lines += _stabilization_trend_note(records)
    groups = collision_groups(records)
    if groups:
        lines += ["**What the collision distance alpha_c does** (0 = no collision model; "
                  "noise = spatial / temporal; 'acts on' = share of fluid particles in the "
                  "impingement zone whose nearest neighbour is closer than alpha_c l0):", ""]
        for group in groups.values():
            r0 = group[0]
            head = (f"{r0['gradient']}, {r0['weight'].upper()}, b/{resolution(r0)}, "
                    f"stabilization {'on' if r0['stabilization'] else 'off'}")
            cells = [
                f"alpha_c {r.get('collision_distance') or 0:g}: noise {fmt(r.get('noise_spatial'))}"
                f" / {fmt(r.get('noise_temporal'))}, drift mean "
                f"{fmt(r.get('density_drift_mean'))}, penetrations {r.get('penetrations')}, "
                f"Cp error {fmt(r.get('cp_rms_error'))}, nearest neighbour "
                f"{fmt(r.get('nn_distance_mean'))} l0, acts on "
                f"{fmt(100 * (r.get('close_fraction') or 0.0), 2)}%"
                for r in group
            ]
            lines.append(f"- {head}: " + "; ".join(cells) + ".")
            lines.append(f"  {_collision_verdict(group)}")
        lines.append("")
    lines += _time_step_note(records)
    for r in (r for r in completed(records) if is_acceptance(r)):
        u = unc.of(r, "cp_rms_error") if unc is not None else UNum(an.num(r.get("cp_rms_error")))
        lines += [
            f"**Acceptance run** ({label(r)}, stabilization on): Cp RMS error {u.text()} "
            f"(claim C4b: below {CP_LIMIT:g}?); numerical uncertainty: {u.detail()}; "
            f"penetrations {r.get('penetrations')}.", ""]
    if lines:
        lines += ["", "Each number comes from one run and one averaging window; the temporal "
                  "measure especially scatters by tens of per cent between runs that differ "
                  "only slightly, so read factors near 1 as 'no clear effect'."]
    return "\n".join(lines)


def _time_step_note(records: list[dict[str, Any]]) -> list[str]:
    """What halving cfl does to the runs that differ only in cfl."""
    table = dt_table(records)
    if table.empty:
        return []
    out = ["**What the time step does** (cfl; the stabilization's added viscosity grows as dt "
           "shrinks, Re_s = U b / nu_s):", ""]
    for (model, state), g in table.groupby(level=[0, 1], sort=False):
        cells = [f"cfl {cfl:g}: Cp error {fmt(row['cp_rms_error'])}, stagnation "
                 f"{fmt(row['cp_stagnation'])}, spatial noise {fmt(row['noise_spatial'])}"
                 + (f", Re_s {fmt(row['stabilization_re'])}" if state == "on" else "")
                 for cfl, row in g.reset_index().set_index("cfl").iterrows()]
        out.append(f"- {model}, stabilization {state}: " + "; ".join(cells) + ".")
    return out + [""]


def _pressure_source_note(prs: list[tuple[dict[str, Any], dict[str, Any]]]) -> list[str]:
    """Plate force vs momentum flux, and clipped pressure vs compression, off -> on."""
    rows = [(off, on) for off, on in prs if on.get("plate_force") is not None]
    if not rows:
        return []
    out = ["**Where the plate pressure comes from.** Plate force / jet momentum flux (steady "
           "momentum balance: 1); for the fluid next to the plate (|x| <= b, two rows), the Cp it "
           "carries and the Cp its mean compression gives through the equation of state without "
           "clipping (carried >> compression: the pressure is clipped noise):", ""]
    for off, on in rows:
        out.append(
            f"- {label(on)}: off: force {fmt(off.get('plate_force'))}, carried "
            f"{fmt(off.get('near_wall_cp'))} vs compression {fmt(off.get('near_wall_cp_eos'))}; "
            f"on: force {fmt(on.get('plate_force'))}, carried {fmt(on.get('near_wall_cp'))} vs "
            f"compression {fmt(on.get('near_wall_cp_eos'))}.")
    out.append("")
    return out


def _stabilization_trend_note(records: list[dict[str, Any]]) -> list[str]:
    """Cp error of the stabilized pgm1/WF2 model (no collision) against l0 and alpha_s."""
    runs = [r for r in completed(records) if r.get("stabilization") and r.get("gradient") == "pgm1"
            and r.get("weight") == "wf2" and not r.get("collision_distance")
            and r.get("stabilization_walls", True) is not False and default_cfl(r)]
    by_l0 = sorted((r for r in runs if r.get("alpha_s") == DEFAULT_ALPHA_S), key=resolution)
    by_alpha = sorted((r for r in runs if resolution(r) == 20), key=lambda r: r["alpha_s"])
    out = []
    for group, what in ((by_l0, "resolution (alpha_s 0.01)"), (by_alpha, "alpha_s (b/20)")):
        if len(group) < 2:
            continue
        cells = [
            (f"b/{resolution(r)}" if what.startswith("res") else f"alpha_s {r['alpha_s']:g}")
            + f": Cp error {fmt(r.get('cp_rms_error'))}, Re_s {fmt(stabilization_re(r))}, sheet "
            f"{fmt(r.get('sheet_speed'))} U, force {fmt(r.get('plate_force'))}"
            for r in group]
        out.append(f"- against {what}: " + "; ".join(cells) + ".")
    if not out:
        return []
    return ["**The stabilized model (pgm1, WF2, wall neighbours) against resolution and "
            "alpha_s** (its added viscosity nu_s falls with l0 and with alpha_s):", "", *out, ""]


def _wall_neighbour_note(prs: list[tuple[dict[str, Any], dict[str, Any]]]) -> list[str]:
    """Compare the default stabilization with the one without wall neighbours, same model."""
    out = []
    for off, on in prs:
        if on.get("stabilization_walls", True) is not False or on.get("alpha_s") != 0.01:
            continue
        twin = [o for f, o in prs if f is off and is_default_stabilization(o)]
        if not twin:
            continue
        base = twin[0]
        re_s = stabilization_re(base)
        delta = math.sqrt(2.0 / re_s) if math.isfinite(re_s) and re_s > 0 else math.nan
        out += [
            f"Wall neighbours, {label(off)}: with the plate's wall and dummy particles in the "
            f"stabilization sum (default) the sheets run at {fmt(base.get('sheet_speed'))} U and "
            f"the Cp error is {fmt(base.get('cp_rms_error'))}; without them, at the same Re_s, "
            f"{fmt(on.get('sheet_speed'))} U and {fmt(on.get('cp_rms_error'))} (no "
            f"stabilization: {fmt(off.get('sheet_speed'))} U, {fmt(off.get('cp_rms_error'))}). "
            f"The slowing comes mostly from the plate acting as a no-slip wall for the "
            f"stabilization "
            f"viscosity (boundary layer sqrt(nu_s x / U) = {fmt(delta, 2)} b at x = 2 b, against "
            f"a sheet b/2 thick), not from the bulk.", ""]
    return out


def _collision_verdict(group: list[dict[str, Any]]) -> str:
    """One sentence on what the collision distance changed in a sweep (vs the smallest alpha_c)."""
    base = group[0]
    worst = max(group, key=lambda r: r.get("penetrations") or 0)
    pen = ("no particle crossed the plate at any alpha_c" if not worst.get("penetrations")
           else f"penetrations range {min(r.get('penetrations') or 0 for r in group)}-"
           f"{worst.get('penetrations')}")
    changes = []
    for m, name in (("noise_spatial", "spatial noise"), ("noise_temporal", "temporal noise"),
                    ("cp_rms_error", "Cp error")):
        vals = [(float(r.get("collision_distance") or 0.0), float(r[m])) for r in group
                if r.get(m) is not None and math.isfinite(r[m])]
        if len(vals) < 2 or not base.get(m):
            continue
        lo, hi = min(vals, key=lambda t: t[1]), max(vals, key=lambda t: t[1])
        changes.append(f"{name} {fmt(lo[1])} (alpha_c {lo[0]:g}) to {fmt(hi[1])} "
                       f"(alpha_c {hi[0]:g})")
    text = f"Verdict: {pen}; range over alpha_c: " + "; ".join(changes) + "."
    idle = [r for r in group[1:] if r.get("collision_distance") and r.get("close_fraction") == 0.0]
    if idle and not base.get("collision_distance"):
        r = idle[0]
        text += (
            f" alpha_c {r['collision_distance']:g} never had a pair that close in the window's "
            f"snapshots, so its differences from alpha_c 0 (spatial noise "
            f"{fmt(base.get('noise_spatial'))} vs {fmt(r.get('noise_spatial'))}, temporal "
            f"{fmt(base.get('noise_temporal'))} vs {fmt(r.get('noise_temporal'))}, Cp error "
            f"{fmt(base.get('cp_rms_error'))} vs {fmt(r.get('cp_rms_error'))}) show the "
            f"run-to-run scatter of a perturbed run.")
    return text
