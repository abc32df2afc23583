"""Cavity figures: the two centreline profiles against Ghia et al.'s points, per spacing and
Reynolds number, and the refinement set of the recommended cell."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import analysis as an
from mpsbench.cases import plotting as pl

from .metrics import SIDE
from .reference import load_ghia


def figures(records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
            outdir: Path, unc: Any = None) -> list[Path]:
    df = an.completed(records)
    if df.empty:
        return []
    df = df.assign(n=(SIDE / df["l0"]).round().astype(int))
    out: list[Path | None] = []
    for _, g in df.groupby(["n", "reynolds"]):
        out.append(_fig_profiles(g, arrays, outdir, int(g["n"].iloc[0]),
                                 int(g["reynolds"].iloc[0])))
    if unc is not None:
        out.append(pl.refinement_figure(
            [s for s in unc.sets if len(s.run_ids) > 1],
            "Cavity: refinement in l0 of the recommended cell (u_num band where converged; "
            "docs/method.md section 9)", outdir / "refinement.png"))
    return [p for p in out if p is not None]


def _name(r: pd.Series) -> str:
    extra = [str(r["gradient"])] if r["gradient"] != "pgm1" else []
    if r["stabilization"]:
        extra.append("stab.")
    return " / ".join([str(r["laplacian"]), *extra])


def _fig_profiles(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]],
                  outdir: Path, n: int, re: int) -> Path | None:
    fig, axes = pl.figure(1, 2, width=4.6, height=4.6)
    ax_u, ax_v = axes[0, 0], axes[0, 1]
    gu, gv = load_ghia("u"), load_ghia("v")
    ax_u.plot(gu[re], gu.coordinate, "ks", ms=4, mfc="none", label="Ghia et al. (1982)")
    ax_v.plot(gv.coordinate, gv[re], "ks", ms=4, mfc="none", label="Ghia et al. (1982)")
    for _, r in an.sort_models(g, ["gradient", "stabilization"]).iterrows():
        data = arrays(str(r["run_id"]))
        if "line" not in data:
            continue
        kw = {"color": pl.colour(str(r["laplacian"])), "lw": 1.2,
              "ls": "--" if r["stabilization"] else "-"}
        ax_u.plot(data["u_line"], data["line"], label=f"{_name(r)} ({r['rms_error']:.3f} U)",
                  **kw)
        ax_v.plot(data["line"], data["v_line"], label=_name(r), **kw)
    ax_u.set_xlabel("u / U on x = 0.5")
    ax_u.set_ylabel("y / L")
    ax_u.set_title("vertical centreline", fontsize=9)
    ax_v.set_xlabel("x / L")
    ax_v.set_ylabel("v / U on y = 0.5")
    ax_v.set_title("horizontal centreline", fontsize=9)
    for ax in (ax_u, ax_v):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.14))
    t_end = float(g["end_time"].max())
    fig.suptitle(f"Lid-driven cavity, Re = {re}, N = {n}: profiles averaged over the last "
                 f"fifth of {t_end:g} s (legend: RMS error against the tables)", fontsize=9)
    return pl.save(fig, outdir / f"profiles_N-{n}_Re-{re}.png")
