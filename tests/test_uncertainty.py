"""GCI, observed order and validation verdicts on constructed sequences, refinement sets in
constructed records, and the model records of a case with refinement grids (docs/method.md 9)."""

from __future__ import annotations

import math

import pytest

from mpsbench.cases import Case, Param, RefinementGrid
from mpsbench.cases import uncertainty as un
from mpsbench.cases.refinement import SPACE, TIME, NumericalUncertainty, Refinement


def sequence(f0: float, c: float, p: float, steps: list[float]) -> list[float]:
    return [f0 + c * h**p for h in steps]


@pytest.mark.parametrize("p", [0.7, 1.0, 2.0, 3.3])
@pytest.mark.parametrize("r", [2.0, 1.5])
def test_known_order_constant_ratio_is_recovered_exactly(p: float, r: float) -> None:
    steps = [0.01, 0.01 * r, 0.01 * r * r]
    values = sequence(0.25, 3.0, p, steps)
    conv = un.convergence(values, steps)
    assert conv.kind == un.MONOTONE
    assert conv.order_observed
    assert conv.order == pytest.approx(p, rel=1e-10)
    assert conv.extrapolated == pytest.approx(0.25, rel=1e-10, abs=1e-13)
    # u_num = Fs |f1 - f_ext| = 1.25 c h1^p
    assert conv.safety == un.FS_THREE
    assert conv.u_num == pytest.approx(1.25 * 3.0 * 0.01**p, rel=1e-8)
    # GCI_fine = Fs |(f2 - f1)/f1| / (r^p - 1)
    f1, f2 = values[0], values[1]
    assert conv.gci == pytest.approx(1.25 * abs((f2 - f1) / f1) / (r**p - 1), rel=1e-10)
    # the coarser members get Fs |f - f_ext| too
    assert conv.u_num_at(values[2]) == pytest.approx(1.25 * 3.0 * steps[2] ** p, rel=1e-8)


def test_known_order_non_constant_ratio_is_recovered() -> None:
    steps = [0.005, 0.0073, 0.0146]  # the dam-break spacings: r21 = 1.46, r32 = 2
    values = sequence(-1.0, 0.4, 1.3, steps)
    conv = un.convergence(values, steps)
    assert conv.kind == un.MONOTONE
    assert conv.order == pytest.approx(1.3, rel=1e-9)
    assert conv.extrapolated == pytest.approx(-1.0, rel=1e-9)


def test_order_from_decreasing_sequence_and_unsorted_input() -> None:
    steps = [0.4, 0.1, 0.2]
    values = sequence(2.0, -5.0, 1.0, steps)  # approaches 2 from below
    conv = un.convergence(values, steps)
    assert conv.steps == (0.1, 0.2, 0.4)
    assert conv.order == pytest.approx(1.0, rel=1e-12)
    assert conv.ratio == pytest.approx(0.5)


def test_oscillatory_sequence_is_flagged() -> None:
    conv = un.convergence([1.00, 1.02, 0.97], [1.0, 2.0, 4.0])
    assert conv.kind == un.OSCILLATORY
    assert conv.ratio is not None and conv.ratio < 0
    assert not conv.converged
    assert conv.u_num is None and conv.order is None and conv.extrapolated is None
    assert conv.u_num_at(1.0) is None


@pytest.mark.parametrize("values", [[0.125, 0.081, 0.05], [1.0, 2.0, 2.5], [3.0, 2.0, 2.0]])
def test_diverging_sequence_is_flagged(values: list[float]) -> None:
    # differences grow (or the coarse pair does not move while the fine one does)
    conv = un.convergence(values, [0.05, 0.1, 0.2])
    assert conv.kind == un.DIVERGING
    assert not conv.converged and conv.u_num is None


def test_two_levels_use_the_theoretical_order_and_safety_factor_3() -> None:
    conv = un.convergence([0.125, 0.081], [0.1, 0.2], order=1.0)
    assert conv.kind == un.TWO_LEVELS and not conv.order_observed
    assert conv.safety == un.FS_TWO
    assert conv.extrapolated == pytest.approx(0.125 + (0.125 - 0.081) / (2 - 1))
    assert conv.u_num == pytest.approx(3 * 0.044)
    second = un.convergence([1.0 + 0.01**2, 1.0 + 0.02**2], [0.01, 0.02], order=2.0)
    assert second.extrapolated == pytest.approx(1.0, abs=1e-14)


def test_two_levels_without_order_give_no_u_num() -> None:
    conv = un.convergence([0.1, 0.2], [1.0, 2.0])
    assert conv.kind == un.NO_ORDER and conv.u_num is None and not conv.converged


def test_unchanged_values_have_zero_u_num() -> None:
    assert un.convergence([0, 0, 0], [1, 2, 4]).u_num == 0.0
    assert un.convergence([5, 5], [1, 2], order=1).u_num == 0.0


def test_bad_refinement_input_raises() -> None:
    with pytest.raises(ValueError, match="steps must differ"):
        un.convergence([1, 2], [1, 1])
    with pytest.raises(ValueError, match="finite"):
        un.convergence([1, math.nan, 2], [1, 2, 4])
    with pytest.raises(ValueError, match="two or more"):
        un.convergence([1], [1])


def test_combine_in_quadrature() -> None:
    assert un.combine([3.0, 4.0]) == pytest.approx(5.0)
    assert un.combine([3.0, None]) is None


def test_validation_verdicts_on_constructed_cases() -> None:
    # |E| = 0.045 <= u_val = hypot(0.03, 0.04) = 0.05: agrees
    v = un.validation(1.045, 1.0, 0.03, 0.04)
    assert v.error == pytest.approx(0.045) and v.u_val == pytest.approx(0.05)
    assert v.verdict == un.AGREES
    # |E| = 0.2 > 0.05: model error, whatever its sign
    assert un.validation(0.8, 1.0, 0.03, 0.04).verdict == un.MODEL_ERROR
    assert un.validation(1.2, 1.0, 0.03, 0.04).verdict == un.MODEL_ERROR
    # not converged wins over the size of E
    nc = un.validation(1.0, 1.0, None, 0.04)
    assert nc.verdict == un.NOT_CONVERGED and nc.u_val is None
    assert "not converged" in nc.describe()
    # no refinement set: u_val = u_D, said so
    nm = un.validation(1.03, 1.0, None, 0.04, u_num_measured=False)
    assert nm.u_val == pytest.approx(0.04) and nm.verdict == un.AGREES
    assert "not measured" in nm.describe()
    with pytest.raises(ValueError):
        un.validation(math.nan, 1.0, 0.1, 0.1)


# --------------------------------------------------------------------------- refinement sets

PARAMS = ["model", "l0", "dt", "check"]


def record(model: str, l0: float, dt: float, value: float, check: bool = False) -> dict:
    return {"model": model, "l0": l0, "dt": dt, "check": check, "e": value, "solver": "s",
            "status": "completed", "tier": "quick", "run_id": f"{model}-{l0}-{dt}-{check}"}


def test_sets_are_groups_that_differ_only_in_the_refined_parameter() -> None:
    records = [record("a", h, 0.1, 1 + h**2) for h in (0.1, 0.2, 0.4)]  # order 2 in l0
    records += [record("a", 0.1, dt, 1.01 + (dt - 0.1)) for dt in (0.05, 0.025)]  # dt, order 1
    records += [record("b", 0.1, 0.1, 5.0), record("b", 0.2, 0.1, 5.0, check=True)]
    records.append({**record("a", 0.8, 0.1, 9.0), "status": "diverged"})  # coarser: left out
    unc = NumericalUncertainty(records, [
        Refinement("l0", ("e",), SPACE, order=2.0, ignore=("check",)),
        Refinement("dt", ("e",), TIME, order=1.0),
    ], PARAMS)
    table = unc.table()
    assert len(table) == 3 and sorted(table["convergence"]) == ["monotone", "monotone",
                                                                  "unchanged"]
    fine = unc.of("a-0.1-0.1-False", "e")
    # l0: three levels, observed order 2, u = 1.25 |f1 - 1| = 1.25 h^2; dt: dt = 0.1 is the
    # coarsest member of {0.025, 0.05, 0.1}: u = 1.25 |f - f_ext| with f_ext = 1.01
    assert fine.parts["l0"].convergence.order == pytest.approx(2.0)
    assert fine.component("l0") == pytest.approx(1.25 * 0.01)
    assert fine.parts["dt"].convergence.kind == "monotone"
    assert fine.component("dt") == pytest.approx(1.25 * 0.1)
    assert fine.u == pytest.approx(math.hypot(1.25 * 0.01, 1.25 * 0.1))
    assert fine.text().endswith("(l0+dt)") and "±" in fine.text()
    coarse = unc.of("a-0.4-0.1-False", "e")
    assert coarse.u == pytest.approx(1.25 * 0.16) and coarse.kinds() == "l0"
    # runs that differ only in an ignored parameter are one set; equal values: u_num 0
    assert unc.of("b-0.1-0.1-False", "e").u == 0.0
    # a run in no set, and one not converged
    assert unc.of(record("c", 0.1, 0.1, 1.0), "e").text() == "1 (u_num not measured)"
    wobble = [record("w", h, 0.1, v) for h, v in ((0.1, 1.0), (0.2, 1.1), (0.4, 0.95))]
    nc = NumericalUncertainty(wobble, [Refinement("l0", ("e",), SPACE)], PARAMS)
    w = nc.of("w-0.1-0.1-False", "e")
    assert w.u is None and w.status == "not converged"
    assert w.text() == "1 (not converged in l0)" and w.u_text() == "not converged"


class Tiny(Case):
    name = "tiny"
    params = (Param("model", "a", kind=str), Param("l0", 0.1), Param("dt", 0.1))
    tiers = {"quick": [{"model": ["a", "b"], "l0": [0.1, 0.2]},
                       RefinementGrid(model=["a"], l0=[0.05, 0.1])]}


def test_model_records_leave_out_the_refinement_runs() -> None:
    case = Tiny()
    assert len(case.expand("quick")) == 5
    assert len(case.expand("quick", part="model")) == 4
    assert [p["l0"] for p in case.expand("quick", part="refinement")] == [0.05, 0.1]
    records = [{**p, "tier": "quick", "status": "completed"} for p in case.expand("quick")]
    kept = case.model_records(records)
    assert len(kept) == 4 and all(r["l0"] != 0.05 for r in kept)  # a / 0.1 is in both grids
    # a run made with --set (here dt = 0.05) matches no refinement grid and stays
    other = {"model": "a", "l0": 0.05, "dt": 0.05, "tier": "quick", "status": "completed"}
    assert case.model_records([other]) == [other]


def test_a_refinement_grid_widened_with_or_stays_one() -> None:
    grid = RefinementGrid(model=["a"], l0=[0.05, 0.1])
    wider = grid | {"dt": [0.01, 0.02]}
    assert isinstance(wider, RefinementGrid) and wider == {**grid, "dt": [0.01, 0.02]}
    assert grid == {"model": ["a"], "l0": [0.05, 0.1]}  # the original is unchanged
    # a plain grid widened by a refinement grid is a plain grid (the left side decides)
    assert type({"model": ["b"]} | grid) is dict


def test_a_diverged_finer_run_leaves_its_set_not_converged() -> None:
    ok = record("a", 0.1, 0.2, 1.0)
    finer = {**record("a", 0.1, 0.1, 1.2), "status": "diverged"}
    refs = [Refinement("dt", ("e",), TIME, order=1.0)]
    u = NumericalUncertainty([ok, finer], refs, PARAMS).of(ok, "e")
    assert u.measured and not u.converged and u.u is None
    assert u.text() == "1 (not converged in dt: the run at dt = 0.1 diverged)"
    # a run that fails only at a coarser step than every completed one is a stability limit
    coarse = {**record("a", 0.1, 0.4, 9.0), "status": "diverged"}
    finest = record("a", 0.1, 0.1, 1.0)
    u = NumericalUncertainty([ok, finest, coarse], refs, PARAMS).of(ok, "e")
    assert u.converged and u.u == 0.0
