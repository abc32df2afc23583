"""The nine injected bugs of issue 16 (``tests/mutants.py``) against the conformance kit and
against ``mpsbench check --against reference``.

Each mutant must fail the checks named here (each of which a correct backend passes:
``tests/test_conformance.py`` runs the whole kit on the reference and numba backends).  The
smoke-tier side (``.ci/validate_smoke.sh`` + ``mpsbench compare``) is
``test_smoke_and_compare_catch_every_mutant`` (slow).  docs/solver-contract.md section 11 has
the table.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from mpsbench.solvers.reference import ReferenceSolver

from mpsbench.testing import check_solver
from mpsbench.testing.agreement import compare_solvers
from tests import mutants

CAUGHT_BY_KIT: dict[type[ReferenceSolver], set[str]] = {
    mutants.LaplacianTimes11: {"check_laplacian_oracle_koshizuka-oka",
                               "check_laplacian_oracle_xu-jin", "check_stable_dt_rule"},
    mutants.Pgm1JPlus: {"check_gradient_oracle_pgm1", "check_hydrostatic"},
    mutants.Pgm23Symmetric: {"check_gradient_oracle_pgm2", "check_gradient_oracle_pgm3",
                             "check_momentum_pgm2", "check_momentum_pgm3"},
    mutants.WallsOutOfDensity: {"check_n0_lattice", "check_hydrostatic"},
    mutants.StableDtTimes2: {"check_lifecycle", "check_stable_dt_rule"},
    mutants.StableDtTimes2Unfixed: {"check_stable_dt_rule"},
    mutants.GravityTwice: {"check_free_fall", "check_hydrostatic"},
    mutants.StabilizedSurface: {"check_stabilization_inner_only"},
    mutants.ShortPeriod: {"check_periodic_crossing"},
}

# the problems of ``--against reference`` that tell each mutant from the reference (a fixed
# time step is given to both, so the two time-step bugs are invisible there by design)
CAUGHT_BY_AGREEMENT: dict[type[ReferenceSolver], set[str]] = {
    mutants.LaplacianTimes11: {"column in tank, pgm1", "diffusion, jittered periodic"},
    mutants.Pgm1JPlus: {"column in tank, pgm1"},
    mutants.Pgm23Symmetric: {"column in tank, pgm2", "column in tank, pgm3"},
    mutants.WallsOutOfDensity: {"column in tank, pgm1"},
    mutants.StableDtTimes2: set(),
    mutants.StableDtTimes2Unfixed: set(),
    mutants.GravityTwice: {"column in tank, pgm1"},
    mutants.StabilizedSurface: {"column in tank, stabilization"},
    mutants.ShortPeriod: {"periodic box, drift across the edges",
                          "channel, moving lid (Couette)"},
}


def test_the_tables_cover_all_nine() -> None:
    assert set(CAUGHT_BY_KIT) == set(mutants.MUTANTS) == set(CAUGHT_BY_AGREEMENT)
    assert len(mutants.MUTANTS) == 9


@pytest.mark.parametrize("mutant", mutants.MUTANTS, ids=lambda m: m.name)
def test_the_kit_catches_the_mutant(mutant: type[ReferenceSolver]) -> None:
    results = check_solver(mutant, on_fail="return")
    failed = {r.check for r in results if r.outcome == "fail"}
    missing = CAUGHT_BY_KIT[mutant] - failed
    assert not missing, f"{mutant.name}: not caught by {sorted(missing)} (failed: {failed})"


@pytest.mark.parametrize("mutant", mutants.MUTANTS, ids=lambda m: m.name)
def test_against_reference_tells_the_mutant_apart(mutant: type[ReferenceSolver]) -> None:
    diffs = {d.problem: d for d in compare_solvers(mutant, "reference")}
    differ = {name for name, d in diffs.items() if d.agrees() is False}
    want = CAUGHT_BY_AGREEMENT[mutant]
    assert want <= differ, f"{mutant.name}: agrees on {sorted(want - differ)}"
    if not want:  # the time-step bugs: with a fixed dt the step itself is the reference's
        assert not differ, f"{mutant.name}: differs on {sorted(differ)}"


# The smoke-tier runs that show each mutant to ``mpsbench compare`` (the committed baseline's
# records of those runs; the mutant stands in for the reference backend, as a bug shipped in a
# backend would): case and the parameters that pick the runs out of the smoke plan.
KO_SMOKE = {"geometry": "koshizuka-oka", "l0": 0.0146}
CAUGHT_BY_SMOKE: dict[type[ReferenceSolver], tuple[str, dict[str, object]]] = {
    mutants.LaplacianTimes11: ("couette", {"l0": 5e-05, "laplacian": "xu-jin",
                                           "wall_velocity": "prescribed", "drift": 0.0}),
    mutants.Pgm1JPlus: ("dam-break", {**KO_SMOKE, "variant": "wc-mps", "gradient": "pgm1"}),
    mutants.Pgm23Symmetric: ("dam-break", {**KO_SMOKE, "variant": "wc-mps",
                                           "gradient": ("pgm2", "pgm3")}),
    mutants.WallsOutOfDensity: ("dam-break", {**KO_SMOKE, "variant": "wc-mps",
                                              "gradient": "pgm1"}),
    mutants.StableDtTimes2: ("dam-break", {**KO_SMOKE, "variant": "wc-mps", "gradient": "pgm1"}),
    mutants.StableDtTimes2Unfixed: ("dam-break", {**KO_SMOKE, "variant": "wc-mps",
                                                  "gradient": "pgm1"}),
    mutants.GravityTwice: ("dam-break", {**KO_SMOKE, "variant": "wc-mps", "gradient": "pgm1"}),
    mutants.StabilizedSurface: ("dam-break", {**KO_SMOKE, "variant": "iwc-mps"}),
    mutants.ShortPeriod: ("couette", {"drift": ("> 0",)}),
}


def _picks(params: dict[str, object], want: dict[str, object]) -> bool:
    for key, value in want.items():
        have = params.get(key)
        if value == ("> 0",):
            if not (isinstance(have, float) and have > 0):
                return False
        elif isinstance(value, tuple):
            if have not in value:
                return False
        elif have != value:
            return False
    return True


@pytest.mark.slow
@pytest.mark.parametrize("mutant", mutants.MUTANTS, ids=lambda m: m.name)
def test_smoke_and_compare_catch_every_mutant(mutant: type[ReferenceSolver],
                                              tmp_path: Path) -> None:
    from mpsbench.cases import get_case
    from mpsbench.results.compare import compare, load_results
    from mpsbench.results.sweep import plan, run_tasks
    from mpsbench.run.protocol import SOLVERS

    name, want = CAUGHT_BY_SMOKE[mutant]
    tasks = [t for t in plan(get_case(name), ["reference"], "smoke") if _picks(t.params, want)]
    assert tasks, f"no smoke run of {name} matches {want}"
    real = SOLVERS.get("reference")
    SOLVERS.register("reference", mutant, replace=True)
    try:
        records = run_tasks(tasks, tmp_path, jobs=1)
    finally:
        SOLVERS.register("reference", real, replace=True)
    baseline = [r for r in load_results(BASELINE) if r["case"] == name]
    cmp = compare(baseline, records)
    assert cmp.matched == len(tasks), "the baseline lacks these smoke runs: refresh it"
    assert cmp.regressions, f"{mutant.name}: no regression in {[t.run_id for t in tasks]}"
    print(mutant.name, [(c.record, c.metric, c.baseline, c.current) for c in cmp.regressions])


BASELINE = Path(__file__).resolve().parents[1] / "validations" / "baselines" / "smoke"
