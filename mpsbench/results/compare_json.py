"""``mpsbench compare --json``: a comparison as JSON, and back (schema ``mpsbench.compare/1``).

The document (every key always present; docs/ci.md shows an example)::

    schema       "mpsbench.compare/1"
    verdict      "regression" (exit status 1) or "ok" (exit status 0)
    baseline     {"path", "records", "tier", "mpsbench_version", "git_commit", "machine"}
    current      the same for the current set
    matched      records present in both (matched by case, solver and parameters)
    compared     metric values held against a tolerance
    counts       {kind: number of changes} for every kind: regression, unheld, worse, better,
                 info, appeared, vanished
    tolerance    {"rtol", "atol"}: the command-line overrides (null: each metric's own rule)
    changes      [{"kind", "record", "metric", "baseline", "current", "relative", "rule",
                   "note"}], in the order the text report lists them; "record" is the run id,
                 "metric" is "" for a whole record (appeared, vanished) and "status" for a run
                 that now diverges or fails; "relative" is (current - baseline) / |baseline|
                 or null when a value is not a number
    timing       [{"case", "solver", "runs", "wall time base [s]", "wall time now [s]",
                   "wall time ratio", "median particle-steps/s ratio"}] (informational)

Numbers that JSON cannot carry (NaN, +-infinity) are the strings ``"NaN"``, ``"Infinity"`` and
``"-Infinity"``; :func:`comparison_from_json` reads them back as floats.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from mpsbench.results.compare import ORDER, Change, CompareError, Comparison

SCHEMA = "mpsbench.compare/1"
META = ("tier", "mpsbench_version", "git_commit", "machine")
CHANGE_FIELDS = ("kind", "record", "metric", "baseline", "current", "rule", "note")
_NON_FINITE = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def _json_value(v: Any) -> Any:
    if hasattr(v, "item") and not isinstance(v, (str, bytes)):
        v = v.item()  # numpy scalar -> Python
    if isinstance(v, float) and not math.isfinite(v):
        return "NaN" if math.isnan(v) else ("Infinity" if v > 0 else "-Infinity")
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    return str(v)


def _from_json(v: Any) -> Any:
    return _NON_FINITE.get(v, v) if isinstance(v, str) else v


def comparison_to_json(
    cmp: Comparison, baseline: str, current: str, *,
    meta: tuple[dict[str, Any], dict[str, Any]] = ({}, {}),
    rtol: float | None = None, atol: float | None = None,
) -> dict[str, Any]:
    """The JSON document of a comparison (see the module docstring)."""
    sides = {}
    for label, path, n, rec in (("baseline", baseline, cmp.n_baseline, meta[0]),
                                ("current", current, cmp.n_current, meta[1])):
        sides[label] = {"path": str(path), "records": n,
                        **{k: _json_value(rec.get(k)) for k in META}}
    timing = [] if cmp.timing.empty else [
        {str(k): _json_value(v) for k, v in row.items()}
        for row in cmp.timing.to_dict(orient="records")]
    return {
        "schema": SCHEMA,
        "verdict": "regression" if cmp.regressions else "ok",
        **sides,
        "matched": cmp.matched,
        "compared": cmp.compared,
        "counts": {kind: cmp.count(kind) for kind in ORDER},
        "tolerance": {"rtol": rtol, "atol": atol},
        "changes": [{**{f: _json_value(getattr(ch, f)) for f in CHANGE_FIELDS},
                     "relative": _json_value(ch.relative)} for ch in cmp.changes],
        "timing": timing,
    }


def comparison_from_json(data: Any) -> Comparison:
    """The :class:`Comparison` a document describes; CompareError when it is not one."""
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        found = data.get("schema") if isinstance(data, dict) else type(data).__name__
        raise CompareError(f"not a {SCHEMA} document (schema: {found!r})")
    try:
        changes = [Change(**{f: _from_json(c[f]) for f in CHANGE_FIELDS})
                   for c in data["changes"]]
        cmp = Comparison(int(data["baseline"]["records"]), int(data["current"]["records"]),
                         int(data["matched"]), int(data["compared"]), changes,
                         pd.DataFrame([{k: _from_json(v) for k, v in row.items()}
                                       for row in data["timing"]]))
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise CompareError(f"malformed {SCHEMA} document: {type(exc).__name__}: {exc}") from None
    unknown = {c.kind for c in changes} - set(ORDER)
    if unknown:
        raise CompareError(f"malformed {SCHEMA} document: unknown change kind(s) "
                           f"{', '.join(sorted(unknown))}; known: {', '.join(ORDER)}")
    return cmp
