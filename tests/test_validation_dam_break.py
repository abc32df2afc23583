"""Dam break case: reference data loader, nondimensionalisation, metrics, variants, CLI smoke."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mpsbench.validations import experiments
from mpsbench.validations.dam_break import metrics as dm
from mpsbench.validations.dam_break.case import CASE, build

GOOD = """# source: a paper
# table: table 1
# units: t=s, p=mbar
# nondimensionalisation: none
t,p
0.0,1.0
0.5,2.0
"""


# ---------------------------------------------------------------- loader


@pytest.mark.parametrize("name", sorted(experiments.SCHEMAS))
def test_shipped_data_files_load_with_sources(name: str) -> None:
    d = experiments.load(name)
    assert len(d) > 0
    for key in experiments.HEADER_KEYS:
        assert d.meta[key]
    assert "doi" in d.source
    assert d.units == experiments.SCHEMAS[name]


def test_martin_moyce_values() -> None:
    front = experiments.load("martin_moyce_1952_surge_front")
    assert len(front) == 15
    assert front["T"][0] == 0.41 and front["Z"][-1] == 4.11
    height = experiments.load("martin_moyce_1952_residual_height")
    assert len(height) == 17
    assert height["tau"][-1] == 7.40 and height["H*"][0] == 0.94
    assert np.all(np.diff(front["T"]) > 0) and np.all(np.diff(height["H*"]) < 0)


def test_load_a_good_file_with_an_explicit_schema(tmp_path: Path) -> None:
    f = tmp_path / "x.csv"
    f.write_text(GOOD)
    d = experiments.load(f, {"t": "s", "p": "mbar"})
    np.testing.assert_array_equal(d["p"], [1.0, 2.0])
    with pytest.raises(KeyError, match="no column 'q'"):
        d["q"]


def test_missing_column_is_rejected_by_name(tmp_path: Path) -> None:
    f = tmp_path / "x.csv"
    f.write_text(GOOD)
    with pytest.raises(experiments.DataFileError, match=r"missing column 'z' \(unit 'mm'\)"):
        experiments.load(f, {"t": "s", "p": "mbar", "z": "mm"})


def test_wrong_unit_is_rejected_naming_column_and_units(tmp_path: Path) -> None:
    f = tmp_path / "x.csv"
    f.write_text(GOOD.replace("p=mbar", "p=kPa"))
    with pytest.raises(experiments.DataFileError,
                       match=r"column 'p' has unit 'kPa', expected 'mbar'"):
        experiments.load(f, {"t": "s", "p": "mbar"})


def test_shipped_schema_applies_to_a_copy_with_the_same_name(tmp_path: Path) -> None:
    src = experiments.DATA_DIR / "lobovsky_2014_peak_pressure.csv"
    bad = tmp_path / src.name
    bad.write_text(src.read_text().replace("median=mbar", "median=Pa"))
    with pytest.raises(experiments.DataFileError, match="'median' has unit 'Pa', expected 'mbar'"):
        experiments.load(bad)
    bad.write_text(src.read_text().replace("sensor,z,median,", "sensor,z,med,")
                   .replace("median=mbar", "med=mbar"))
    with pytest.raises(experiments.DataFileError, match="missing column 'median'"):
        experiments.load(bad)


@pytest.mark.parametrize(
    "text, message",
    [
        (GOOD.replace("# source: a paper\n", ""), "lacks source"),
        (GOOD.replace("t=s, ", ""), "column 't' has no unit"),
        (GOOD.replace("0.5,2.0", "0.5,abc"), "column 'p': 'abc' is not a finite number"),
        (GOOD.replace("0.5,2.0", "0.5"), "data row 3 has 1 values"),
        (GOOD.replace("t=s", "t"), "not of the form column=unit"),
    ],
)
def test_malformed_files_are_rejected(tmp_path: Path, text: str, message: str) -> None:
    f = tmp_path / "x.csv"
    f.write_text(text)
    with pytest.raises(experiments.DataFileError, match=message):
        experiments.load(f, {"t": "s", "p": "mbar"})


def test_unknown_data_set_lists_known() -> None:
    with pytest.raises(experiments.DataFileError, match="known: martin_moyce"):
        experiments.load("no_such_set")


# ---------------------------------------------------------------- conversions


def test_lobovsky_pressure_scale_and_conversion() -> None:
    assert experiments.rho_g_h() == pytest.approx(2934.171)  # Pa
    assert float(experiments.mbar_to_pstar(29.3417)) == pytest.approx(1.0, abs=1e-5)
    bands = experiments.lobovsky_bands()
    np.testing.assert_allclose(bands["z"], [0.003, 0.015, 0.03, 0.08])
    # sensor 1 median 91.44 mbar = 9144 Pa; / 2934.171 Pa
    assert bands["median"][0] == pytest.approx(9144.0 / 2934.171)
    assert np.all(bands["lo"] < bands["median"]) and np.all(bands["median"] < bands["hi"])


def test_nondimensionalisation_helpers() -> None:
    a, g = 0.146, 9.81
    assert float(dm.surge_T(1.0, a, g)) == pytest.approx(math.sqrt(2 * g / a))
    assert float(dm.height_tau(1.0, a, g)) == pytest.approx(math.sqrt(g / a))
    # n^2 = 2: T = sqrt(2) tau
    assert float(dm.surge_T(0.3, a)) == pytest.approx(math.sqrt(2) * float(dm.height_tau(0.3, a)))
    assert float(dm.surge_Z(0.292, a)) == pytest.approx(2.0)
    assert float(dm.height_star(0.146, 0.292)) == pytest.approx(0.5)
    assert float(dm.pressure_star(997 * 9.81 * 0.3, 997.0, 0.3)) == pytest.approx(1.0)
    assert float(dm.time_star(math.sqrt(0.3 / 9.81), 0.3)) == pytest.approx(1.0)


# ---------------------------------------------------------------- metrics


def test_curve_errors_on_synthetic_data() -> None:
    xe = np.array([0.5, 1.0, 2.0, 3.0, 3.5])
    ye = 2 * xe
    xs = np.linspace(0, 4, 81)
    e = dm.curve_errors(xs, 2 * xs + 0.1, xe, ye, x_max=3.0)
    assert e["n"] == 4
    assert e["rms"] == pytest.approx(0.1) and e["max"] == pytest.approx(0.1)
    assert e["mean"] == pytest.approx(0.1)
    ys = 2 * xs
    ys[xs == 2.0] -= 0.4
    e = dm.curve_errors(xs, ys, xe, ye, x_max=3.0)
    assert e["max"] == pytest.approx(0.4) and e["mean"] == pytest.approx(-0.1)
    assert e["rms"] == pytest.approx(math.sqrt(0.16 / 4))
    # points outside the simulated range are not compared
    assert dm.curve_errors(xs[:21], ys[:21], xe, ye)["n"] == 2
    assert math.isnan(dm.curve_errors([0.0], [1.0], xe, ye)["rms"])


def test_first_crossing_gives_the_arrival_time() -> None:
    T = np.linspace(0, 4, 41)
    Z = 1 + T
    assert dm.first_crossing(T, Z, 4.0) == pytest.approx(3.0)
    assert math.isnan(dm.first_crossing(T, Z, 10.0))
    front = experiments.load("martin_moyce_1952_surge_front")
    assert dm.first_crossing(front["T"], front["Z"], 4.0) == pytest.approx(3.22)


def test_contiguous_extent_ignores_detached_droplets() -> None:
    x = np.r_[np.arange(0.005, 0.3, 0.01), 0.5]
    assert dm.contiguous_extent(x, 0.0, 0.03) == pytest.approx(0.295)
    assert dm.contiguous_extent(np.array([0.2]), 0.0, 0.03) == 0.0
    assert math.isnan(dm.contiguous_extent(np.array([]), 0.0, 0.03))


def test_peak_in_window_and_band() -> None:
    t = np.linspace(0, 5, 501)
    p = np.where(t > 2.5, 3.0 * np.exp(-np.minimum((t - 2.6) ** 2 / 0.001, 50.0)), 0.0)
    p = np.where(t > 2.5, p, 0.0) + 0.2 * (t > 4)
    t_a = dm.impact_start(t, p[:, None], 0.05)
    assert 2.5 <= t_a < 2.6
    peak, t_peak = dm.window_peak(t, p, t_a, t_a + 0.5)
    assert peak == pytest.approx(3.0, rel=1e-3) and t_peak == pytest.approx(2.6)
    assert dm.in_band(peak, 2.56, 4.46) is True
    assert dm.in_band(peak, 1.8, 2.2) is False
    assert dm.in_band(math.nan, 1.0, 2.0) is None
    assert math.isnan(dm.impact_start(t, np.zeros((len(t), 2)), 0.05))
    assert dm.window_peak(t, p, 10.0, 11.0) == (pytest.approx(math.nan, nan_ok=True),) * 2


def test_noise_of_smooth_and_noisy_signals() -> None:
    t = np.linspace(0, 2, 2001)
    smooth = 1.0 + 0.5 * t  # linear: the centred average reproduces it exactly
    assert dm.signal_noise(t, smooth, 0.05) == pytest.approx(0.0, abs=1e-12)
    slow = np.sin(2 * np.pi * 0.5 * t)
    assert dm.signal_noise(t, slow, 0.05) < 1e-3
    rng = np.random.default_rng(1)
    noisy = smooth + 0.3 * rng.standard_normal(len(t))
    n = dm.signal_noise(t, noisy, 0.05)
    assert 0.2 < n < 0.35
    # only the part after t0 counts
    part = smooth + np.where(t > 1, 0.3 * rng.standard_normal(len(t)), 0.0)
    assert dm.signal_noise(t, part, 0.05, t0=1.1) > 0.2
    assert dm.signal_noise(t, part, 0.05, t0=-1) < dm.signal_noise(t, part, 0.05, t0=1.1)


# ---------------------------------------------------------------- case set-up


def test_variants_resolve_and_custom_is_recorded() -> None:
    runs = CASE.expand("smoke")
    got = {(p["geometry"], p["variant"]): (p["laplacian"], p["stabilization"]) for p in runs}
    assert got[("koshizuka-oka", "wc-mps")] == ("koshizuka-oka", False)
    assert got[("koshizuka-oka", "iwc-mps")] == ("xu-jin", True)
    custom = CASE.expand("smoke", {"laplacian": ["xu-jin-analytic"]})
    assert {p["variant"] for p in custom} == {"custom"}
    assert {p["laplacian"] for p in custom} == {"xu-jin-analytic"}
    assert {p["stabilization"] for p in custom} == {True, False}
    same = CASE.expand("smoke", {"laplacian": ["koshizuka-oka"]})
    assert {p["variant"] for p in same} == {"wc-mps", "custom"}


def test_quick_tier_has_the_gate_runs() -> None:
    quick = CASE.expand("quick")
    ko = [p for p in quick if p["geometry"] == "koshizuka-oka"]
    assert any(p["variant"] == "iwc-mps" and p["l0"] <= 0.005 for p in ko)
    assert any(p["variant"] == "wc-mps" and p["l0"] <= 0.005 for p in ko)
    lob = [p for p in quick if p["geometry"] == "lobovsky"]
    assert {p["variant"] for p in lob} == {"wc-mps", "iwc-mps"}


@pytest.mark.parametrize("tier", ["smoke", "quick", "paper"])
def test_every_tier_runs_lobovsky_with_the_collision_model(tier: str) -> None:
    # the gate needs every model run to complete: without the collision model a spray pair can
    # end the Lobovsky runs on one CPU's rounding and not another's (case docstring), and C6
    # and C7 read only runs with the geometry's own setting (analysis.is_default)
    lob = [p for p in CASE.expand(tier) if p["geometry"] == "lobovsky"]
    assert {p["variant"] for p in lob} == {"wc-mps", "iwc-mps"}
    assert all(p["collision"] for p in lob)


@pytest.mark.parametrize("geometry, ratio", [("koshizuka-oka", 2.0), ("lobovsky", 0.5)])
def test_build_keeps_the_column_aspect_ratio(geometry: str, ratio: float) -> None:
    for l0 in (0.01, 0.005):
        params = CASE.defaults() | {"geometry": geometry, "l0": l0}
        problem, sc = build(params)
        assert sc["H"] / sc["a"] == pytest.approx(ratio, rel=0.04)
        n_fluid = int(problem.particles.fluid.sum())
        assert n_fluid == round(sc["a"] / l0) * round(sc["H"] / l0)


# ---------------------------------------------------------------- end to end


@pytest.mark.slow
def test_smoke_tier_cli_end_to_end(tmp_path: Path) -> None:
    from mpsbench.cli import main

    out = tmp_path / "db"
    rc = main(["validate", "dam-break", "--tier", "smoke", "--out", str(out), "--jobs", "2",
               "--vtu"])
    assert rc in (0, 1)
    records = json.loads((out / "results.json").read_text())
    assert len(records) == 4
    assert all(r["status"] == "completed" for r in records)
    for r in records:
        if r["geometry"] == "koshizuka-oka":
            assert math.isfinite(r["front_rms_error"]) and math.isfinite(r["front_arrival_T"])
        else:
            assert all(r[f"peak_p_sensor{k}"] is not None for k in range(1, 5))
    for name in ("snapshots_koshizuka-oka", "surge_front_and_height", "impact_pressure_lobovsky"):
        assert (out / "figures" / f"{name}.png").exists()
    assert (out / "tables" / "impact_pressure.md").exists()
    assert "Findings" in (out / "report.md").read_text()
    assert len(list((out / "paraview").glob("*.pvd"))) == len(records)


def test_records_with_the_retired_vtu_parameter_still_compare() -> None:
    """'vtu' was a case parameter before ParaView output became 'validate --vtu': a baseline
    made before carries it, today's records do not, and that is no change of any run."""
    from mpsbench.results.compare import compare, load_results
    from mpsbench.results.identity import record_hash

    # the dam-break records of the smoke baseline as it was until 0aba31b (the refresh for
    # whole powers as products replaced them with records made without the parameter)
    old = Path(__file__).parent / "data" / "retired_vtu_dam_break_records.json"
    base = [r for r in load_results(old) if r["case"] == "dam-break" and "vtu" in r]
    assert len(base) == 5
    now = [{k: v for k, v in r.items() if k != "vtu"} for r in base]
    assert [record_hash(r, CASE) for r in base] == [record_hash(r, CASE) for r in now]
    cmp = compare(base, now)
    assert cmp.matched == len(base) and not cmp.changes
