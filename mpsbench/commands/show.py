"""``mpsbench show RUN``: a PNG of one run's particles coloured by a field at a chosen time,
from the frames stored in ``runs/<run_id>.npz`` (``mpsbench validate ... --vtu``).

The frame shown is the one nearest ``--time`` (default: the last); fluid particles are coloured
by the field, wall and dummy particles drawn grey.  Fields: ``pressure`` [Pa], ``speed``,
``u``, ``v`` [m/s], ``kind``, or any extra field the run stored.
Exit status: 0 written, 2 not a run, no frames, unknown field or part.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mpsbench.errors import UsageError

if TYPE_CHECKING:
    from mpsbench.results.frames import StoredFrame

ORDER = 37
UNITS = {"pressure": "Pa", "speed": "m/s", "u": "m/s", "v": "m/s", "kind": "-"}


def register(sub: Any) -> None:
    p = sub.add_parser(
        "show",
        help="a PNG of a run's particles coloured by a field at a chosen time",
        description="Draw one run's particles (from the frames 'mpsbench validate ... --vtu' "
        "kept) coloured by a field at the stored time nearest --time.",
    )
    p.add_argument("run", metavar="RUN", help="runs/<run_id>.json or runs/<run_id>.npz")
    p.add_argument("--field", default="pressure",
                   help="pressure (default), speed, u, v, kind or a stored field's name")
    p.add_argument("--time", type=float, default=None, metavar="T",
                   help="simulated time [s]: the frame nearest it (default: the last)")
    p.add_argument("--part", type=int, default=0,
                   help="which solver run of a case run made of several (default 0)")
    p.add_argument("--out", default=None, metavar="PNG",
                   help="output file (default: <run_id>_<field>_t<time>.png here)")
    p.set_defaults(func=cmd_show)


def cmd_show(args: argparse.Namespace) -> int:
    from mpsbench.results.paraview import frames_of

    _, rid, frames = frames_of(Path(args.run))
    parts = sorted({f.part for f in frames})
    if args.part not in parts:
        raise UsageError(f"--part = {args.part} is not allowed: one of "
                         f"{', '.join(map(str, parts))}")
    frames = [f for f in frames if f.part == args.part]
    frame = frames[-1] if args.time is None else min(frames, key=lambda f: abs(f.time - args.time))
    values = field_values(frame, args.field)
    out = Path(args.out) if args.out else Path(f"{rid}_{args.field}_t{frame.time:.4g}.png")
    draw(frame, values, args.field, f"{rid}\nt = {frame.time:.4g} s (step {frame.step})", out)
    print(out)
    return 0


def field_values(frame: StoredFrame, name: str) -> Any:
    import numpy as np

    p = frame.particles
    known = {"pressure": p.pressure, "u": p.vel[:, 0], "v": p.vel[:, 1],
             "speed": np.hypot(p.vel[:, 0], p.vel[:, 1]), "kind": p.kind.astype(float),
             **p.fields}
    if name not in known:
        raise UsageError(f"--field = {name!r} is not allowed: one of {', '.join(known)}")
    return np.asarray(known[name], float)


def draw(frame: StoredFrame, values: Any, name: str, title: str, out: Path) -> None:
    import textwrap

    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = frame.particles
    fluid = p.kind == 0
    span = p.pos.max(axis=0) - p.pos.min(axis=0) if p.n else [1.0, 1.0]
    aspect = float(span[1] / span[0]) if span[0] > 0 else 1.0
    fig, ax = plt.subplots(figsize=(7.5, max(2.5, min(7.5, 6.0 * aspect + 1.0))),
                           constrained_layout=True)
    size = max(0.5, min(12.0, 6000.0 / max(1, p.n)))
    ax.scatter(p.pos[~fluid, 0], p.pos[~fluid, 1], s=size * 0.5, c="0.6", linewidths=0,
               label="walls")
    shown = values[fluid]
    # the colour range of the 1st-99th percentile: one impact spike must not wash out the rest
    lo, hi = (np.percentile(shown, [1, 99]) if len(shown) else (0.0, 1.0))
    sc = ax.scatter(p.pos[fluid, 0], p.pos[fluid, 1], s=size, c=shown, cmap="viridis",
                    vmin=lo, vmax=hi if hi > lo else lo + 1.0, linewidths=0)
    fig.colorbar(sc, ax=ax, extend="both",
                 label=f"{name} [{UNITS.get(name, 'as stored')}] (1st-99th percentile range)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    lines = [w for line in title.splitlines()
             for w in textwrap.wrap(line, 80, break_on_hyphens=False)]
    ax.set_title("\n".join(lines), fontsize=8)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=120)
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot write: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
