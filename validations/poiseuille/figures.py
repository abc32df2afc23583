"""Poiseuille figures: profiles against the series solution, convergence in l0 and the
refinement set of the headline cell."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import analysis as an
from mpsbench.cases import plotting as pl

from .analysis import convergence_table, default_walls, grid
from .metrics import END_TIME, FLOW, TIMES, U_MAX, L


def figures(records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
            outdir: Path, unc: Any = None) -> list[Path]:
    df = default_walls(grid(an.completed(records)))
    if df.empty:
        return []
    out: list[Path | None] = [_fig_profiles(df[df["n"] == df["n"].max()], arrays, outdir)]
    if df["n"].nunique() > 1:
        out.append(pl.convergence_figure(
            df, "l2_error", convergence_table(df),
            f"Poiseuille: relative L2 error at t = {END_TIME:g} s against l0 (prescribed "
            "walls on the plates); legend: observed order", outdir / "convergence.png",
            whole=L, symbol="L", slope=1.0))
    if unc is not None:
        out.append(pl.refinement_figure(
            [s for s in unc.sets if len(s.run_ids) > 2],
            f"Poiseuille: refinement set of the t = {END_TIME:g} s error (u_num band where "
            "converged; docs/method.md section 9)", outdir / "refinement.png"))
    return [p for p in out if p is not None]


def _fig_profiles(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]],
                  outdir: Path) -> Path | None:
    g = g[(g["weight"] == "wf2") & np.isclose(g["re_ratio"], 3.1)]
    if g.empty:
        return None
    models = sorted(g["laplacian"].unique(), key=an.model_sort_key)
    fig, axes = pl.figure(1, len(models), width=3.6, height=4.4)
    yy = np.linspace(0.0, L, 201)
    colours = ["tab:blue", "tab:orange", "tab:green"]
    n = int(g["n"].iloc[0])
    for col, model in enumerate(models):
        ax = axes[0, col]
        rec = g[g["laplacian"] == model].iloc[0]
        data = arrays(str(rec["run_id"]))
        for k, t in enumerate(TIMES):
            ax.plot(FLOW.velocity(yy, t) / U_MAX, yy / L, "-", color=colours[k], lw=1,
                    label=f"series, t = {t:g} s")
            if "u" in data:
                ax.plot(data["u"][k] / U_MAX, data["y"] / L, "o", ms=3, mfc="none",
                        color=colours[k])
        ax.plot(FLOW.steady(yy) / U_MAX, yy / L, "-", color="k", lw=1, label="steady")
        if "u_steady" in data:
            ax.plot(data["u_steady"] / U_MAX, data["y"] / L, "o", ms=3, mfc="none", color="k")
        ax.set_title(f"{model}\nL2 error at {END_TIME:g} s: {an.pct(rec['l2_error'])}",
                     fontsize=9)
        ax.set_xlabel("u / u_max (u_max = 2.5e-5 m/s)")
        ax.set_xlim(-0.05, 1.3)
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("y / L")
    axes[0, 0].legend(fontsize=6, loc="upper right")  # the empty corner above the parabola
    fig.suptitle(f"Poiseuille: u(y) (circles: particles, lines: series), WF2, r_e/l0 = 3.1, "
                 f"L/{n}, prescribed walls")
    return pl.save(fig, outdir / f"profiles_L-{n}.png")
