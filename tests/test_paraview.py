"""ParaView output (issue 18, item 1): frames kept by an output option that changes no run,
the .pvd series with time values, ``mpsbench export`` and ``mpsbench show`` end to end."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import meshio
import numpy as np
import pytest

from mpsbench import cli
from mpsbench.results.paraview import read_pvd
from mpsbench.results.records import load_arrays
from mpsbench.run.frames import keeping_frames
from mpsbench.run.runner import run
from mpsbench.testing.problems import diffusion_problem
from tests.fake_cases import ToyCounter, ToyDiffusion, only_cases


@pytest.fixture
def toys() -> Iterator[tuple[ToyDiffusion, ToyCounter]]:
    diffusion, counter = ToyDiffusion(), ToyCounter()
    with only_cases(diffusion, counter):
        yield diffusion, counter


def test_frames_take_no_step_of_their_own() -> None:
    """A run keeping frames takes the same steps and ends in the same state, bit for bit."""
    end = 2.5e-3
    plain = run("reference", diffusion_problem("xu-jin", n_side=16), end_time=end)
    with keeping_frames(6):
        kept = run("reference", diffusion_problem("xu-jin", n_side=16), end_time=end)
    assert plain.frames == [] and plain.n_steps == kept.n_steps and plain.time == kept.time
    assert plain.final is not None and kept.final is not None
    assert np.array_equal(plain.final.fields["phi"], kept.final.fields["phi"])
    times = [f.time for f in kept.frames]
    assert len(times) == 6 and times[0] == 0.0 and times[-1] == pytest.approx(end, rel=1e-12)
    # each frame at the first step reaching its mark: within one step after it
    dt = end / kept.n_steps
    marks = np.linspace(0.0, end, 6)
    assert all(m - 1e-12 <= t <= m + 1.5 * dt for t, m in zip(times, marks, strict=True))
    assert np.array_equal(kept.frames[-1].particles.fields["phi"], kept.final.fields["phi"])


def _validate(out: Path, *extra: str) -> int:
    return cli.main(["validate", "toy-diffusion", "--tier", "smoke", "--out", str(out), *extra])


def test_vtu_is_an_output_option_not_a_parameter(toys: object, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    plain, vtu = tmp_path / "plain", tmp_path / "vtu"
    assert _validate(plain) == 0
    assert _validate(vtu, "--vtu", "--frames", "4") == 0
    a = {r["run_id"]: r for r in json.loads((plain / "results.json").read_text())}
    b = {r["run_id"]: r for r in json.loads((vtu / "results.json").read_text())}
    assert a.keys() == b.keys()  # the same run ids
    for rid in a:
        assert a[rid]["run_hash"] == b[rid]["run_hash"]
        assert a[rid]["l2_error"] == b[rid]["l2_error"] and a[rid]["n_steps"] == b[rid]["n_steps"]
        assert not [k for k in b[rid] if "frame" in k or "vtu" in k]  # no record column
    capsys.readouterr()
    assert cli.main(["compare", str(plain), str(vtu)]) == 0
    assert "0 regression(s), 0 better, 0 informational" in capsys.readouterr().out

    # one .pvd per run; its time values are the stored frame times, each file opens
    pvds = sorted((vtu / "paraview").glob("*.pvd"))
    assert [p.stem for p in pvds] == sorted(b)
    for pvd in pvds:
        stored = load_arrays(vtu, pvd.stem)
        series = read_pvd(pvd)
        assert [t for t, _ in series] == stored["frame_time"].tolist()
        assert len(series) == 4 and series[-1][0] > series[0][0] == 0.0
        for k, (_, path) in enumerate(series):
            mesh = meshio.read(path)
            assert mesh.points.shape == (len(stored[f"frame{k}_pos"]), 3)
            assert np.array_equal(mesh.points[:, :2], stored[f"frame{k}_pos"])
            assert np.array_equal(mesh.point_data["phi"], stored[f"frame{k}_field_phi"])
            assert mesh.point_data["velocity"].shape[1] == 3
            assert b"format=\"binary\"" in path.read_bytes()[:2000]
    assert not (plain / "paraview").exists()


def test_vtu_reruns_a_run_done_without_frames(toys: object, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    assert _validate(out) == 0
    assert _validate(out) == 0
    assert capsys.readouterr().err.count(" skip ") == 2
    assert _validate(out, "--vtu", "--frames", "3") == 0
    err = capsys.readouterr().err
    assert " skip " not in err and "paraview: 2 series" in err
    assert _validate(out, "--vtu", "--frames", "3") == 0  # now they have frames: skipped
    assert capsys.readouterr().err.count(" skip ") == 2


def test_export_and_show_end_to_end(toys: object, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str],
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "r"
    assert _validate(out, "--vtu", "--frames", "4") == 0
    run_file = sorted((out / "runs").glob("*.json"))[0]
    # export of a folder, into another folder, from the stored frames alone
    dest = tmp_path / "pv"
    capsys.readouterr()
    assert cli.main(["export", str(out), "--vtu", "--out", str(dest)]) == 0
    printed = capsys.readouterr().out.split()
    assert sorted(Path(p).name for p in printed) == sorted(
        p.name for p in (out / "paraview").glob("*.pvd"))
    series = read_pvd(dest / f"{run_file.stem}.pvd")
    assert len(series) == 4 and all(p.is_file() for _, p in series)
    # export of one run (its arrays file), in place
    (out / "paraview").rename(tmp_path / "old")
    assert cli.main(["export", str(run_file.with_suffix(".npz")), "--vtu"]) == 0
    assert (out / "paraview" / f"{run_file.stem}.pvd").is_file()

    png = tmp_path / "show.png"
    t_mid = series[2][0]
    assert cli.main(["show", str(run_file), "--field", "phi", "--time", str(t_mid * 1.01),
                     "--out", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000
    monkeypatch.chdir(tmp_path)
    capsys.readouterr()
    assert cli.main(["show", str(run_file)]) == 0  # the last frame, pressure, here
    t_end = series[-1][0]
    assert Path(capsys.readouterr().out.strip()) == Path(
        f"{run_file.stem}_pressure_t{t_end:.4g}.png")
    assert (tmp_path / f"{run_file.stem}_pressure_t{t_end:.4g}.png").is_file()


def test_export_show_and_vtu_refuse_bad_input(toys: object, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    assert _validate(out) == 0
    run_file = sorted((out / "runs").glob("*.json"))[0]
    capsys.readouterr()
    assert cli.main(["export", str(out), "--vtu"]) == 2
    assert "no run kept frames" in capsys.readouterr().err
    assert cli.main(["show", str(run_file)]) == 2
    assert "kept no frames" in capsys.readouterr().err
    assert cli.main(["show", str(tmp_path / "nothing.json")]) == 2
    assert "not a run" in capsys.readouterr().err
    assert _validate(out, "--vtu", "--frames", "0") == 2
    assert "--frames = 0 is not allowed" in capsys.readouterr().err
    assert _validate(out, "--vtu", "--frames", "2") == 0
    assert cli.main(["show", str(run_file), "--field", "nope"]) == 2
    assert "--field = 'nope' is not allowed: one of pressure" in capsys.readouterr().err
