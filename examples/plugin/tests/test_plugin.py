"""The example plugin's own tests: what a plugin author puts in their test suite.

Two tools from mpsbench do the work:

* ``parametrize_solver_checks`` (the conformance kit): one pytest test per protocol check --
  API shape, capabilities honoured, determinism, conservation, divergence reporting.  Checks
  the solver does not declare the capabilities for are skipped with the reason.
* ``run_case``: runs a validation case (here the 2-D diffusion case at the ``smoke`` tier) on
  the solver through the same machinery as ``mpsbench validate`` and returns the records and
  the case's own checks.

Run with ``pytest`` after ``pip install ./examples/plugin[test]`` (mpsbench installed too).
"""

from __future__ import annotations

import pytest
from mpsbench_example.solver import ExampleSolver

from mpsbench.physics.laplacians import KoshizukaOka, get_laplacian
from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.operators import lattice_constants, lattice_pairs
from mpsbench.physics.weights import get_weight
from mpsbench.run.protocol import SOLVERS
from mpsbench.testing import parametrize_solver_checks
from mpsbench.testing.plugins import run_case


def test_entry_points_are_installed():
    assert get_laplacian("ko-local").name == "ko-local"
    assert SOLVERS.get("example") is ExampleSolver


def test_ko_local_equals_lm1_on_a_full_lattice():
    pos, box = lattice_pairs(10, 0.1)  # periodic, l0 = 0.1 m
    w, re = get_weight("wf2"), 0.31
    pairs = build_pairs(pos, re, box)
    n0, lam = lattice_constants(w, re / 0.1, 0.1)
    local = get_laplacian("ko-local").coefficients(pairs, w, re, n0, lam)
    lm1 = KoshizukaOka().coefficients(pairs, w, re, n0, lam)
    assert abs(local - lm1).max() <= 1e-12 * abs(lm1).max()


# One test per conformance check, e.g. test_conformance[example-check_momentum_pgm2].
@parametrize_solver_checks("example")
def test_conformance(solver, check):
    check(solver)


def test_diffusion_case(tmp_path):
    result = run_case("diffusion", "example", tier="smoke", laplacian="ko-local", out=tmp_path)
    result.assert_ok()  # every run completed and none of the case's checks failed
    assert result.records and {r["laplacian"] for r in result.records} == {"ko-local"}


def test_other_laplacians_are_refused(tmp_path):
    result = run_case("diffusion", "example", tier="smoke", laplacian="xu-jin", out=tmp_path)
    assert all(r["status"] == "failed" for r in result.records)
    assert "'xu-jin' not supported" in result.records[0]["reason"]
    with pytest.raises(AssertionError, match="not supported"):
        result.assert_ok()


def test_ko_local_runs_on_the_numba_backend_too(tmp_path):
    """The formulas are the plugin's own: the numba backend compiles them into its kernels, so
    the smoke diffusion runs give the reference's numbers (numba needs mpsbench[fast])."""
    pytest.importorskip("numba")
    ref = run_case("diffusion", "reference", tier="smoke", laplacian="ko-local",
                   out=tmp_path / "ref")
    fast = run_case("diffusion", "numba", tier="smoke", laplacian="ko-local",
                    out=tmp_path / "numba")
    ref.assert_ok()
    fast.assert_ok()
    def by_run(records):
        return {(r["l0"], r["dt_check"]): r["l2_error"] for r in records}

    want, got = by_run(ref.records), by_run(fast.records)
    assert len(want) == len(ref.records) and got.keys() == want.keys()
    for key, value in want.items():
        assert got[key] == pytest.approx(value, rel=1e-8)
