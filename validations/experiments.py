"""Experimental reference data shipped in ``validations/data/`` and a loader that checks them.

Each data file is a CSV whose header comment names its provenance::

    # source: <authors, year, title, journal, doi>
    # table: <which table or figure, what the experiment was>
    # units: <column>=<unit>, ...          ("1" means dimensionless)
    # nondimensionalisation: <how the columns were made dimensionless, or "none">
    col_a,col_b,...
    1.0,2.0,...

:func:`load` reads a file, checks that the four header keys are there, that every column the
schema expects is present, that each column's declared unit is the one expected and that every
value is a finite number; any problem raises :class:`DataFileError` with a message naming the
file, the column and the unit.  Unit conversions the cases need live here too, so they are tested
in one place.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mpsbench.errors import MpsbenchError

FloatArray = NDArray[np.float64]

DATA_DIR = Path(__file__).resolve().parent / "data"
HEADER_KEYS = ("source", "table", "units", "nondimensionalisation")

#: data set name -> {column: unit}; the file is ``data/<name>.csv``.
SCHEMAS: dict[str, dict[str, str]] = {
    "martin_moyce_1952_surge_front": {"T": "1", "Z": "1"},
    "martin_moyce_1952_residual_height": {"tau": "1", "H*": "1"},
    "lobovsky_2014_peak_pressure": {
        "sensor": "1", "z": "mm", "median": "mbar", "p2.5": "mbar", "p97.5": "mbar",
    },
}

G = 9.81  # m/s^2, as in the Lobovsky et al. normalisation
LOBOVSKY_RHO = 997.0  # kg/m^3
LOBOVSKY_H = 0.3  # m, initial water height
PA_PER_MBAR = 100.0


class DataFileError(MpsbenchError, ValueError):
    """A reference data file is malformed: missing header key or column, wrong unit, bad value."""


@dataclass(frozen=True)
class Dataset:
    """One reference table: its header (``meta``), the declared units and the numeric columns."""

    name: str
    path: Path
    meta: dict[str, str]
    units: dict[str, str]
    columns: dict[str, FloatArray] = field(repr=False)

    def __getitem__(self, column: str) -> FloatArray:
        try:
            return self.columns[column]
        except KeyError:
            raise KeyError(
                f"{self.name}: no column {column!r}; columns: {', '.join(self.columns)}"
            ) from None

    @property
    def source(self) -> str:
        return self.meta["source"]

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0


def _parse_units(path: Path, text: str) -> dict[str, str]:
    units: dict[str, str] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        col, sep, unit = item.partition("=")
        if not sep or not col.strip() or not unit.strip():
            raise DataFileError(
                f"{path.name}: header 'units' entry {item!r} is not of the form column=unit"
            )
        units[col.strip()] = unit.strip()
    return units


def load(name_or_path: str | Path, schema: dict[str, str] | None = None) -> Dataset:
    """Load and check a data file: a data set name from :data:`SCHEMAS` or a path.

    For a path, ``schema`` ({column: unit}) defaults to the schema of the file's stem when it is
    a known data set name; a path with neither is checked for its header only.
    """
    path = Path(name_or_path)
    if path.suffix != ".csv":
        if str(name_or_path) not in SCHEMAS:
            raise DataFileError(
                f"unknown data set {str(name_or_path)!r}; known: {', '.join(SCHEMAS)}"
            )
        path = DATA_DIR / f"{name_or_path}.csv"
    name = path.stem
    if schema is None:
        schema = SCHEMAS.get(name)
    if not path.is_file():
        raise DataFileError(f"data file {path} does not exist")
    meta: dict[str, str] = {}
    body: list[str] = []
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DataFileError(f"{path.name}: not UTF-8 text ({exc.reason} at byte {exc.start})"
                            ) from None
    except OSError as exc:
        raise DataFileError(f"data file {path}: cannot read: {exc.strerror or exc}") from None
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("#"):
            key, sep, value = stripped.lstrip("#").partition(":")
            if sep:
                meta[key.strip().lower()] = value.strip()
        elif stripped:
            body.append(stripped)
    missing = [k for k in HEADER_KEYS if not meta.get(k)]
    if missing:
        raise DataFileError(
            f"{path.name}: header comment lacks {', '.join(missing)} "
            f"(every data file names its {', '.join(HEADER_KEYS)})"
        )
    units = _parse_units(path, meta["units"])
    if not body:
        raise DataFileError(f"{path.name}: no column header row and no data")
    rows = list(csv.reader(body))
    header = [h.strip() for h in rows[0]]
    if len(set(header)) != len(header):
        raise DataFileError(f"{path.name}: repeated column names in {header}")
    for col in header:
        if col not in units:
            raise DataFileError(f"{path.name}: column {col!r} has no unit in the 'units' header")
    if schema is not None:
        for col, unit in schema.items():
            if col not in header:
                raise DataFileError(
                    f"{path.name}: missing column {col!r} (unit {unit!r}); expected columns "
                    f"{', '.join(schema)}, found {', '.join(header)}"
                )
            if units[col] != unit:
                raise DataFileError(
                    f"{path.name}: column {col!r} has unit {units[col]!r}, expected {unit!r}"
                )
    values: dict[str, list[float]] = {col: [] for col in header}
    for lineno, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise DataFileError(
                f"{path.name}: data row {lineno} has {len(row)} values, expected {len(header)}"
            )
        for col, text in zip(header, row, strict=True):
            try:
                v = float(text)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise DataFileError(
                    f"{path.name}: data row {lineno}, column {col!r}: {text!r} is not a "
                    "finite number"
                )
            values[col].append(v)
    if len(rows) < 2:
        raise DataFileError(f"{path.name}: no data rows")
    columns = {col: np.asarray(v, float) for col, v in values.items()}
    return Dataset(name, path, meta, {c: units[c] for c in header}, columns)


# ---------------------------------------------------------------- conversions


def rho_g_h(rho: float = LOBOVSKY_RHO, h: float = LOBOVSKY_H, g: float = G) -> float:
    """The pressure scale rho g H [Pa] (2934.2 Pa = 29.342 mbar for Lobovsky et al.)."""
    return rho * g * h


def mbar_to_pstar(p_mbar: FloatArray | float, rho: float = LOBOVSKY_RHO, h: float = LOBOVSKY_H,
                  g: float = G) -> FloatArray:
    """p* = p / (rho g H) for a pressure in mbar (1 mbar = 100 Pa)."""
    return np.asarray(p_mbar, float) * PA_PER_MBAR / rho_g_h(rho, h, g)


def lobovsky_bands() -> dict[str, FloatArray]:
    """Lobovsky et al. (2014) table 2 in dimensionless form: z [m], median, lo, hi as p*."""
    d = load("lobovsky_2014_peak_pressure")
    return {
        "sensor": d["sensor"].astype(int),
        "z": d["z"] * 1e-3,
        "median": mbar_to_pstar(d["median"]),
        "lo": mbar_to_pstar(d["p2.5"]),
        "hi": mbar_to_pstar(d["p97.5"]),
    }


# ---------------------------------------------------------------- data uncertainty u_D
# (docs/method.md section 9).  Martin & Moyce tabulate the front at marks: every Z is an odd
# multiple of 1/9 (marks a/9 = 0.25 in apart on a = 2.25 in) and every H* a multiple of 1/18
# (marks H/18 = 0.25 in apart): the times were read when the front or the column top passed a
# mark.  The position between marks is known to half a mark spacing, taken as u_D (about 95 %
# coverage of a reading error spread uniformly over the spacing).
MARTIN_MOYCE_U_Z = 1.0 / 18.0  # half of the 1/9 mark spacing in Z = z/a
MARTIN_MOYCE_U_H = 1.0 / 36.0  # half of the 1/18 mark spacing in H* = h/H


def martin_moyce_u_T(z: float) -> float:
    """u_D of the experimental T at which the front reaches Z = ``z``: the position reading
    uncertainty carried into time through the local slope dT/dZ of the table."""
    d = load("martin_moyce_1952_surge_front")
    T, Z = d["T"], d["Z"]
    k = int(np.clip(np.searchsorted(Z, z), 1, len(Z) - 1))
    slope = (T[k] - T[k - 1]) / (Z[k] - Z[k - 1])
    return float(abs(slope) * MARTIN_MOYCE_U_Z)


def lobovsky_u_peak(sensor: int, simulated: float) -> float:
    """u_D of a Lobovsky first-impact peak (p*): the half-width of the measured 2.5-97.5 %
    band on the side of the simulated value (the band over 100 repeats is itself a 95 %
    interval, the coverage of u_num)."""
    band = lobovsky_bands()
    k = int(np.flatnonzero(band["sensor"] == sensor)[0])
    median = float(band["median"][k])
    return float(band["hi"][k] - median if simulated >= median else median - band["lo"][k])
