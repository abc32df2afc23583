"""Figures of the water-jet study (matplotlib, Agg): snapshots, plate Cp, histories, noise."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .analysis import (
    collision_groups,
    completed,
    is_default_stabilization,
    label,
    pairs,
    resolution,
)
from .metrics import TABLE_CP, TABLE_XB, free_streamline_cp

CP_MAX_COLOUR = 1.5  # colour scale of the snapshots: Cp in [0, 1.5]


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figures(
    records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path
) -> list[Path]:
    out: list[Path] = []
    prs = [p for p in pairs(records) if not p[0].get("collision_distance")]
    # the plate profile shows every run without a collision model, paired with an
    # unstabilized twin or not (the b/40 and alpha_s runs of the quick tier are not)
    plain = [r for r in completed(records) if not r.get("collision_distance")]
    for path in (_snapshots(prs, arrays, outdir), _plate_cp(plain, arrays, outdir),
                 _histories(prs, arrays, outdir)):
        if path is not None:
            out.append(path)
    path = _noise_bars(pairs(records), outdir)
    if path is not None:
        out.append(path)
    path = _collision(records, outdir)
    if path is not None:
        out.append(path)
    return out


def _finest(prs: list[tuple[dict[str, Any], dict[str, Any]]]) -> list[tuple[dict, dict]]:
    """For each gradient model, the WF2 pair at the finest resolution (else any weight),
    preferring the default stabilization settings."""

    def score(p: tuple[dict, dict]) -> tuple[bool, bool, int]:
        return (is_default_stabilization(p[1]), p[0]["weight"] == "wf2", resolution(p[0]))

    best: dict[str, tuple[dict, dict]] = {}
    for pair in prs:
        g = pair[0]["gradient"]
        if g not in best or score(pair) > score(best[g]):
            best[g] = pair
    return [best[g] for g in sorted(best)]


def _snapshots(prs: list, arrays: Callable, outdir: Path) -> Path | None:
    chosen = [p for p in _finest(prs) if "snap_pos" in arrays(p[0]["run_id"])
              and "snap_pos" in arrays(p[1]["run_id"])]
    if not chosen:
        return None
    plt = _plt()
    n = len(chosen)
    fig, axes = plt.subplots(n, 2, figsize=(11, 2.9 * n), squeeze=False, constrained_layout=True)
    sc = None
    for row, (off, on) in enumerate(chosen):
        for col, rec in enumerate((off, on)):
            a = arrays(rec["run_id"])
            ax = axes[row, col]
            pos, cp, kind = a["snap_pos"], a["snap_cp"], a["snap_kind"]
            bnd = kind != 0
            ax.scatter(pos[bnd, 0], pos[bnd, 1], s=2, c="0.6", marker="s", linewidths=0)
            fl = ~bnd
            size = 60.0 / resolution(rec)
            sc = ax.scatter(pos[fl, 0], pos[fl, 1], s=size, c=cp[fl], cmap="viridis",
                            vmin=0.0, vmax=CP_MAX_COLOUR, linewidths=0)
            ax.set_aspect("equal")
            ax.set_xlim(-3.1, 3.1)
            ax.set_ylim(-0.5, 2.5)
            t = float(a["snap_t_over_T"][0])
            state = "on" if rec["stabilization"] else "off"
            ax.set_title(f"{label(rec)}, stabilization {state}, t = {t:.2f} b/U", fontsize=9)
            ax.set_xlabel("x / b")
            ax.set_ylabel("y / b")
    if sc is not None:
        fig.colorbar(sc, ax=axes, shrink=0.8, label="Cp = p / (rho U^2 / 2)")
    path = outdir / "snapshots_pressure.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _plate_cp(records: list[dict[str, Any]], arrays: Callable, outdir: Path) -> Path | None:
    recs = {rec["run_id"]: rec for rec in records}
    grads = sorted({r["gradient"] for r in recs.values()})
    if not grads:
        return None
    plt = _plt()
    fig, axes = plt.subplots(1, len(grads), figsize=(4.8 * len(grads), 4.0), squeeze=False,
                             sharey=True, constrained_layout=True)
    x = np.linspace(0.0, 2.5, 251)
    order = sorted(recs.values(), key=lambda r: (resolution(r), r["weight"], label(r),
                                                 bool(r["stabilization"])))
    for ax, g in zip(axes[0], grads, strict=True):
        ax.plot(x, free_streamline_cp(x), "k-", lw=2, label="free streamline (exact)")
        ax.plot(TABLE_XB, TABLE_CP, "ko", ms=3, label="docs/method.md table")
        for rec in order:
            a = arrays(rec["run_id"])
            if rec["gradient"] != g or "plate_cp" not in a:
                continue
            state = "on" if rec["stabilization"] else "off"
            err = rec.get("cp_rms_error")
            ax.plot(a["plate_xb"], a["plate_cp"], "-" if rec["stabilization"] else "--",
                    marker=".", ms=3, lw=1,
                    label=f"{label(rec).split(', ', 1)[1]}, stab {state} (err "
                    f"{err if err is not None else math.nan:.3f})")
        ax.axvspan(2.0, 2.5, color="0.92", zorder=0)
        ax.set_title(f"plate Cp, {g}")
        ax.set_xlabel("x / b")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="upper right")
    axes[0, 0].set_ylabel("Cp (time mean over the window)")
    # room above the curves for the longest legend (a row per line), so it hides none of them
    lines = [line for ax in axes[0] for line in ax.get_lines()]
    top = max([1.05] + [float(np.nanmax(line.get_ydata())) for line in lines])
    rows = max(len(ax.get_lines()) for ax in axes[0])
    axes[0, 0].set_ylim(-0.05, top + 0.06 * rows)
    path = outdir / "plate_cp.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _histories(prs: list, arrays: Callable, outdir: Path) -> Path | None:
    chosen = _finest(prs)
    if not chosen:
        return None
    plt = _plt()
    fig, axes = plt.subplots(len(chosen), 1, figsize=(8, 2.6 * len(chosen)), squeeze=False,
                             sharex=True, constrained_layout=True)
    for ax, (off, on) in zip(axes[:, 0], chosen, strict=True):
        for rec, colour in ((off, "tab:red"), (on, "tab:blue")):
            a = arrays(rec["run_id"])
            if "hist_cp0" not in a:
                continue
            state = "on" if rec["stabilization"] else "off"
            ax.plot(a["hist_t_over_T"], a["hist_cp0"], color=colour, lw=0.8,
                    label=f"stabilization {state} (std/mean {rec.get('noise_temporal') or 0:.2f})")
        t0 = off["t_end"] - off["t_window"]
        ax.axvspan(t0, off["t_end"], color="0.9", zorder=0, label="averaging window")
        ax.axhline(1.0, color="k", lw=0.8, ls=":")
        ax.set_ylim(0.0, 4.0)  # the impact spike at t ~ 0 goes far above: clipped
        ax.set_ylabel("Cp at x = 0")
        ax.set_title(f"stagnation pressure history, {label(off)}", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("t U / b")
    path = outdir / "stagnation_history.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _noise_bars(prs: list, outdir: Path) -> Path | None:
    if not prs:
        return None
    plt = _plt()
    measures = [("noise_spatial", "spatial noise"), ("noise_temporal", "temporal noise"),
                ("density_drift_mean", "mean |n/n0 - 1|")]
    fig, axes = plt.subplots(1, 3, figsize=(13, 0.9 + 0.35 * len(prs)), constrained_layout=True)
    y = np.arange(len(prs))
    names = [label(on) for _, on in prs]
    for ax, (m, title) in zip(axes, measures, strict=True):
        off = [p[0].get(m) or 0.0 for p in prs]
        on = [p[1].get(m) or 0.0 for p in prs]
        ax.barh(y - 0.2, off, 0.4, color="tab:red", label="stabilization off")
        ax.barh(y + 0.2, on, 0.4, color="tab:blue", label="stabilization on")
        ax.set_yticks(y, names if ax is axes[0] else [""] * len(y), fontsize=7)
        ax.invert_yaxis()
        ax.set_title(title)
        ax.grid(axis="x", alpha=0.3)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3))
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=2, fontsize=8)
    path = outdir / "noise.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _collision(records: list[dict[str, Any]], outdir: Path) -> Path | None:
    groups = collision_groups(completed(records))
    if not groups:
        return None
    plt = _plt()
    panels = [("noise_spatial", "spatial noise"), ("noise_temporal", "temporal noise"),
              ("density_drift_max", "max |n/n0 - 1|"), ("penetrations", "penetrations")]
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.2), constrained_layout=True)
    for group in groups.values():
        r0 = group[0]
        name = (f"{r0['gradient']} {r0['weight'].upper()} b/{resolution(r0)} "
                f"stab {'on' if r0['stabilization'] else 'off'}")
        ac = [r.get("collision_distance") or 0.0 for r in group]
        for ax, (m, title) in zip(axes, panels, strict=True):
            ax.plot(ac, [r.get(m) if r.get(m) is not None else np.nan for r in group], "o-",
                    label=name)
            ax.set_title(title)
            ax.set_xlabel("collision distance alpha_c (0 = off)")
            ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    path = outdir / "collision_distance.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
