"""Figure helpers shared by the cases (matplotlib, Agg backend): a colour per model, a marker
per weighting function, error-against-r_e and log-log convergence panels.

matplotlib is imported inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.cases.analysis import fraction, model_sort_key

_COLOURS = {
    "koshizuka-oka": "tab:blue",
    "khayyer-gotoh": "tab:red",
    "xu-jin": "tab:green",
    "xu-jin-analytic": "tab:purple",
}
_MARKERS = {"wf1": "o", "wf2": "s"}
_EXTRA = ("tab:orange", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray")


def colour(model: str) -> str:
    """A fixed colour per built-in model; a plugin model gets one from its name."""
    if model in _COLOURS:
        return _COLOURS[model]
    return _EXTRA[sum(map(ord, model)) % len(_EXTRA)]


def marker(weight: str) -> str:
    return _MARKERS.get(weight, "^")


def line_style(weight: str) -> str:
    return "-" if weight == "wf1" else "--"


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figure(nrows: int, ncols: int, width: float = 4.6, height: float = 3.6) -> tuple[Any, Any]:
    """A matplotlib figure with a 2-D array of axes (Agg backend)."""
    fig, axes = pyplot().subplots(nrows, ncols, figsize=(width * ncols, height * nrows),
                                  squeeze=False, layout="constrained")
    return fig, axes


def save(fig: Any, path: Path) -> Path:
    """Write ``fig`` as PNG and close it.  A figure with a layout engine (:func:`figure`'s
    constrained layout) is saved as laid out; ``bbox_inches="tight"`` would draw it once more
    to find the box (the quick tier's diffusion report: 11.2-11.4 s against 9.7-10.0 s)."""
    tight = None if fig.get_layout_engine() is not None else "tight"
    fig.savefig(path, dpi=110, bbox_inches=tight)
    pyplot().close(fig)
    return path


def plot_vs_re(ax: Any, df: pd.DataFrame, value: str, log: bool = True,
               radii: Sequence[float] = ()) -> None:
    """``value`` against r_e/l0: one line per model (colour) and WF (marker, line style);
    the x range covers ``radii`` too (so panels of different tiers line up)."""
    for (model, weight), g in sorted(df.groupby(["laplacian", "weight"]),
                                     key=lambda kv: (model_sort_key(str(kv[0][0])), kv[0][1])):
        model, weight = str(model), str(weight)
        g = g.sort_values("re_ratio")
        ax.plot(g["re_ratio"], g[value], line_style(weight), marker=marker(weight),
                color=colour(model), label=f"{model} / {weight}")
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("r_e / l0")
    xs = tuple(radii) + tuple(df["re_ratio"])
    ax.set_xlim(min(xs) - 0.15, max(xs) + 0.15)
    ax.grid(True, which="both", alpha=0.3)


def convergence_figure(
    df: pd.DataFrame, value: str, orders: pd.DataFrame, title: str, path: Path,
    whole: float = 1.0, symbol: str = "1", slope: float | None = None,
) -> Path:
    """Log-log ``value`` against l0: one panel per WF (rows) and model (columns), one line
    per r_e/l0 labelled with its observed order (``orders``: model, weight, re_ratio,
    observed_order).  ``slope`` adds a dotted reference line of that order to each panel."""
    import matplotlib

    weights = sorted(df["weight"].unique())
    models = sorted(df["laplacian"].unique(), key=model_sort_key)
    radii = sorted(df["re_ratio"].unique())
    cmap = matplotlib.colormaps["viridis"]
    fig, axes = figure(len(weights), len(models), width=3.7, height=3.3)
    ticks = sorted(df["l0"].unique())
    for row, weight in enumerate(weights):
        for col, model in enumerate(models):
            ax = axes[row, col]
            sub = df[(df["weight"] == weight) & (df["laplacian"] == model)]
            for k, re in enumerate(radii):
                g = sub[np.isclose(sub["re_ratio"], re)].sort_values("l0")
                g = g[g[value] > 0]
                if g.empty:
                    continue
                o = orders[(orders["model"] == model) & (orders["weight"] == weight)
                           & np.isclose(orders["re_ratio"], re)]
                label = f"r_e/l0 = {re:g}"
                if len(o):
                    label += f" (order {o['observed_order'].iloc[0]:.2f})"
                ax.loglog(g["l0"], g[value], "-o", ms=4, label=label,
                          color=cmap(k / max(1, len(radii) - 1)))
            if slope is not None and not sub.empty:
                finest = sub[sub["l0"] == sub["l0"].max()][value]
                reference_slope(ax, ticks, float(finest.min()), slope, f"slope {slope:g}")
            ax.set_xticks(ticks, [fraction(h, whole, symbol) for h in ticks])
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_title(f"{model} / {weight}", fontsize=10)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=6, loc="best")
            if row == len(weights) - 1:
                ax.set_xlabel("l0")
        axes[row, 0].set_ylabel(value.replace("_", " "))
    fig.suptitle(title)
    return save(fig, path)


def reference_slope(ax: Any, x: Sequence[float], y0: float, order: float, label: str) -> None:
    """A dotted line of slope ``order`` through (max x, y0 / 2), just below the data."""
    h = np.asarray(sorted(x), float)
    if len(h) < 2 or not (y0 > 0):
        return
    ax.loglog(h, 0.5 * y0 * (h / h[-1]) ** order, ":", color="k", lw=1, label=label)


def set_labels(sets: Sequence[Any]) -> list[str]:
    """What tells the refinement sets of one figure apart: for each set, the parameters of its
    ``key`` whose values differ between the sets, ``name=value`` joined by ", ", in two lines
    when long; a parameter a set does not hold fixed (None: the one it refines) is left out.
    One set, or sets that differ only in metric or kind: ""."""
    keys = [dict(s.key) for s in sets]
    names = sorted({k for key in keys for k in key})
    varying = [k for k in names if len({repr(key.get(k)) for key in keys}) > 1]

    def show(v: Any) -> str:
        return f"{v:g}" if isinstance(v, float) else str(v)

    out = []
    for key in keys:
        parts = [f"{k}={show(key[k])}" for k in varying if key.get(k) is not None]
        half = (len(parts) + 1) // 2
        text = ", ".join(parts)
        out.append(text if len(text) <= 48 else
                   ", ".join(parts[:half]) + ",\n" + ", ".join(parts[half:]))
    return out


def refinement_figure(sets: Sequence[Any], title: str, path: Path) -> Path | None:
    """One panel per refinement set (:class:`mpsbench.cases.refinement.RefinementSet`): the
    metric against the refined step, the extrapolated value and its u_num band when converged,
    and the convergence kind in the title."""
    if not sets:
        return None
    n = len(sets)
    ncol = min(3, n)
    nrow = (n + ncol - 1) // ncol
    fig, axes = figure(nrow, ncol, width=4.0, height=3.2)
    names = set_labels(sets)
    for k, s in enumerate(sets):
        ax = axes[k // ncol, k % ncol]
        c = s.convergence
        ax.plot(c.steps, c.values, "-o", ms=4, color="tab:blue", label=s.metric)
        if c.converged and c.extrapolated is not None:
            ax.axhline(c.extrapolated, color="k", lw=0.8, ls=":", label="extrapolated")
            u = c.u_num or 0.0
            ax.fill_between([0.0, c.steps[0]], c.values[0] - u, c.values[0] + u,
                            color="tab:blue", alpha=0.2, label="finest ± u_num")
        ax.set_xlim(left=0.0)
        ax.set_xlabel(f"{s.refinement.over} ({s.kind})")
        ax.set_ylabel(s.metric)
        ax.set_title(f"{names[k]}\n{s.metric}: {c.kind}" if names[k] else f"{s.metric}: {c.kind}",
                     fontsize=7 if names[k] else 9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    for k in range(n, nrow * ncol):
        axes[k // ncol, k % ncol].set_axis_off()
    fig.suptitle(title)
    return save(fig, path)
