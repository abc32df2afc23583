"""Taylor-Green figures: kinetic energy and velocity error over time against the exact decay,
the particles at the end (the disorder), and the refinement set of the recommended cell."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases import analysis as an
from mpsbench.cases import plotting as pl

from .analysis import shifted
from .metrics import HEADLINE_N, RECOMMENDED, SIDE, flow


def figures(records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
            outdir: Path, unc: Any = None) -> list[Path]:
    df = an.completed(records)
    if df.empty:
        return []
    df = df.assign(n=(SIDE / df["l0"]).round().astype(int))
    out: list[Path | None] = []
    for _, g in df.groupby(["n", "reynolds"]):
        out.append(_fig_decay(g, arrays, outdir, int(g["n"].iloc[0]),
                              float(g["reynolds"].iloc[0])))
    head = an.select(df[df["n"] == HEADLINE_N], **RECOMMENDED)
    if not head.empty:
        out.append(_fig_particles(head, arrays, outdir))
    if unc is not None:
        out.append(pl.refinement_figure(
            [s for s in unc.sets if len(s.run_ids) > 1],
            "Taylor-Green: refinement in l0 of the recommended cell (u_num band where "
            "converged; docs/method.md section 9)", outdir / "refinement.png"))
    return [p for p in out if p is not None]


def _name(r: pd.Series) -> str:
    stab = "stab." if r["stabilization"] else "no stab."
    if shifted(r):
        stab += ", shifting"
    return f"{r['laplacian']} / {r['gradient']}, {stab}"


def _style(r: pd.Series) -> dict[str, Any]:
    dashes = {"pgm1": "-", "pgm2": "--", "pgm3": ":"}
    style = {"color": pl.colour(str(r["laplacian"])), "ls": dashes.get(str(r["gradient"]), "-."),
             "lw": 1.6 if r["stabilization"] else 0.9}
    return style


def _fig_decay(g: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path,
               n: int, re: float) -> Path | None:
    fig, axes = pl.figure(1, 2, width=5.6, height=4.4)
    ax_e, ax_u = axes[0, 0], axes[0, 1]
    tg = flow(re)
    t_end = float(g["end_time"].max())
    tt = np.linspace(0.0, t_end, 100)
    ax_e.semilogy(tt, [tg.kinetic_energy_ratio(t) for t in tt], color="k", lw=2,
                  label="exact e^{2bt}")
    for _, r in an.sort_models(g, ["gradient", "stabilization"]).iterrows():
        data = arrays(str(r["run_id"]))
        if "t" not in data:
            continue
        e = np.asarray(data["energy_ratio"]) * np.array(
            [tg.kinetic_energy_ratio(t) for t in data["t"]])
        mark = "s" if shifted(r) else "o"
        ax_e.semilogy(data["t"], np.maximum(e, 1e-6), label=_name(r), **_style(r),
                      **({"marker": mark, "ms": 3, "markevery": 5} if shifted(r) else {}))
        if "error_t" in data:
            ax_u.plot(data["error_t"], 100 * np.asarray(data["velocity_error"]), marker=mark,
                      ms=3, label=_name(r), **_style(r))
    ax_e.set_xlabel("t [s]")
    ax_e.set_ylabel("E(t) / E(0)")
    ax_e.set_title("kinetic energy of the fluid", fontsize=9)
    ax_e.grid(True, which="both", alpha=0.3)
    ax_u.set_xlabel("t [s]")
    ax_u.set_ylabel("||u - u_exact|| / ||u_exact|| [%]")
    ax_u.set_title("velocity error at the particles", fontsize=9)
    ax_u.grid(alpha=0.3)
    for ax in (ax_e, ax_u):
        ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    fig.suptitle(f"Taylor-Green vortex, Re = {re:g}, N = {n} (thick: stabilized; squares: "
                 "shifting; line style: PGM1 solid, PGM2 dashed, PGM3 dotted)", fontsize=9)
    return pl.save(fig, outdir / f"decay_N-{n}_Re-{re:g}.png")


def _fig_particles(head: pd.DataFrame, arrays: Callable[[str], dict[str, np.ndarray]],
                   outdir: Path) -> Path | None:
    runs = [r for _, r in an.sort_models(head, ["stabilization", "reynolds"]).iterrows()
            if "x" in arrays(str(r["run_id"]))][:3]
    if not runs:
        return None
    fig, axes = pl.figure(1, len(runs), width=4.0, height=4.2)
    for k, r in enumerate(runs):
        data = arrays(str(r["run_id"]))
        ax = axes[0, k]
        tg = flow(float(r["reynolds"]))
        sc = ax.scatter(np.mod(data["x"], SIDE), np.mod(data["y"], SIDE), c=data["speed"],
                        s=4, cmap="viridis", vmin=0.0,
                        vmax=tg.amplitude(float(r["end_time"])))
        ax.set_aspect("equal")
        ax.set_xlim(0, SIDE)
        ax.set_ylim(0, SIDE)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{_name(r)}, t = {float(r['end_time']):g} s\n(colour scale: the exact "
                     f"amplitude, {tg.amplitude(float(r['end_time'])):.2f} m/s)", fontsize=8)
        fig.colorbar(sc, ax=ax, shrink=0.8, label="|u| [m/s]")
    fig.suptitle(f"Taylor-Green: particles at the end, N = {HEADLINE_N}, started from the "
                 "square lattice")
    return pl.save(fig, outdir / "particles.png")
