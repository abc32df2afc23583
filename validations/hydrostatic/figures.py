"""Hydrostatic figures: RMS speed and free surface over time, the time-averaged pressure
profile against rho0 g (H - y), and the refinement set of the floor pressure."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import analysis as an
from mpsbench.cases import plotting as pl

from .metrics import SETTLE_FRACTION, speed_scale
from .reference import RHO0, G


def figures(records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
            outdir: Path, unc: Any = None) -> list[Path]:
    df = an.completed(records)
    if df.empty:
        return []
    out: list[Path | None] = []
    for l0 in sorted(df["l0"].unique()):
        g = df[df["l0"] == l0]
        out.append(_fig_motion(g, arrays, outdir, float(l0)))
        out.append(_fig_pressure(g, arrays, outdir, float(l0)))
    if unc is not None:
        out.append(pl.refinement_figure(
            [s for s in unc.sets if len(s.run_ids) > 1],
            "Hydrostatic: refinement in l0 of the recommended configuration (u_num band "
            "where converged; docs/method.md section 9)", outdir / "refinement.png"))
    return [p for p in out if p is not None]


def _name(r: pd.Series) -> str:
    stab = "stabilized" if r["stabilization"] else "no stabilization"
    return f"{r['laplacian']} / {r['gradient']}, {stab}"


def _style(r: pd.Series) -> dict[str, Any]:
    return {"color": pl.colour(str(r["laplacian"])),
            "ls": "-" if r["stabilization"] else "--", "lw": 1.2}


def _runs(g: pd.DataFrame) -> list[pd.Series]:
    g = an.sort_models(g, ["gradient", "stabilization"])
    return [r for _, r in g.iterrows()]


def _fig_motion(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path,
                l0: float) -> Path | None:
    fig, axes = pl.figure(1, 2, width=5.6, height=4.2)
    ax_v, ax_s = axes[0, 0], axes[0, 1]
    height = float(g["column_height"].iloc[0])
    for r in _runs(g):
        data = arrays(str(r["run_id"]))
        if "t" not in data:
            continue
        ax_v.semilogy(data["t"], np.maximum(data["rms_speed"], 1e-6), label=_name(r), **_style(r))
        ax_s.plot(data["t"], 1000 * (data["surface"] - height), label=_name(r), **_style(r))
    ax_v.axhline(SETTLE_FRACTION * speed_scale(height), color="k", lw=0.8, ls=":",
                 label=f"{SETTLE_FRACTION:.0%} of sqrt(2 g H)")
    ax_v.set_ylim(bottom=1e-4)
    ax_v.set_xlabel("t [s]")
    ax_v.set_ylabel("RMS speed of the fluid [m/s]")
    ax_v.set_title("motion of a column that should be at rest", fontsize=9)
    ax_v.grid(True, which="both", alpha=0.3)
    ax_s.axhline(0.0, color="k", lw=0.8)
    ax_s.set_xlabel("t [s]")
    ax_s.set_ylabel("free surface - H [mm]")
    ax_s.set_title("free surface (mean of the top row + l0/2)", fontsize=9)
    ax_s.grid(alpha=0.3)
    ax_v.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14))
    ax_s.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14))
    fig.suptitle(f"Hydrostatic tank, H = {height:g} m, l0 = {l0:g} m "
                 "(solid: stabilized, dashed: not)")
    return pl.save(fig, outdir / f"motion_l0-{l0:g}.png")


def _fig_pressure(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path,
                  l0: float) -> Path | None:
    fig, axes = pl.figure(1, 2, width=5.0, height=4.6)
    ax_p, ax_e = axes[0, 0], axes[0, 1]
    height = float(g["column_height"].iloc[0])
    scale = RHO0 * G * height
    yy = np.linspace(0.0, height, 50)
    ax_p.plot(1.0 - yy / height, yy / height, "-", color="k", lw=1, label="rho0 g (H - y)")
    for r in _runs(g):
        data = arrays(str(r["run_id"]))
        if "layer_y" not in data:
            continue
        y, p = data["layer_y"], data["layer_p_mean"]
        ok = np.isfinite(p)
        kw = _style(r)
        ax_p.plot(p[ok] / scale, y[ok] / height, "o", ms=3, mfc="none", color=kw["color"],
                  label=_name(r) if r["stabilization"] else None)
        inside = ok & (y < height)
        err = (p[inside] - RHO0 * G * (height - y[inside])) / scale
        ax_e.plot(100 * err, y[inside] / height, marker="o", ms=3, label=_name(r), **kw)
    ax_p.set_xlabel("p / (rho0 g H), time mean over the second half")
    ax_p.set_ylabel("y / H")
    ax_p.set_title("layer pressure (stabilized runs)", fontsize=9)
    ax_p.grid(alpha=0.3)
    ax_p.legend(fontsize=7, loc="upper right")
    ax_e.axvline(0.0, color="k", lw=0.8)
    ax_e.set_xlabel("(p - rho0 g (H - y)) / (rho0 g H) [%]")
    ax_e.set_title("error of the layer pressure", fontsize=9)
    ax_e.grid(alpha=0.3)
    ax_e.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14))
    fig.suptitle(f"Hydrostatic tank: pressure profile, H = {height:g} m, l0 = {l0:g} m")
    return pl.save(fig, outdir / f"pressure_l0-{l0:g}.png")
