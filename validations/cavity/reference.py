"""Lid-driven cavity reference: Ghia, Ghia & Shin's (1982) centreline velocities, checked.

Ghia, U., Ghia, K. N. and Shin, C. T. (1982), High-Re solutions for incompressible flow using
the Navier-Stokes equations and a multigrid method, J. Comput. Phys. 48(3):387-411,
doi:10.1016/0021-9991(82)90058-4.  Unit square, lid y = 1 moving at speed 1 in +x, the other
walls at rest, Re = U L / nu = 1 / nu.  Table I gives u on the vertical centreline x = 0.5,
table II v on the horizontal centreline y = 0.5, 17 points each from their 129 x 129 grid
solution; ``validations/data/`` ships the Re = 100 and Re = 1000 columns (everything
dimensionless: coordinates over L, velocities over U) and its README records the four public
copies the values were compared with.

The files go through :func:`mpsbench.validations.experiments.load` (header, columns, units,
finite numbers) and then through the checks a benchmark table needs before a case trusts it:
UTF-8 text, 17 rows, coordinates in [0, 1] and strictly monotone with both walls present, and
the boundary values (u = 1 at the lid and 0 at the bottom wall; v = 0 at both side walls).  A
file failing any of them raises :class:`~mpsbench.validations.experiments.DataFileError` (a
ValueError) naming the file and the problem, so a damaged copy cannot pass as a reference.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..experiments import DATA_DIR, DataFileError, load

FloatArray = NDArray[np.float64]
Component = Literal["u", "v"]

#: component -> (data set name, coordinate column)
FILES: dict[str, tuple[str, str]] = {
    "u": ("ghia_1982_u_vertical_centreline", "y"),
    "v": ("ghia_1982_v_horizontal_centreline", "x"),
}
REYNOLDS = (100, 1000)  # columns Re100, Re1000; every shipped file must have them
N_POINTS = 17  # rows of Ghia's tables I and II
_RE_COLUMN = re.compile(r"Re(\d+)")
_WALL_TOL = 1e-12


@dataclass(frozen=True)
class CentrelineProfile:
    """One of Ghia's tables: the coordinate (table order) and one velocity column per Re."""

    component: Component
    coordinate_name: str
    path: Path
    source: str
    coordinate: FloatArray = field(repr=False)
    values: dict[int, FloatArray] = field(repr=False)

    def __getitem__(self, reynolds: int) -> FloatArray:
        try:
            return self.values[reynolds]
        except KeyError:
            raise KeyError(
                f"{self.path.name}: no Re = {reynolds} column; available: "
                f"{', '.join(str(r) for r in self.values)}"
            ) from None

    @property
    def reynolds(self) -> tuple[int, ...]:
        return tuple(self.values)

    def ascending(self, reynolds: int) -> tuple[FloatArray, FloatArray]:
        """(coordinate, velocity) sorted by increasing coordinate, as np.interp wants them."""
        order = np.argsort(self.coordinate)
        return self.coordinate[order], self[reynolds][order]


def load_ghia(component: Component, path: str | Path | None = None) -> CentrelineProfile:
    """Load and check Ghia's u (table I, x = 0.5) or v (table II, y = 0.5) centreline table.

    ``path`` defaults to the shipped file; tests pass damaged copies to see them refused.
    """
    if component not in FILES:
        raise ValueError(f"component must be 'u' or 'v', got {component!r}")
    name, coord = FILES[component]
    file = DATA_DIR / f"{name}.csv" if path is None else Path(path)
    _check_encoding(file)
    schema = {coord: "1", **{f"Re{r}": "1" for r in REYNOLDS}}
    data = load(file, schema)
    extra = [c for c in data.columns if c != coord and not _RE_COLUMN.fullmatch(c)]
    if extra:
        raise DataFileError(
            f"{file.name}: unexpected column(s) {', '.join(extra)}; expected {coord!r} and "
            "one column Re<number> per Reynolds number"
        )
    if len(data) != N_POINTS:
        raise DataFileError(
            f"{file.name}: {len(data)} data rows, expected {N_POINTS} (Ghia's table has "
            f"{N_POINTS} points); truncated or padded file?"
        )
    s = data[coord]
    _check_coordinate(file.name, coord, s)
    values = {
        int(m.group(1)): data[c] for c in data.columns if (m := _RE_COLUMN.fullmatch(c))
    }
    _check_walls(file.name, component, coord, s, values)
    return CentrelineProfile(component, coord, file, data.source, s, values)


def u_vertical_centreline(path: str | Path | None = None) -> CentrelineProfile:
    """Table I: u on x = 0.5 against y."""
    return load_ghia("u", path)


def v_horizontal_centreline(path: str | Path | None = None) -> CentrelineProfile:
    """Table II: v on y = 0.5 against x."""
    return load_ghia("v", path)


def _check_encoding(file: Path) -> None:
    """UTF-8 without a byte-order mark, which experiments.load would misread as data."""
    if not file.is_file():
        raise DataFileError(f"data file {file} does not exist")
    raw = file.read_bytes()
    if raw.startswith(b"\xef\xbb\xbf"):
        raise DataFileError(
            f"{file.name}: starts with a UTF-8 byte-order mark; save it as plain UTF-8"
        )
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise DataFileError(
            f"{file.name}: not UTF-8 text (byte 0x{raw[exc.start]:02x} on line {line}); "
            "the data files are UTF-8"
        ) from None


def _check_coordinate(name: str, coord: str, s: FloatArray) -> None:
    outside = (s < 0.0) | (s > 1.0)
    if np.any(outside):
        raise DataFileError(
            f"{name}: coordinate {coord!r} outside [0, 1] (the cavity side is 1): "
            f"{s[outside].tolist()}"
        )
    steps = np.diff(s)
    direction = np.sign(s[-1] - s[0])  # Ghia's tables run from 1 down to 0
    wrong = np.nonzero(np.sign(steps) != direction)[0]
    if direction == 0.0 or wrong.size:
        i = int(wrong[0]) if wrong.size else 0  # data rows count from 2, as in experiments.load
        raise DataFileError(
            f"{name}: coordinate {coord!r} is not strictly monotone (data rows {i + 2} and "
            f"{i + 3}: {s[i]:g} then {s[i + 1]:g})"
        )
    if min(s[0], s[-1]) != 0.0 or max(s[0], s[-1]) != 1.0:
        raise DataFileError(
            f"{name}: coordinate {coord!r} runs from {s[0]:g} to {s[-1]:g}; Ghia's tables "
            "include both walls, 0 and 1"
        )


def _check_walls(name: str, component: Component, coord: str, s: FloatArray,
                 values: dict[int, FloatArray]) -> None:
    at_0, at_1 = int(np.argmin(s)), int(np.argmax(s))
    if component == "u":  # x = 0.5 meets the bottom wall (u = 0) and the lid (u = 1)
        walls = ((at_0, 0.0, "the bottom wall y = 0"), (at_1, 1.0, "the lid y = 1"))
    else:  # y = 0.5 meets the two side walls (v = 0)
        walls = ((at_0, 0.0, "the left wall x = 0"), (at_1, 0.0, "the right wall x = 1"))
    for re_, vals in values.items():
        for row, expected, where in walls:
            if abs(vals[row] - expected) > _WALL_TOL:
                raise DataFileError(
                    f"{name}: Re{re_}: {component} = {vals[row]:g} at {where} "
                    f"({coord} = {s[row]:g}), expected {expected:g}"
                )
