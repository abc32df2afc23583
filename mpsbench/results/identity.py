"""Run identity: which runs are the same run, whatever they are called.

A run is identified by a hash of its case, its solver (with the solver's options) and its full,
normalised parameter set (every parameter of the case, defaults included, each value through
the case's :meth:`~mpsbench.cases.Param.check`), stored in every record as ``run_hash``.  The
readable ``run_id`` (file name, labels) is separate: it names what a sweep varies, so the same
run planned by two different sweeps gets two readable names but one hash, and resuming or
widening a grid (:func:`mpsbench.results.sweep.run_tasks`) skips it either way.

Records written before the hash existed are matched by recomputing it from their parameters
(a parameter a record lacks takes the case's default, as ``mpsbench compare`` does).

Solver options: a solver given with options (issue #14, e.g. ``numba:threads=1``) is another
run than the bare solver.  A task's solver may be such a spec (``NAME:key=value,...``): its
options are split off; records carry the options in the ``OPTIONS_COLUMN`` column (text
``key=value,...`` or a mapping), which :func:`record_hash` reads when it is there.  No options,
an empty text and an empty mapping are the same (the backend's defaults).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from typing import Any

HASH_COLUMN = "run_hash"
OPTIONS_COLUMN = "solver_options"
HASH_LENGTH = 16  # hex digits (64 bits): no collision in any study that fits a disk


def canonical(value: Any) -> Any:
    """A JSON value that is equal for equal parameter values (-0.0 is 0.0; tuples are lists)."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return repr(value)
        return 0.0 if value == 0 else float(value)
    if hasattr(value, "item") and not isinstance(value, (list, tuple, dict)):
        return canonical(value.item())  # a numpy scalar
    if isinstance(value, (list, tuple)):
        return [canonical(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    return str(value)


Options = Mapping[str, Any] | str | None


def canonical_options(options: Options) -> str:
    """Solver options as one text: ``key=value,...`` (a mapping sorted by key), '' for none."""
    if not options:
        return ""
    if isinstance(options, str):
        return options.strip()
    return ",".join(f"{k}={canonical(v)}" for k, v in sorted(options.items(), key=lambda kv:
                                                               str(kv[0])))


def run_hash(case: str, solver: str, params: Mapping[str, Any], options: Options = None) -> str:
    """The identity of a run: a hex digest of case, solver, solver options and parameters."""
    payload = {
        "case": case,
        "solver": solver,
        "options": canonical_options(options),
        "params": canonical(dict(params)),
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()[:HASH_LENGTH]


def record_params(record: Mapping[str, Any], case: Any) -> dict[str, Any] | None:
    """The full, normalised parameter set of a record of ``case`` (None when a stored value
    is no longer allowed, so the record cannot be the same run as any planned one)."""
    from mpsbench.errors import ConfigError

    out: dict[str, Any] = {}
    for p in case.params:
        value = record.get(p.name, p.default)
        if value is None:
            value = p.default
        try:
            out[p.name] = p.parse(value) if isinstance(value, str) and p.kind is not str \
                else p.check(value)
        except ConfigError:
            return None
    return out


def record_options(record: Mapping[str, Any]) -> Options:
    options = record.get(OPTIONS_COLUMN)
    return options if isinstance(options, (str, Mapping)) else None


def record_hash(record: Mapping[str, Any], case: Any | None) -> str | None:
    """The identity of a stored record: recomputed from its parameters when its case is known
    (so old records and new ones agree), else the ``run_hash`` it carries (None if none)."""
    if case is not None:
        params = record_params(record, case)
        if params is not None:
            return run_hash(str(record.get("case")), str(record.get("solver")), params,
                            record_options(record))
        return None
    stored = record.get(HASH_COLUMN)
    return stored if isinstance(stored, str) and stored else None


def task_hash(case: str, solver: str, params: Mapping[str, Any], options: Options = None) -> str:
    """The identity of a planned run, computed as :func:`record_hash` will compute it from the
    run's record (through the case's parameters when the case can be loaded).  ``solver`` may
    be a spec ``NAME:key=value,...``: the options are split off, as the record stores them."""
    name, _, spec_options = solver.partition(":")
    solver, options = name, options or spec_options
    try:
        from mpsbench.cases import get_case

        case_obj = get_case(case)
    except Exception:  # noqa: BLE001 - an unknown or broken case: hash the parameters as given
        case_obj = None
    normal = record_params(params, case_obj) if case_obj is not None else None
    return run_hash(case, solver, normal if normal is not None else params, options)
