"""Dam break figures: pressure snapshots, Z(T) and H*(tau) against Martin & Moyce, p*(t*) per
sensor with Lobovsky's band; VTU export of the snapshots on request."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .. import experiments
from .analysis import DEFAULT_CFL, KO, LOB, _num, _ok, label, own_models


def _pick(records: list[dict[str, Any]], geometry: str, variant: str) -> dict[str, Any] | None:
    """The finest completed run of a variant, preferring its own models in the geometry and
    the default cfl (fewest settings off them first)."""
    cands = [
        r
        for r in records
        if r.get("geometry") == geometry and r.get("variant") == variant and _ok(r)
    ]
    if not cands:
        return None

    own = own_models(geometry) | {"cfl": DEFAULT_CFL}

    def score(r: dict[str, Any]) -> tuple[int, float]:
        misses = sum(r.get(k, v) != v for k, v in own.items())
        return misses, _num(r.get("l0"))

    return min(cands, key=score)


def _snapshot_figure(
    records: list[dict[str, Any]],
    arrays: Callable[[str], dict[str, np.ndarray]],
    geometry: str,
    path: Path,
) -> Path | None:
    import matplotlib.pyplot as plt

    rows = []
    for variant in ("wc-mps", "iwc-mps"):
        r = _pick(records, geometry, variant)
        if r is not None:
            data = arrays(r["run_id"])
            if "snap_labels" in data and len(data["snap_labels"]):
                rows.append((r, data))
    if not rows:
        return None
    scale = 1000.0 * 9.81 * _num(rows[0][0].get("column_height"))  # rho g H [Pa]
    allp = np.concatenate(
        [
            d[f"snap{k}_p"][d[f"snap{k}_kind"] == 0] / scale
            for _, d in rows
            for k in range(len(d["snap_labels"]))
        ]
    )
    vmax = float(np.percentile(allp, 99)) if len(allp) else 1.0
    ncol = max(len(d["snap_labels"]) for _, d in rows)
    fig, axes = plt.subplots(
        len(rows),
        ncol,
        figsize=(3.6 * ncol, 2.6 * len(rows) + 0.6),
        squeeze=False,
        constrained_layout=True,
    )
    sym = "T" if geometry == KO else "t*"
    sc = None
    for i, (r, d) in enumerate(rows):
        for k in range(ncol):
            ax = axes[i, k]
            if k >= len(d["snap_labels"]):
                ax.axis("off")
                continue
            pos, kind, p = d[f"snap{k}_pos"], d[f"snap{k}_kind"], d[f"snap{k}_p"] / scale
            f = kind == 0
            ax.scatter(pos[~f, 0], pos[~f, 1], s=0.3, c="0.55", linewidths=0)
            sc = ax.scatter(
                pos[f, 0],
                pos[f, 1],
                s=1.5,
                c=p[f],
                cmap="viridis",
                vmin=0.0,
                vmax=vmax,
                linewidths=0,
            )
            ax.set_aspect("equal")
            ax.set_title(f"{label(r)}\n{sym} = {d['snap_labels'][k]:g}", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.set_xlabel("x [m]", fontsize=7)
            if k == 0:
                ax.set_ylabel("y [m]", fontsize=7)
    if sc is not None:
        fig.colorbar(sc, ax=axes, shrink=0.8, label="p / (rho g H)")
    fig.suptitle(f"Dam break ({geometry}): particles coloured by pressure, same scale for both")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _front_figure(
    records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]], path: Path
) -> Path | None:
    import matplotlib.pyplot as plt

    runs = [r for r in records if r.get("geometry") == KO and _ok(r)]
    if not runs:
        return None
    front = experiments.load("martin_moyce_1952_surge_front")
    height = experiments.load("martin_moyce_1952_residual_height")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    for r in sorted(runs, key=lambda r: (str(r.get("variant")), -_num(r.get("l0")))):
        d = arrays(r["run_id"])
        if "front_T" not in d:
            continue
        style = (
            "-"
            if r.get("variant") == "iwc-mps"
            else ("--" if r.get("variant") == "wc-mps" else ":")
        )
        lines = ax1.plot(d["front_T"], d["front_Z"], style, lw=1.2, label=label(r))
        ax2.plot(d["height_tau"], d["height_H"], style, lw=1.2, color=lines[0].get_color())
    ax1.plot(front["T"], front["Z"], "ko", ms=4, label="Martin & Moyce 1952")
    ax2.plot(height["tau"], height["H*"], "ko", ms=4, label="Martin & Moyce 1952")
    ax1.axvline(3.0, color="0.7", lw=0.8)
    ax1.set_xlabel("T = t sqrt(2g/a)")
    ax1.set_ylabel("Z = z/a")
    ax1.set_title("surge front (error measured for T <= 3)")
    ax1.set_xlim(0, 4.6)
    ax2.set_xlabel("tau = t sqrt(g/a)")
    ax2.set_ylabel("H* = h/H")
    ax2.set_title("residual column height at the back wall")
    ax2.set_xlim(0, 3.5)
    ax1.legend(fontsize=7)
    ax2.legend(fontsize=7)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _pressure_figure(
    records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]], path: Path
) -> Path | None:
    import matplotlib.pyplot as plt

    runs = [r for r in records if r.get("geometry") == LOB and _ok(r)]
    if not runs:
        return None
    band = experiments.lobovsky_bands()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), constrained_layout=True)
    t_a = [_num(r.get("impact_tstar")) for r in runs]
    t_a = [t for t in t_a if math.isfinite(t)]
    lo_t = (min(t_a) - 0.4) if t_a else 0.0
    for k, ax in enumerate(axes.ravel()):
        for r in sorted(runs, key=lambda r: (str(r.get("variant")), -_num(r.get("l0")))):
            d = arrays(r["run_id"])
            if "sensor_tstar" not in d or d["sensor_p"].ndim != 2:
                continue
            lines = ax.plot(d["sensor_tstar"], d["sensor_p"][:, k], lw=0.6, label=label(r))
            pk = _num(r.get(f"peak_p_sensor{k + 1}"))
            if math.isfinite(pk):
                ax.plot(
                    [_num(r.get(f"peak_tstar_sensor{k + 1}"))],
                    [pk],
                    "o",
                    ms=4,
                    color=lines[0].get_color(),
                )
        ax.axhspan(
            band["lo"][k],
            band["hi"][k],
            color="0.6",
            alpha=0.35,
            label="measured 2.5-97.5 % (peak)",
        )
        ax.axhline(band["median"][k], color="k", lw=0.8, ls="--", label="measured median")
        ax.set_xlim(left=lo_t)
        ax.set_title(f"sensor {k + 1}, z = {band['z'][k] * 1000:g} mm", fontsize=9)
        ax.set_xlabel("t* = t sqrt(g/H)")
        ax.set_ylabel("p* = p/(rho g H)")
    axes[0, 0].legend(fontsize=6)
    fig.suptitle("Lobovsky et al. 2014: wall pressure; dots mark the first-impact peak")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def figures(
    records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]], outdir: Path
) -> list[Path]:
    made = [
        _snapshot_figure(records, arrays, KO, outdir / "snapshots_koshizuka-oka.png"),
        _front_figure(records, arrays, outdir / "surge_front_and_height.png"),
        _pressure_figure(records, arrays, outdir / "impact_pressure_lobovsky.png"),
        _snapshot_figure(records, arrays, LOB, outdir / "snapshots_lobovsky.png"),
    ]
    return [p for p in made if p is not None]
