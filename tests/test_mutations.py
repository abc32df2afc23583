"""The nine injected bugs of issue 16 (``tests/mutants.py``) against the conformance kit and
against ``mpsbench check --against reference``.

Each mutant must fail the checks named here (each of which a correct backend passes:
``tests/test_conformance.py`` runs the whole kit on the reference and numba backends).  The
smoke-tier side (``.ci/validate_smoke.sh`` + ``mpsbench compare``) is
``test_smoke_and_compare_catch_every_mutant`` (slow).  docs/solver-contract.md section 11 has
the table.
"""

from __future__ import annotations

import pytest

from mpsbench.testing import check_solver
from mpsbench.testing.agreement import compare_solvers
from tests import mutants

CAUGHT_BY_KIT: dict[type, set[str]] = {
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
CAUGHT_BY_AGREEMENT: dict[type, set[str]] = {
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
def test_the_kit_catches_the_mutant(mutant: type) -> None:
    results = check_solver(mutant, on_fail="return")
    failed = {r.check for r in results if r.outcome == "fail"}
    missing = CAUGHT_BY_KIT[mutant] - failed
    assert not missing, f"{mutant.name}: not caught by {sorted(missing)} (failed: {failed})"


@pytest.mark.parametrize("mutant", mutants.MUTANTS, ids=lambda m: m.name)
def test_against_reference_tells_the_mutant_apart(mutant: type) -> None:
    diffs = {d.problem: d for d in compare_solvers(mutant, "reference")}
    differ = {name for name, d in diffs.items() if d.agrees() is False}
    want = CAUGHT_BY_AGREEMENT[mutant]
    assert want <= differ, f"{mutant.name}: agrees on {sorted(want - differ)}"
    if not want:  # the time-step bugs: with a fixed dt the step itself is the reference's
        assert not differ, f"{mutant.name}: differs on {sorted(differ)}"
