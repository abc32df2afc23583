"""Tiny cases for the validate-all / compare / report tests (seconds, not minutes).

``ToyDiffusion`` runs a real (very small) periodic diffusion problem on a solver through the
runner, so records carry real wall times and particle counts; ``ToyCounter`` needs no solver;
``Shaky`` has a run that completes, one that diverges and one that raises, and a check that
holds, one that does not and one that cannot decide.
Both have knobs (class attributes) the tests turn: ``error_scale`` multiplies the error metric
(a model change that doubles the error), ``fail_check`` makes a check fail, ``broken_figures``
makes the figure code raise, ``claim_margin`` decides ``ToyDiffusion``'s claim (its rule:
xu-jin's error <= margin x koshizuka-oka's; 0 refutes it).  :func:`only_cases` swaps the case
registry for the test.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from mpsbench.solvers.reference import ReferenceSolver

from mpsbench.cases import CASES, Case, CaseCheck, CaseRun, Claim, Param
from mpsbench.cases.refinement import SPACE, Refinement
from mpsbench.run.protocol import SOLVERS, Status
from mpsbench.run.runner import RunResult, run
from mpsbench.testing.problems import diffusion_problem


class ToyDiffusion(Case):
    name = "toy-diffusion"
    title = "Toy diffusion"
    description = "Decay of sin(2 pi x) sin(2 pi y) on a periodic unit square, a few steps."
    params = (
        Param("laplacian", "xu-jin", "Laplacian model", kind=str,
              choices=("koshizuka-oka", "xu-jin")),
        Param("n_side", 8, "particles per side", kind=int, minimum=4),
        Param("steps", 3, "time steps", kind=int, minimum=1),
    )
    tiers = {
        "smoke": [{"laplacian": ["koshizuka-oka", "xu-jin"]}],
        "quick": [{"laplacian": ["koshizuka-oka", "xu-jin"], "n_side": [8, 10]}],
        "paper": [{"laplacian": ["koshizuka-oka", "xu-jin"], "n_side": [8, 10, 12]}],
    }
    metrics = {"l2_error": "relative L2 error of phi after the run [-]",
               "peak": "max |phi| at the end [-]"}
    compare = {"peak": ("equal", 0.01)}
    headline = "errors"
    refinements = (Refinement("n_side", ("l2_error", "peak"), SPACE, order=2.0, inverse=True),)
    error_scale = 1.0
    fail_check = False
    broken_figures = False
    claim_margin = 1e9
    claim = Claim("T1", "xu-jin is at least as accurate as koshizuka-oka on the toy problem.",
                  "tests/fake_cases.py")

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        problem = diffusion_problem(params["laplacian"], n_side=params["n_side"], value=None,
                                    amplitude=0.0)
        x, y = problem.particles.pos[:, 0], problem.particles.pos[:, 1]
        res = run(solver, problem, max_steps=params["steps"])
        assert res.final is not None
        decay = np.exp(-8 * math.pi**2 * res.time)
        exact = decay * np.sin(2 * math.pi * x) * np.sin(2 * math.pi * y)
        phi = res.final.fields["phi"]
        err = float(np.linalg.norm(phi - exact) / np.linalg.norm(exact)) * self.error_scale
        return CaseRun({"l2_error": err, "peak": float(np.abs(phi).max())}, [res],
                       {"phi": phi, "x": x})

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        worst = max(float(r.get("l2_error") or math.inf) for r in records)
        limit = 1e-9 if self.fail_check else 0.5
        detail = f"worst {worst:.3g} < {limit:g}"
        return [CaseCheck("l2 error below limit", worst < limit, detail),
                CaseCheck("undecided check", None, "no data to decide")]

    def claims(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        rule = f"xu-jin's l2_error <= {self.claim_margin:g} x koshizuka-oka's (same n_side)"
        by = {r["laplacian"]: r for r in records if r.get("status") == "completed"}
        if not {"xu-jin", "koshizuka-oka"} <= set(by):
            return [self.claim.no_data(rule, "runs of both models")]
        a, b = by["xu-jin"]["l2_error"], by["koshizuka-oka"]["l2_error"]
        return [self.claim.verdict(a <= self.claim_margin * b, rule,
                                   f"xu-jin {a:.3g}, koshizuka-oka {b:.3g}",
                                   [by[m]["run_id"] for m in ("xu-jin", "koshizuka-oka")])]

    def tables(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        df = pd.DataFrame(records)
        return {"errors": df.pivot_table(index="n_side", columns="laplacian", values="l2_error"),
                "timing": df[["run_id", "wall_time_s"]].set_index("run_id")}

    def figures(self, records: list[dict[str, Any]], arrays: Callable[[str], dict[str, np.ndarray]],
                outdir: Path) -> list[Path]:
        if self.broken_figures:
            raise RuntimeError("figure code is broken")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(4, 3))
        for rec in records:
            arr = arrays(rec["run_id"])
            if arr:
                ax.plot(arr["x"], arr["phi"], ".", ms=2, label=rec["laplacian"])
        ax.set_xlabel("x [m]")
        ax.legend()
        path = outdir / "profile.png"
        fig.savefig(path, dpi=60)
        plt.close(fig)
        return [path]

    def findings(self, records: list[dict[str, Any]]) -> str:
        best = min(records, key=lambda r: float(r.get("l2_error") or math.inf))
        return (f"**{best['laplacian']}** has the smallest error ({best['l2_error']:.3g}).\n\n"
                "- every run is `tiny`\n- and *fast*")


class ToyCounter(Case):
    name = "toy-counter"
    title = "Toy counter"
    description = "No solver: metrics from a formula."
    params = (Param("k", 1, "a number", kind=int, minimum=1),)
    tiers = {"smoke": [{"k": [1]}], "quick": [{"k": [1, 2]}], "paper": [{"k": [1, 2, 3]}]}
    metrics = {"drift": "a drift [-]", "score": "a score [-]"}
    compare = {"score": ("higher", 0.1)}
    drift_scale = 1.0

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        return CaseRun({"drift": 0.01 * params["k"] * self.drift_scale, "score": 10.0,
                        "label": f"k{params['k']}"})

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        ok = all((r.get("drift") or math.inf) < 1 for r in records)
        return [CaseCheck("drift small", ok, "drift < 1")]


class Shaky(Case):
    """Three runs: one completes, one diverges, one fails (raises)."""

    name = "shaky"
    params = (Param("mode", "ok", "what the run does", kind=str,
                    choices=("ok", "diverge", "raise")),)
    tiers = {"smoke": [{"mode": ["ok", "diverge", "raise"]}]}
    metrics = {"value": "a number [-]"}

    def execute(self, params: dict[str, Any], solver: str) -> CaseRun:
        if params["mode"] == "raise":
            raise RuntimeError("solver crashed \x1b[31mred\x1b[0m")  # escapes XML cannot hold
        status = Status.DIVERGED if params["mode"] == "diverge" else Status.COMPLETED
        reason = "velocity above 100 m/s at step 3" if status is Status.DIVERGED else ""
        result = RunResult(status, reason, 0.1, 3, 0.01, 300.0, 100)
        return CaseRun({"value": 1.0}, [result])

    def checks(self, records: list[dict[str, Any]]) -> list[CaseCheck]:
        return [CaseCheck("value is one", True, "1 == 1"),
                CaseCheck("never holds", False, "0.3 > 0.1"),
                CaseCheck("cannot decide", None, "needs two resolutions")]


@contextmanager
def only_cases(*cases: Case) -> Iterator[None]:
    """Make ``cases`` the only registered cases for the duration (the built-ins are hidden)."""
    saved, scanned = dict(CASES._entries), CASES._scanned
    CASES._entries.clear()
    CASES._scanned = True
    try:
        for case in cases:
            CASES.register(case.name, case, replace=True)
        yield
    finally:
        CASES._entries.clear()
        CASES._entries.update(saved)
        CASES._scanned = scanned


class ToyReference(ReferenceSolver):
    """The reference backend under another name: a second solver for multi-solver reports."""

    name = "toy-reference"
    version = "0.0.1"


@contextmanager
def extra_solver() -> Iterator[str]:
    SOLVERS.register(ToyReference.name, ToyReference, replace=True)
    try:
        yield ToyReference.name
    finally:
        SOLVERS.unregister(ToyReference.name)
