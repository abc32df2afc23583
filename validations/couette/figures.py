"""Couette figures: profiles against the series solution, the shape of the error across the
gap, error against r_e/l0, convergence in l0 and the refinement sets of the headline cell."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import analysis as an
from mpsbench.cases import plotting as pl

from ..paper import RE_RATIOS
from .analysis import _default_walls, _treatment_groups, convergence_table, grid
from .metrics import END_TIME, TIMES, L, U, series


def figures(records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
            outdir: Path, unc: Any = None) -> list[Path]:
    df = grid(an.completed(records))
    if df.empty:
        return []
    out: list[Path | None] = []
    finest = df["n"].max()
    for key, g in _treatment_groups(df):
        if g["n"].iloc[0] == finest:
            out.append(_fig_profiles(g, arrays, outdir, key))
            out.append(_fig_error_profiles(g, arrays, outdir, key))
    out.append(_fig_error_vs_re(df[df["n"] == finest], outdir, finest))
    if df["n"].nunique() > 1:
        out.append(_fig_convergence(df, outdir))
    if unc is not None:
        out.append(pl.refinement_figure(
            [s for s in unc.sets if len(s.run_ids) > 2 or s.kind == "dt"],
            "Couette: refinement sets of the t = 0.1125 s error (extrapolated value and u_num "
            "band where converged; docs/method.md section 9)", outdir / "refinement.png"))
    return [p for p in out if p is not None]


def _pick(g: pd.DataFrame, weight: str = "wf2", re: float = 3.1) -> tuple[pd.DataFrame, str, float]:
    w = weight if weight in set(g["weight"]) else g["weight"].iloc[0]
    sub = g[g["weight"] == w]
    r = min(sub["re_ratio"].unique(), key=lambda x: abs(x - re))
    return sub[np.isclose(sub["re_ratio"], r)], w, float(r)


def _fig_profiles(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path,
                  key: str) -> Path | None:
    sub, w, re = _pick(g)
    models = sorted(sub["laplacian"].unique(), key=an.model_sort_key)
    fig, axes = pl.figure(1, len(models), width=3.8, height=4.2)
    yy = np.linspace(0.0, L, 201)
    colours = ["tab:blue", "tab:orange", "tab:green", "k"]
    for col, model in enumerate(models):
        ax = axes[0, col]
        run_rec = sub[sub["laplacian"] == model].iloc[0]
        data = arrays(str(run_rec["run_id"]))
        for k, t in enumerate(TIMES):
            ax.plot(series(yy, t) / U, yy / L, "-", color=colours[k], lw=1,
                    label=f"exact t = {t:g} s")
            if "u" in data:
                ax.plot(data["u"][k] / U, data["y"] / L, "o", ms=3, color=colours[k], mfc="none")
        ax.plot(yy / L, yy / L, "-", color="k", lw=1, label="exact steady")
        if "u_steady" in data:
            ax.plot(data["u_steady"] / U, data["y"] / L, "o", ms=3, color="k", mfc="none")
        ax.set_title(f"{model}\nL2 error at {END_TIME:g} s: {an.pct(run_rec['l2_error'])}",
                     fontsize=9)
        ax.set_xlabel("u / U")
        ax.set_xlim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("y / L")
    axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Couette: u(y) (circles: particles, lines: series solution); {w}, "
                 f"r_e/l0 = {re:g}, {key.replace('_', ', ').replace('L-', 'L/')} walls")
    return pl.save(fig, outdir / f"profiles_{key}.png")


def _fig_error_profiles(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]],
                        outdir: Path, key: str) -> Path | None:
    """The shape of the error across the gap, e(y) / max|e|, per model (legend: max|e| / U)."""
    weights = sorted(g["weight"].unique())
    fig, axes = pl.figure(1, len(weights), width=5.0, height=4.2)
    for col, w in enumerate(weights):
        sub, _, re = _pick(g, w)
        ax = axes[0, col]
        for model in sorted(sub["laplacian"].unique(), key=an.model_sort_key):
            rec = sub[sub["laplacian"] == model].iloc[0]
            data = arrays(str(rec["run_id"]))
            if "u" not in data:
                continue
            err = (data["u"][-1] - series(data["y"], END_TIME)) / U
            top = float(np.max(np.abs(err))) or 1.0
            ax.plot(err / top, data["y"] / L, "-o", ms=2.5, color=pl.colour(model),
                    label=f"{model} (max |e| = {top:.2g} U, {100 * rec['wall_error_share']:.0f}%"
                          " of e^2 in grey)")
        l0 = float(sub["l0"].iloc[0])
        band = re * l0 / L
        for lo, hi in ((0.0, band), (1.0 - band, 1.0)):
            ax.axhspan(lo, hi, color="0.85", zorder=0)
        ax.axvline(0.0, color="k", lw=0.7)
        ax.set_xlim(-1.05, 1.05)
        ax.set_xlabel(f"(u - u_exact) / max|u - u_exact| at t = {END_TIME:g} s")
        ax.set_title(f"{w}, r_e/l0 = {re:g} (grey: within r_e of a plate)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=1)
    axes[0, 0].set_ylabel("y / L")
    fig.suptitle(f"Couette: shape of the error across the gap, "
                 f"{key.replace('_', ', ').replace('L-', 'L/')} walls")
    return pl.save(fig, outdir / f"error_profiles_{key}.png")


def _fig_error_vs_re(df: pd.DataFrame, outdir: Path, n: int) -> Path:
    groups = [(k, g) for k, g in _treatment_groups(df)]
    fig, axes = pl.figure(1, len(groups), width=5.2)
    for col, (key, g) in enumerate(groups):
        ax = axes[0, col]
        pl.plot_vs_re(ax, g, "l2_error", radii=RE_RATIOS)
        ax.set_title(key.replace("_", ", ").replace("L-", "L/") + " walls")
        ax.set_ylabel(f"relative L2 error at t = {END_TIME:g} s")
    axes[0, -1].legend(fontsize=7)
    fig.suptitle(f"Couette: error against r_e/l0 per model and WF (L/{n})")
    return pl.save(fig, outdir / f"error_vs_re_L-{n}.png")


def _fig_convergence(df: pd.DataFrame, outdir: Path) -> Path | None:
    d = _default_walls(df)
    if d.empty or d["n"].nunique() < 2:
        return None
    return pl.convergence_figure(
        d, "l2_error", convergence_table(d),
        f"Couette: relative L2 error at t = {END_TIME:g} s against l0 (prescribed walls, "
        "wall row on the plate); legend: observed order", outdir / "convergence.png",
        whole=L, symbol="L", slope=1.0)
