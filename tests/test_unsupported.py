"""Status ``unsupported``: a run a solver's capabilities exclude is recorded with the reason and
never fails a case; a (case, solver) with no supported run passes with nothing decided and says
so; an outside code's not-applicable parameters collapse its sweep.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import pytest
from mpsbench.solvers.reference import ReferenceSolver
from mpsbench.validations.water_jet import CASE as WATER_JET

from mpsbench.cases import get_case
from mpsbench.cli import main
from mpsbench.results.records import load_records
from mpsbench.results.sweep import plan
from mpsbench.run.protocol import SOLVERS
from tests.fake_cases import only_cases
from tests.test_isolation import TinyFlow


class NoInflowSolver(ReferenceSolver):
    """The reference backend declaring, honestly, that it has no inflow or outflow."""

    name = "fake-no-inflow"
    capabilities = dataclasses.replace(
        ReferenceSolver.capabilities,
        boundaries=ReferenceSolver.capabilities.boundaries - {"inflow", "outflow"})


class OwnKernelSolver(ReferenceSolver):
    """Declares it ignores the MPS model settings (as an outside code does)."""

    name = "fake-own-kernel"
    capabilities = dataclasses.replace(
        ReferenceSolver.capabilities,
        ignores=frozenset({"laplacians", "weights", "gradients", "radii", "time-stepping"}))


@pytest.fixture()
def fakes() -> Iterator[None]:
    for cls in (NoInflowSolver, OwnKernelSolver):
        SOLVERS.register(cls.name, cls, replace=True)
    try:
        yield
    finally:
        for cls in (NoInflowSolver, OwnKernelSolver):
            SOLVERS.unregister(cls.name)


def test_no_inflow_backend_gets_unsupported_water_jet_and_validate_all_passes(
        tmp_path: Path, fakes: None, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "all"
    with only_cases(WATER_JET, TinyFlow()):
        code = main(["validate", "all", "--tier", "smoke", "--solver", "fake-no-inflow",
                     "--jobs", "1", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.out + captured.err
    recs = load_records(out / "water-jet")
    assert recs and {r["status"] for r in recs} == {"unsupported"}
    assert all("boundary 'inflow' not supported" in r["reason"] for r in recs)
    assert {r["status"] for r in load_records(out / "tiny-flow")} == {"completed"}
    assert "PASS water-jet [fake-no-inflow]" in captured.out
    assert "no supported run" in captured.out
    assert "no supported run" in (out / "summary.md").read_text().lower()
    report = (out / "water-jet" / "report.md").read_text()
    assert "No supported run" in report and "boundary 'inflow' not supported" in report


def test_unsupported_runs_do_not_count_against_a_case_check(tmp_path: Path) -> None:
    """Dam break's "every run of the model grid completes" holds the runs that were made: the
    iwc-mps runs a backend without stabilization cannot make are unsupported, not
    divergences."""
    from mpsbench.validations.dam_break.analysis import gates

    from mpsbench.results.case_report import render_case_outputs

    ko = {"geometry": "koshizuka-oka"}
    made = [{**ko, "run_id": "a", "status": "completed", "variant": "wc-mps", "l0": 0.01,
             "front_rms_error": 0.2}]
    refused = [{**ko, "run_id": "b", "status": "unsupported", "variant": "iwc-mps", "l0": 0.005,
                "reason": "feature 'stabilization' not supported"}]
    name = "every run of the model grid completes (no divergence)"
    r = render_case_outputs(get_case("dam-break"), made + refused, tmp_path / "db")
    assert r.passed, r.failures
    first = {c.name: c for c in r.checks}[name]
    assert first.passed and first.detail.startswith("1/1")
    # the case's own rule, given every record, would count the refusal
    assert {c.name: c for c in gates(made + refused)}[name].passed is False
    assert "1 of 2 runs unsupported" in r.note


def test_an_own_kernel_backend_runs_each_physical_set_once(fakes: None) -> None:
    case = get_case("couette")
    mps = plan(case, ["reference"], "quick")
    own = plan(case, ["fake-own-kernel"], "quick")
    assert len(mps) > 60
    # L/20 and L/40 x {steady off, steady on, mirror} at the default model, and the L/80 run
    # of the refinement grid (its c_nu refinements collapse: c_nu does not apply)
    assert len(own) == 7
    assert sorted({round(1e-3 / t.params["l0"]) for t in own}) == [20, 40, 80]
    assert {t.params["laplacian"] for t in own} == {case.param("laplacian").default}
    assert {t.params["re_ratio"] for t in own} == {case.param("re_ratio").default}
    assert set(own[0].not_applicable) == {"laplacian", "weight", "re_ratio", "c_nu"}
    assert not mps[0].not_applicable


def test_a_study_file_collapses_an_own_kernel_backend_the_same_way(fakes: None) -> None:
    from mpsbench.results.study_spec import parse_study

    grid = {"laplacian": ["koshizuka-oka", "xu-jin", "khayyer-gotoh"], "re_ratio": [2.1, 3.1]}
    table = {"case": "couette", "tier": "smoke", "solvers": ["reference", "fake-own-kernel"],
             "grid": grid}
    tasks = parse_study(table, "own").tasks()
    mps = [t for t in tasks if t.solver == "reference"]
    own = [t for t in tasks if t.solver == "fake-own-kernel"]
    assert len(mps) == len(own) * 6 and own  # the six model sets are one physical set
    assert {t.params["laplacian"] for t in own} == {get_case("couette").param("laplacian").default}
    assert set(own[0].not_applicable) == {"laplacian", "weight", "re_ratio", "c_nu"}
    assert not mps[0].not_applicable
