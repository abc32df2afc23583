"""The cross-code table: one case's runs on MPS backends and on an outside code (a backend that
ignores the MPS model settings, such as PySPH) side by side, accuracy and throughput.

An outside code runs each physical parameter set once (its not-applicable parameters at the
case defaults, :func:`mpsbench.results.sweep.plan`); an MPS backend runs it once per model.  So
the rows are keyed by the physical parameters that vary (geometry, resolution, variant, ...)
and the solver, with a ``models`` column saying which MPS model a row is ("own kernel" for the
outside code).  Columns: the case's ``accuracy`` metrics, then particle-steps per second
(``particle_steps_per_s``: a PySPH PEC step evaluates forces twice, an MPS step once),
simulated seconds per wall second (the fair speed figure across schemes whose time steps
differ), particles, steps and wall time.  Unsupported runs are left out; runs that did not
complete keep their row with their status.
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from mpsbench.cases import Case
from mpsbench.results.records import NOT_RUN

SPEED_COLUMNS = ("particle_steps_per_s", "sim_s_per_wall_s", "n_particles", "n_steps",
                 "wall_time_s")


def not_applicable(records: list[dict[str, Any]]) -> list[str]:
    """The parameters some record says do not apply to its solver."""
    return sorted({n for r in records for n in str(r.get("not_applicable") or "").split(",")
                   if n})


def accuracy_metrics(case: Case) -> list[str]:
    return list(case.accuracy) or list(case.metrics)[:3]


def cross_code_table(case: Case, records: list[dict[str, Any]]) -> pd.DataFrame:
    """The table (empty unless the records hold an outside code's runs and another solver's)."""
    na = not_applicable(records)
    solvers = {str(r.get("solver")) for r in records}
    if not na or len(solvers) < 2:
        return pd.DataFrame()
    made = [r for r in records if r.get("status") not in NOT_RUN]
    if not made:
        return pd.DataFrame()
    df = pd.DataFrame.from_records(made)
    physical = [p.name for p in case.params if p.name in df.columns and p.name not in na
                and df[p.name].astype(str).nunique() > 1]
    own = df["not_applicable"].fillna("").astype(str) != "" if "not_applicable" in df else (
        pd.Series(False, index=df.index))
    models = [n for n in na if n in df.columns]
    df["models"] = ["own kernel" if o else ", ".join(f"{n}={r[n]}" for n in models)
                    for o, (_, r) in zip(own, df.iterrows(), strict=True)]
    if {"wall_time_s", "sim_time_s"} <= set(df.columns):
        wall = pd.to_numeric(df["wall_time_s"], errors="coerce")
        sim = pd.to_numeric(df["sim_time_s"], errors="coerce")
        df["sim_s_per_wall_s"] = sim / wall.where(wall > 0)
    metrics = [m for m in accuracy_metrics(case) if m in df.columns]
    status = ["status"] if (df["status"] != "completed").any() else []
    cols = [*physical, "solver", "models", *status, *metrics,
            *[c for c in SPEED_COLUMNS if c in df.columns]]
    out = df[cols].sort_values([*physical, "solver", "models"], kind="stable")
    return out.reset_index(drop=True)


def cross_code_caption(case: Case, records: list[dict[str, Any]]) -> str:
    na = not_applicable(records)
    outside = sorted({str(r.get("solver")) for r in records if r.get("not_applicable")})
    return (f"Same {case.name} runs on every solver.  {', '.join(outside)}: its own kernel and "
            f"time step ({', '.join(na)} do not apply; one run per physical parameter set).  "
            "particle_steps_per_s counts solver steps (a PySPH PEC step evaluates forces twice, "
            "an MPS step once; their time steps differ too): sim_s_per_wall_s is the like-for-"
            "like speed.  Timings are wall-clock on the machine and load of the run.")
