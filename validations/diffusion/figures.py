"""Diffusion figures: error against r_e/l0, convergence in l0, decay-rate ratio, error maps."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import analysis as an
from mpsbench.cases import plotting as pl

from ..paper import RE_RATIOS
from .analysis import convergence_table, default_dt


def figures(records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
            outdir: Path, unc: Any = None) -> list[Path]:
    df = default_dt(an.completed(records))
    if df.empty:
        return []
    out: list[Path | None] = [
        _fig_error_vs_re(df, l0, outdir) for l0 in sorted(df["l0"].unique(), reverse=True)]
    out += [_fig_convergence(df, jit, outdir) for jit in sorted(df["jitter"].unique())
            if df[df["jitter"] == jit]["l0"].nunique() > 1]
    out.append(_fig_decay_ratio(df, outdir))
    out.append(_fig_error_maps(df, arrays, outdir))
    if unc is not None:
        out.append(pl.refinement_figure(
            [s for s in unc.sets if s.metric == "l2_error"],
            "Diffusion: refinement sets of the L2 error (extrapolated value and u_num band "
            "where converged; docs/method.md section 9)", outdir / "refinement.png"))
    return [p for p in out if p is not None]


def _fig_error_vs_re(df: pd.DataFrame, l0: float, outdir: Path) -> Path:
    sub = df[np.isclose(df["l0"], l0)]
    jitters = sorted(sub["jitter"].unique())
    fig, axes = pl.figure(len(jitters), 2, width=5.2)
    for row, jit in enumerate(jitters):
        g = sub[sub["jitter"] == jit]
        where = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
        pl.plot_vs_re(axes[row, 0], g, "l2_error", radii=RE_RATIOS)
        axes[row, 0].set_ylabel("relative L2 error at t_end")
        axes[row, 0].set_title(f"L2 error, l0 = {an.fraction(l0)}, {where}")
        pl.plot_vs_re(axes[row, 1], g, "linf_error", radii=RE_RATIOS)
        axes[row, 1].set_ylabel("relative Linf error at t_end")
        axes[row, 1].set_title(f"Linf error, l0 = {an.fraction(l0)}, {where}")
    axes[0, 1].legend(fontsize=7, loc="best")
    fig.suptitle("Diffusion: error against r_e/l0 per model and WF")
    return pl.save(fig, outdir / f"error_vs_re_l0-1_{round(1 / l0)}.png")


def _fig_convergence(df: pd.DataFrame, jit: float, outdir: Path) -> Path:
    sub = df[df["jitter"] == jit]
    where = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
    return pl.convergence_figure(
        sub, "l2_error", convergence_table(sub),
        f"Diffusion: relative L2 error at t_end against l0 ({where}); legend: observed order "
        "between the two finest l0", outdir / f"convergence_jitter-{jit:g}.png", slope=2.0)


def _fig_decay_ratio(df: pd.DataFrame, outdir: Path) -> Path:
    finest = df["l0"].min()
    jitters = sorted(df["jitter"].unique())
    fig, axes = pl.figure(1, len(jitters), width=5.0)
    for col, jit in enumerate(jitters):
        ax = axes[0, col]
        pl.plot_vs_re(ax, an.select(df, jitter=jit, l0=finest), "decay_ratio", log=False,
                        radii=RE_RATIOS)
        ax.axhline(1.0, color="k", lw=0.8)
        where = "regular lattice" if jit == 0 else f"jitter {jit:g} l0"
        ax.set_title(f"l0 = {an.fraction(finest)}, {where}")
        ax.set_ylabel("decay rate / exact rate")
    axes[0, -1].legend(fontsize=7, loc="upper right")
    fig.suptitle("Diffusion: measured decay rate over the exact rate 8 pi^2 kappa (1 = exact)")
    return pl.save(fig, outdir / "decay_ratio.png")


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
    models = sorted(sub["laplacian"].unique(), key=an.model_sort_key)
    if not models:
        return None
    fig, axes = pl.figure(len(jitters), len(models), width=3.6, height=3.3)
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
            ax.set_title(f"{model}, {where}\nL2 {an.pct(g['l2_error'].iloc[0])}", fontsize=9)
            ax.set_aspect("equal")
            ax.set_xticks([0, 0.5, 1])
            ax.set_yticks([0, 0.5, 1])
    fig.suptitle(f"Diffusion: (phi - phi_exact) / max|phi_exact| at t_end; {weight}, "
                 f"r_e/l0 = {re:g}, l0 = {an.fraction(l0)} (colour scale per panel)")
    return pl.save(fig, outdir / "error_maps.png")
