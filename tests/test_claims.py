"""Gates and claims (docs/method.md section 8): decision helpers, claim rules of the built-in
cases on constructed records (met, refuted, without data), the claims table in summary.md and
index.html, plain-text terminal output and --strict-claims."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mpsbench.validations.couette import case as cou
from mpsbench.validations.dam_break import analysis as dba
from mpsbench.validations.diffusion import case as dif
from mpsbench.validations.water_jet import case as wj

from mpsbench import cli
from mpsbench.cases import CaseCheck, Claim
from mpsbench.cases.checks import above, below, decide, less
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases

# --------------------------------------------------------------------------- decision helpers


def test_comparisons_respect_the_uncertainty() -> None:
    assert below(0.08, 0.1) is True and below(0.12, 0.1) is False
    assert below(0.08, 0.1, 0.01) is True
    assert below(0.095, 0.1, 0.01) is None  # the margin is inside u
    assert below(0.105, 0.1, 0.01) is None
    assert below(0.12, 0.1, 0.01) is False
    assert below(0.08, 0.1, 0.01, converged=False) is None
    assert above(0.3, 0.1, 0.1) is True and above(0.15, 0.1, 0.1) is None
    assert above(0.05, 0.1) is False
    assert less(1.0, 2.0, 0.3, 0.4) is True  # combined u = 0.5
    assert less(1.0, 1.4, 0.3, 0.4) is None
    assert less(2.0, 1.0) is False
    assert below(math.nan, 1.0) is None


def test_decide_a_rule() -> None:
    assert decide([True, True]) is True
    assert decide([True, None]) is None
    assert decide([True, None, False]) is False
    assert decide([]) is None


def test_claim_check_roundtrips_through_json() -> None:
    claim = Claim("C0", "A statement.", "somewhere")
    check = claim.verdict(False, "x < 1", "x = 2", ["run-a"])
    assert check.is_claim and check.verdict == "refuted" and check.claim == "C0"
    back = CaseCheck.from_json(json.loads(json.dumps(check.to_json())))
    assert back == check
    assert claim.no_data("x < 1", "runs of x").verdict == "inconclusive"
    gate = CaseCheck.from_json({"name": "old", "passed": True, "detail": "d"})  # old checks.json
    assert not gate.is_claim and gate.verdict == "PASS"


# --------------------------------------------------------------------------- claim rules


def couette(laplacian: str, weight: str, re: float, error: float, n: int = 40) -> dict[str, Any]:
    return {**cou.CASE.defaults(), "laplacian": laplacian, "weight": weight, "re_ratio": re,
            "l0": cou.L / n, "l2_error": error, "status": "completed", "tier": "quick",
            "solver": "reference", "run_id": f"{laplacian}-{weight}-{re}-{n}"}


def couette_grid(lm3_wf1: float = 0.004) -> list[dict[str, Any]]:
    out = []
    for re in (2.1, 3.1):
        out += [couette("xu-jin", "wf2", re, 0.003), couette("xu-jin", "wf1", re, lm3_wf1),
                couette("koshizuka-oka", "wf2", re, 0.006), couette("koshizuka-oka", "wf1", re,
                                                                    0.008),
                couette("khayyer-gotoh", "wf2", re, 0.2), couette("khayyer-gotoh", "wf1", re,
                                                                  0.25)]
    return out


def verdicts(checks: list[CaseCheck]) -> dict[str, str]:
    return {c.claim: c.verdict for c in checks if c.is_claim}


def test_couette_claims_met_refuted_and_without_data() -> None:
    # LM3 best everywhere, WF ratio 4/3 > 1.25: C2 met, C3 refuted, C8 (LM2 > 5 %) met
    got = verdicts(cou.CASE.claims(couette_grid()))
    assert got == {"C2": "supported", "C3": "refuted", "C8": "supported"}
    # WF ratio within the band, and LM3 beaten by LM1 in one cell: C2 refuted, C3 met
    records = couette_grid(lm3_wf1=0.0033)
    records[1]["l2_error"] = 0.009  # xu-jin / wf1 / 2.1 above koshizuka-oka's 0.008
    records[7]["l2_error"] = 0.0033
    got = verdicts(cou.CASE.claims(records))
    assert got["C2"] == "refuted"
    c2 = next(c for c in cou.CASE.claims(records) if c.claim == "C2")
    assert "wf1/2.1" in c2.detail and "3 of 4 cells" in c2.detail
    # only L/20 runs: nothing to decide at L/40
    coarse = [couette("xu-jin", "wf2", 3.1, 0.01, n=20)]
    assert set(verdicts(cou.CASE.claims(coarse)).values()) == {"inconclusive"}
    assert all("no data" in c.detail for c in cou.CASE.claims(coarse))


def diffusion(laplacian: str, l0: float, decay: float, error: float = 0.01,
              dt: float = dif.DT) -> dict[str, Any]:
    return {**dif.CASE.defaults(), "laplacian": laplacian, "weight": "wf2", "re_ratio": 3.1,
            "l0": l0, "dt": dt, "decay_ratio": decay, "l2_error": error, "status": "completed",
            "tier": "smoke", "solver": "reference", "run_id": f"{laplacian}-{l0}-{dt}"}


def test_diffusion_c9_reads_the_extrapolated_decay_rate() -> None:
    # LM1 converging to the exact rate at second order: "remains inexact" is refuted
    exact = [diffusion("koshizuka-oka", h, 1 + 4 * h**2) for h in (1 / 20, 1 / 40)]
    c9 = next(c for c in dif.CASE.claims(exact) if c.claim == "C9")
    assert c9.verdict == "refuted" and "1.00000" in c9.detail
    # converging to a rate 3 % off: supported
    off = [diffusion("koshizuka-oka", h, 1.03 + 4 * h**2) for h in (1 / 20, 1 / 40)]
    assert verdicts(dif.CASE.claims(off))["C9"] == "supported"
    # one spacing: no refinement set, no verdict
    one = [diffusion("koshizuka-oka", 1 / 40, 1.0)]
    assert verdicts(dif.CASE.claims(one))["C9"] == "inconclusive"


def test_diffusion_c8_uses_u_num() -> None:
    # LM2 15 % off at the finest l0 with a small u_num: supported
    lm2 = [diffusion("khayyer-gotoh", h, 1.15 + 0.01 * h**2 / (1 / 40) ** 2)
           for h in (1 / 20, 1 / 40)]  # 1.19, 1.16: u_num = 3 x 0.01
    assert verdicts(dif.CASE.claims(lm2))["C8"] == "supported"
    # 12 % off but still moving by 9 % between the spacings: u_num straddles the 10 % line
    moving = [diffusion("khayyer-gotoh", 1 / 20, 1.21), diffusion("khayyer-gotoh", 1 / 40, 1.12)]
    assert verdicts(dif.CASE.claims(moving))["C8"] == "inconclusive"
    # 2 % off: refuted
    near = [diffusion("khayyer-gotoh", h, 1.02) for h in (1 / 20, 1 / 40)]
    assert verdicts(dif.CASE.claims(near))["C8"] == "refuted"


def jet(stabilization: bool, **metrics: Any) -> dict[str, Any]:
    rec = {**wj.CASE.defaults(), "stabilization": stabilization, "status": "completed",
           "tier": "quick", "solver": "reference", "penetrations": 0}
    rec.update(metrics)
    rec["run_id"] = f"jet-{stabilization}-{rec['l0']}-{rec['cfl']}"
    return rec


def test_water_jet_c4b_is_decided_only_beyond_u_num() -> None:
    def records(cp_fine: float, cp_coarse: float) -> list[dict[str, Any]]:
        return [jet(True, cp_rms_error=cp_fine), jet(True, l0=0.01, cp_rms_error=cp_coarse),
                jet(False, cp_rms_error=0.08)]

    assert verdicts(wj.CASE.claims(records(0.05, 0.055)))["C4b"] == "supported"
    assert verdicts(wj.CASE.claims(records(0.2, 0.21)))["C4b"] == "refuted"
    # 0.113 with u_num 3 x 0.034 = 0.1: inconclusive
    assert verdicts(wj.CASE.claims(records(0.113, 0.147)))["C4b"] == "inconclusive"
    assert verdicts(wj.CASE.claims([jet(False, cp_rms_error=0.08)]))["C4b"] == "inconclusive"


def test_water_jet_c4_and_c5_on_pairs() -> None:
    off = jet(False, noise_spatial=1.0, noise_temporal=0.5, density_drift_mean=0.02)
    on = jet(True, noise_spatial=0.3, noise_temporal=0.2, density_drift_mean=0.005)
    assert verdicts(wj.CASE.claims([off, on])) == {"C4": "supported", "C4b": "inconclusive",
                                                   "C5": "supported"}
    on.update(noise_temporal=0.4, penetrations=2)
    got = verdicts(wj.CASE.claims([off, on]))
    assert got["C4"] == "refuted" and got["C5"] == "refuted"


def lobovsky(variant: str, l0: float, noise: float, collision: bool = True) -> dict[str, Any]:
    return {"geometry": "lobovsky", "variant": variant, "l0": l0, "cfl": 0.2, "weight": "wf2",
            "re_ratio": 2.1, "gradient": "pgm1", "re_ratio_laplacian": 0.0, "gate_delay": 0.0,
            "stabilization_walls": True, "collision": collision, "status": "completed",
            "run_id": f"{variant}-{l0}", **{f"noise_sensor{k}": noise for k in range(1, 5)}}


def test_dam_break_c7() -> None:
    ok = [lobovsky("wc-mps", 0.01, 1.0), lobovsky("iwc-mps", 0.01, 0.3)]
    assert dba._c7(ok).verdict == "supported"
    weak = [lobovsky("wc-mps", 0.01, 1.0), lobovsky("iwc-mps", 0.01, 0.8)]
    assert dba._c7(weak).verdict == "refuted"
    assert dba._c7([lobovsky("wc-mps", 0.01, 1.0)]).verdict == "inconclusive"
    # the Lobovsky geometry's own models include the collision model (the tiers run it so)
    off = [lobovsky("wc-mps", 0.01, 1.0, False), lobovsky("iwc-mps", 0.01, 0.3, False)]
    assert dba._c7(off).verdict == "inconclusive"


# --------------------------------------------------------------------------- reports


@pytest.fixture
def toys() -> Iterator[tuple[ToyDiffusion, ToyCounter]]:
    diffusion, counter = ToyDiffusion(), ToyCounter()
    with only_cases(diffusion, counter):
        yield diffusion, counter


def validate(out: Path, *extra: str) -> int:
    return cli.main(["validate", "all", "--tier", "smoke", "--out", str(out), "--jobs", "1",
                     *extra])


def test_summary_opens_with_the_claims_table(toys: object, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    assert validate(out) == 0
    summary = (out / "summary.md").read_text()
    assert summary.startswith("# mpsbench validation: PASS (2/2 cases pass); claims: 1 supported")
    assert summary.index("## Claims") < summary.index("## Gates") < summary.index("## Toy")
    claims = summary[summary.index("## Claims"):summary.index("## Gates")]
    assert "| T1 xu-jin is at least as accurate" in claims and "supported" in claims
    # rule (HTML characters as entities, as everywhere in summary.md) and evidence
    assert "xu-jin's l2_error &lt;= 1e+09 x" in claims and "(2 runs)" in claims
    page = (out / "index.html").read_text()
    assert page.index('id="claims"') < page.index('id="gates"')
    assert '<span class="pass">supported</span>' in page
    printed = capsys.readouterr().out
    assert "**" not in printed  # plain text on the terminal
    assert "claim T1 supported" in printed and "claims: 1 supported" in printed


def test_refuted_claim_fails_only_with_strict_claims(
    toys: tuple[ToyDiffusion, ToyCounter], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    toys[0].claim_margin = 0.0
    out = tmp_path / "r"
    assert validate(out) == 0  # a refuted claim is a finding
    assert "claims: 1 refuted" in (out / "summary.md").read_text()
    assert '<span class="fail">refuted</span>' in (out / "index.html").read_text()
    checks = json.loads((out / "toy-diffusion" / "checks.json").read_text())
    assert [c["kind"] for c in checks].count("claim") == 1
    assert cli.main(["report", str(out)]) == 0
    assert cli.main(["report", str(out), "--strict-claims"]) == 1
    assert "refuted T1" in capsys.readouterr().out
    assert validate(tmp_path / "s", "--strict-claims") == 1
    assert "FAIL" in (tmp_path / "s" / "summary.md").read_text().splitlines()[0]
    toys[0].claim_margin = 1e9
    assert cli.main(["report", str(out), "--strict-claims"]) == 0  # re-rendered: supported


def test_claims_survive_a_report_from_files(toys: tuple[ToyDiffusion, ToyCounter],
                                            tmp_path: Path) -> None:
    toys[0].claim_margin = 0.0
    out = tmp_path / "r"
    assert validate(out) == 0
    assert cli.main(["report", str(out), "--from-files", "--strict-claims"]) == 1
    assert "claims: 1 refuted" in (out / "summary.md").read_text()


def test_a_plugin_case_declares_refinement_sets(toys: object, tmp_path: Path) -> None:
    out = tmp_path / "q"
    assert cli.main(["validate", "toy-diffusion", "--tier", "paper", "--out", str(out)]) == 0
    table = (out / "tables" / "numerical_uncertainty.md").read_text()
    # n_side 8, 10, 12 per model: three levels, unequal ratios, steps 1/n_side
    assert table.count("n_side (l0)") == 4  # two models x two metrics
    assert "0.08333, 0.1, 0.125" in table
    assert "## Table: numerical_uncertainty" in (out / "report.md").read_text()


def test_dam_break_gates_hold_the_model_grid_and_name_refinement_runs() -> None:
    from mpsbench.validations.dam_break import case as dbc

    def ko(variant: str, cfl: float, status: str = "completed") -> dict[str, Any]:
        params = [p for p in dbc.CASE.expand("quick") if p["geometry"] == "koshizuka-oka"
                  and p["variant"] == variant and p["l0"] == 0.005 and p["cfl"] == cfl
                  and p["stabilization_walls"]][0]
        return {**params, "tier": "quick", "status": status, "front_rms_error": 0.1,
                "run_id": f"{variant}-{cfl}", "reason": "fluid speed too high"}

    model = [ko("iwc-mps", 0.2), ko("wc-mps", 0.2)]
    records = [*model, ko("iwc-mps", 0.1), ko("wc-mps", 0.1, "diverged")]
    assert [r["run_id"] for r in dbc.CASE.model_records(records)] == ["iwc-mps-0.2", "wc-mps-0.2"]
    complete, front = dbc.CASE.checks(records)
    assert complete.passed is True and front.passed is True
    assert "refinement runs not completed" in complete.detail and "wc-mps" in complete.detail
    model[0]["status"] = "diverged"  # a model-grid run that diverges still fails
    assert dbc.CASE.checks(records)[0].passed is False
