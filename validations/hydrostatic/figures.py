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


# besides the Laplacian, the gradient and the stabilization: what may differ between the runs of
# one figure (several solvers, a study of the stabilization rate or the step), named when it does
VARIANTS = ("solver", "stabilization_rate", "alpha_s", "cfl", "weight", "re_ratio", "end_time")
WIDTHS = (1.2, 2.4, 0.7, 1.8)  # line widths of the variants, in order of appearance


class _Labels:
    """Names and line styles of a figure's runs, telling apart the variants present in it."""

    def __init__(self, g: pd.DataFrame) -> None:
        # the case sees ``solver`` as the whole spec (name:options, results.sections.by_spec)
        self.solver = "solver" in g.columns and g["solver"].astype(str).nunique() > 1
        self.extra = [c for c in VARIANTS[1:]
                      if c in g.columns and g[c].astype(str).nunique() > 1]
        self.index: dict[str, int] = {}

    def _variant(self, r: pd.Series) -> str:
        parts = [str(r["solver"])] if self.solver else []
        for c in self.extra:
            if c == "stabilization_rate":
                if r["stabilization"]:
                    parts.append(f"alpha_s per {'acoustic step' if r[c] == 'acoustic' else 'step'}")
            else:
                parts.append(f"{c} {r[c]}")
        return ", ".join(parts)

    def name(self, r: pd.Series) -> str:
        stab = "stabilized" if r["stabilization"] else "no stabilization"
        variant = self._variant(r)
        return f"{r['laplacian']} / {r['gradient']}, {stab}" + (f", {variant}" if variant else "")

    def style(self, r: pd.Series) -> dict[str, Any]:
        k = self.index.setdefault(self._variant(r), len(self.index))
        return {"color": pl.colour(str(r["laplacian"])),
                "ls": "-" if r["stabilization"] else "--", "lw": WIDTHS[k % len(WIDTHS)]}


def _runs(g: pd.DataFrame) -> list[pd.Series]:
    extra = [c for c in VARIANTS if c in g.columns]
    g = an.sort_models(g, ["gradient", "stabilization", *extra])
    return [r for _, r in g.iterrows()]


def _fig_motion(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path,
                l0: float) -> Path | None:
    fig, axes = pl.figure(1, 2, width=5.6, height=4.2)
    ax_v, ax_s = axes[0, 0], axes[0, 1]
    height = float(g["column_height"].iloc[0])
    lab = _Labels(g)
    for r in _runs(g):
        data = arrays(str(r["run_id"]))
        if "t" not in data:
            continue
        name, style = lab.name(r), lab.style(r)
        ax_v.semilogy(data["t"], np.maximum(data["rms_speed"], 1e-6), label=name, **style)
        ax_s.plot(data["t"], 1000 * (data["surface"] - height), label=name, **style)
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
    # one legend under both panels (the same runs): long names do not squeeze the axes
    fig.legend(*ax_v.get_legend_handles_labels(), fontsize=7, loc="outside lower center",
               ncol=2 if len(ax_v.lines) > 6 else 1)
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
    lab = _Labels(g)
    for r in _runs(g):
        data = arrays(str(r["run_id"]))
        if "layer_y" not in data:
            continue
        y, p = data["layer_y"], data["layer_p_mean"]
        ok = np.isfinite(p)
        kw = lab.style(r)
        ax_p.plot(p[ok] / scale, y[ok] / height, "o", ms=3, mfc="none", color=kw["color"],
                  label=lab.name(r) if r["stabilization"] else None)
        inside = ok & (y < height)
        err = (p[inside] - RHO0 * G * (height - y[inside])) / scale
        ax_e.plot(100 * err, y[inside] / height, marker="o", ms=3, label=lab.name(r), **kw)
    ax_p.set_xlabel("p / (rho0 g H), time mean over the second half")
    ax_p.set_ylabel("y / H")
    ax_p.set_title("layer pressure (stabilized runs)", fontsize=9)
    ax_p.grid(alpha=0.3)
    ax_p.legend(*[h[:1] for h in ax_p.get_legend_handles_labels()], fontsize=7,
                loc="upper right")  # the exact line; the runs are named under both panels
    ax_e.axvline(0.0, color="k", lw=0.8)
    ax_e.set_xlabel("(p - rho0 g (H - y)) / (rho0 g H) [%]")
    ax_e.set_title("error of the layer pressure", fontsize=9)
    ax_e.grid(alpha=0.3)
    fig.legend(*ax_e.get_legend_handles_labels(), fontsize=7, loc="outside lower center",
               ncol=2 if len(ax_e.lines) > 6 else 1)
    fig.suptitle(f"Hydrostatic tank: pressure profile, H = {height:g} m, l0 = {l0:g} m")
    return pl.save(fig, outdir / f"pressure_l0-{l0:g}.png")
