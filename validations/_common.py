"""Helpers shared by the diffusion and Couette cases: record frames, pivots, orders, plot style.

Nothing here knows a case's physics; the case modules pass column names in.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mpsbench.physics.gradients import GRADIENTS
from mpsbench.physics.laplacians import LAPLACIANS
from mpsbench.physics.weights import WEIGHTS

# The four Laplacians of docs/method.md section 3, in the order the tables list them.
MODELS = ("koshizuka-oka", "khayyer-gotoh", "xu-jin", "xu-jin-analytic")
WFS = ("wf1", "wf2")
RE_RATIOS = (2.1, 2.5, 3.1, 3.5, 4.0)

_COLOURS = {
    "koshizuka-oka": "tab:blue",
    "khayyer-gotoh": "tab:red",
    "xu-jin": "tab:green",
    "xu-jin-analytic": "tab:purple",
}
_MARKERS = {"wf1": "o", "wf2": "s"}
_EXTRA = ("tab:orange", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray")


def laplacian_names() -> tuple[str, ...]:
    """Registered Laplacians (built-ins first), so a plugin model is an allowed value."""
    names = list(LAPLACIANS.names())
    return tuple([m for m in MODELS if m in names] + sorted(n for n in names if n not in MODELS))


def weight_names() -> tuple[str, ...]:
    names = list(WEIGHTS.names())
    return tuple([w for w in WFS if w in names] + sorted(n for n in names if n not in WFS))


def gradient_names() -> tuple[str, ...]:
    """Registered pressure-gradient models (pgm1-3 first), plugin models included."""
    names = list(GRADIENTS.names())
    builtin = ("pgm1", "pgm2", "pgm3")
    return tuple([g for g in builtin if g in names] + sorted(n for n in names if n not in builtin))


def colour(model: str) -> str:
    if model in _COLOURS:
        return _COLOURS[model]
    return _EXTRA[sum(map(ord, model)) % len(_EXTRA)]


def marker(weight: str) -> str:
    return _MARKERS.get(weight, "^")


def model_sort_key(model: str) -> tuple[int, str]:
    return (MODELS.index(model) if model in MODELS else len(MODELS), model)


def completed(records: Sequence[dict[str, Any]]) -> pd.DataFrame:
    """Completed runs as a DataFrame (empty frame when there are none)."""
    rows = [r for r in records if r.get("status") == "completed"]
    return pd.DataFrame.from_records(rows)


def several_solvers(df: pd.DataFrame) -> bool:
    return "solver" in df.columns and df["solver"].nunique() > 1


def fraction(value: float, whole: float = 1.0, symbol: str = "1") -> str:
    """``1/40`` (or ``L/40``) when ``value`` is whole/N for an integer N, else ``%g``."""
    if value > 0:
        n = whole / value
        if abs(n - round(n)) < 1e-6 * n:
            return f"{symbol}/{round(n)}"
    return f"{value:g}"


def pct(x: Any, digits: int = 2) -> str:
    """A fraction as a percentage for prose (``n/a`` for missing values)."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return f"{100.0 * float(x):.{digits}f}%"


def row_label(model: str, weight: str) -> str:
    return f"{model} / {weight}"


def pivot(
    df: pd.DataFrame, value: str, columns: str = "re_ratio", column_label: str = "r_e/l0 = {:g}"
) -> pd.DataFrame:
    """Rows model x WF (``laplacian / weight``, plus the solver when there are several),
    columns ``columns`` (r_e/l0), cells ``value`` (the first of duplicates)."""
    if df.empty or value not in df.columns:
        return pd.DataFrame()
    df = df[df[value].notna()]
    if df.empty:
        return pd.DataFrame()
    rows = df.apply(lambda r: row_label(r["laplacian"], r["weight"]), axis=1)
    if several_solvers(df):
        rows = df["solver"].astype(str) + ": " + rows
    frame = pd.DataFrame({"row": rows, "col": df[columns], "value": df[value]})
    table = frame.pivot_table(index="row", columns="col", values="value", aggfunc="first")
    order = sorted(
        table.index,
        key=lambda s: (s.split(": ")[0] if ": " in s else "",
                       model_sort_key(s.split(": ")[-1].split(" / ")[0]), s),
    )
    table = table.loc[order]
    table.columns = [column_label.format(c) for c in table.columns]
    table.index.name = "model / WF"
    return table


def observed_orders(
    df: pd.DataFrame, value: str, keys: Sequence[str], resolution: str = "l0"
) -> pd.DataFrame:
    """Observed order of convergence of ``value`` in ``resolution`` for each ``keys`` group.

    ``observed_order`` is the local order between the two finest resolutions,
    log(e_coarse / e_fine) / log(l0_coarse / l0_fine); ``order_fit`` is the least-squares slope
    of log e against log l0 over all resolutions (equal to the first with two).  Groups with a
    single resolution are left out.
    """
    cols = [*keys, "n_resolutions", "l0_coarse", "l0_fine", "error_coarse", "error_fine",
            "observed_order", "order_fit"]
    if df.empty or value not in df.columns:
        return pd.DataFrame(columns=cols)
    rows = []
    use = [k for k in keys if k in df.columns]
    for key, group in df[df[value].notna()].groupby(use, sort=False):
        g = group.sort_values(resolution, ascending=False).drop_duplicates(resolution)
        if len(g) < 2:
            continue
        h = g[resolution].to_numpy(float)
        e = g[value].to_numpy(float)
        ok = e > 0
        order = fit = math.nan
        if ok[-1] and ok[-2]:
            order = math.log(e[-2] / e[-1]) / math.log(h[-2] / h[-1])
        if ok.sum() >= 2:
            fit = float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0])
        key = key if isinstance(key, tuple) else (key,)
        rows.append([*key, len(g), h[0], h[-1], e[0], e[-1], order, fit])
    out = pd.DataFrame(rows, columns=[*use, *cols[len(keys):]])
    return out


def sort_models(df: pd.DataFrame, extra: Iterable[str] = ()) -> pd.DataFrame:
    """Sort by model (docs/method.md order), weight, then ``extra`` columns."""
    if df.empty:
        return df
    by = [c for c in ("solver", "weight", *extra) if c in df.columns]
    key = df["laplacian"].map(lambda m: model_sort_key(m)[0]) if "laplacian" in df else None
    df = df.assign(_m=key) if key is not None else df
    df = df.sort_values(["_m", *by] if key is not None else by, kind="stable")
    return df.drop(columns="_m") if key is not None else df


def save(fig: Any, path: Path) -> Path:
    fig.savefig(path, dpi=110, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def row_min(df: pd.DataFrame, value: str) -> pd.Series:
    """The row with the smallest ``value`` (NaN rows ignored)."""
    return df.iloc[int(np.nanargmin(df[value].to_numpy(float)))]


def row_max(df: pd.DataFrame, value: str) -> pd.Series:
    """The row with the largest ``value`` (NaN rows ignored)."""
    return df.iloc[int(np.nanargmax(df[value].to_numpy(float)))]


# ---------------------------------------------------------------------- plots
def figure(nrows: int, ncols: int, width: float = 4.6, height: float = 3.6) -> tuple[Any, Any]:
    """A matplotlib figure with a 2-D array of axes (Agg backend)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False,
                             layout="constrained")
    return fig, axes


def line_style(weight: str) -> str:
    return "-" if weight == "wf1" else "--"


def plot_vs_re(ax: Any, df: pd.DataFrame, value: str, log: bool = True) -> None:
    """``value`` against r_e/l0: one line per model (colour) and WF (marker, line style)."""
    for (model, weight), g in sorted(df.groupby(["laplacian", "weight"]),
                                     key=lambda kv: (model_sort_key(str(kv[0][0])), kv[0][1])):
        model, weight = str(model), str(weight)
        g = g.sort_values("re_ratio")
        ax.plot(g["re_ratio"], g[value], line_style(weight), marker=marker(weight),
                color=colour(model), label=f"{model} / {weight}")
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("r_e / l0")
    lo, hi = min(RE_RATIOS + tuple(df["re_ratio"])), max(RE_RATIOS + tuple(df["re_ratio"]))
    ax.set_xlim(lo - 0.15, hi + 0.15)
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


def span(values: Any, fmt: Any, sep: str = "-") -> str:
    """``fmt(min)-fmt(max)``, or one value when they print the same."""
    lo, hi = fmt(float(np.min(values))), fmt(float(np.max(values)))
    return lo if lo == hi else f"{lo}{sep}{hi}"


def weight_ratio_line(df: pd.DataFrame, value: str, where: str) -> str:
    """Plain words: the WF1 / WF2 ratio of ``value`` per model at the same r_e/l0."""
    if df.empty or not {"wf1", "wf2"} <= set(df["weight"]):
        return ""
    keys = ["laplacian", "re_ratio"]
    w1 = df[df["weight"] == "wf1"].groupby(keys)[value].first()
    w2 = df[df["weight"] == "wf2"].groupby(keys)[value].first()
    both = pd.concat([w1.rename("a"), w2.rename("b")], axis=1, join="inner").dropna()
    both = both[both["b"] > 0]
    if both.empty:
        return ""
    parts = []
    for model in sorted(both.index.get_level_values(0).unique(), key=model_sort_key):
        ratio = both.loc[model, "a"] / both.loc[model, "b"]
        parts.append(f"{model} {span(ratio, lambda v: f'{v:.2f}')}")
    return (f"- **WF1 / WF2** error ratio at the same r_e/l0 ({where}): " + "; ".join(parts)
            + " (1 = insensitive to the weighting function).")
