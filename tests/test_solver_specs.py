"""Solver options travel with the name: ``NAME:key=value,...`` specs, validated like case
parameters, kept apart from the name in records, named in run ids; the runner checks the
solvers' health summary instead of reading their state every step."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mpsbench.solvers.reference import ReferenceSolver

from mpsbench import cli
from mpsbench.errors import ConfigError
from mpsbench.params import Option
from mpsbench.registry import UnknownNameError
from mpsbench.results.records import execute_task, run_id, solver_folder, solver_label
from mpsbench.results.sweep import plan
from mpsbench.run.protocol import SOLVERS, Health
from mpsbench.run.runner import run
from mpsbench.run.specs import make_solver, solver_options, solver_spec
from mpsbench.testing import problems
from tests.fake_cases import ToyDiffusion, only_cases


class Tunable(ReferenceSolver):
    """The reference backend with two options (as a device backend would declare its id)."""

    name = "tunable"
    options = (
        Option("device", 0, "device id", kind=int, minimum=0),
        Option("fast", False, "a switch", kind=bool),
    )

    def __init__(self, device: int = 0, fast: bool = False) -> None:
        super().__init__()
        self.device, self.fast = device, fast


@pytest.fixture
def tunable():
    SOLVERS.register("tunable", Tunable, origin="user")
    yield Tunable
    SOLVERS.unregister("tunable")


def test_specs_are_parsed_validated_and_canonical(tunable: type) -> None:
    assert solver_spec("tunable").text == "tunable"
    spec = solver_spec(" tunable: fast=yes , device=2 ")
    assert spec.name == "tunable" and spec.kwargs == {"device": 2, "fast": True}
    assert spec.text == "tunable:device=2,fast=true"  # declaration order, canonical values
    assert solver_spec("tunable:device=0,fast=off").text == "tunable"  # defaults drop out
    s = make_solver("tunable:device=3")
    assert isinstance(s, Tunable) and s.device == 3 and s.fast is False
    with pytest.raises(ConfigError, match=r"solver 'tunable' has no option 'gpu'; its options: "
                       r"device, fast"):
        solver_spec("tunable:gpu=1")
    with pytest.raises(ConfigError, match=r"solver 'tunable': option device = '-1' is not "
                       r"allowed: an int >= 0"):
        solver_spec("tunable:device=-1")
    with pytest.raises(ConfigError, match="is not KEY=VALUE"):
        solver_spec("tunable:device")
    with pytest.raises(ConfigError, match="given twice"):
        solver_spec("tunable:device=1,device=2")
    with pytest.raises(ConfigError, match="takes no options"):
        solver_spec("reference:device=1")
    with pytest.raises(UnknownNameError, match="unknown solver 'nope'"):
        solver_spec("nope:device=1")
    rows = solver_options(Tunable)
    assert [r["name"] for r in rows] == ["device", "fast"]
    assert rows[0]["allowed"] == "an int >= 0" and rows[1]["default_text"] == "false"


def test_numba_declares_threads_and_sort() -> None:
    pytest.importorskip("numba")
    spec = solver_spec("numba:threads=1,sort=true")
    assert spec.text == "numba:threads=1,sort=true"
    s: Any = make_solver(spec)
    assert s.requested_threads == 1 and s.sort is True
    assert solver_spec("numba:threads=0,sort=false").text == "numba"


def test_records_keep_name_and_options_apart(tunable: type, tmp_path: Path) -> None:
    case = ToyDiffusion()
    tasks = plan(case, ["tunable:fast=1", "tunable"], "smoke")
    specs = list(dict.fromkeys(t.solver for t in tasks))
    assert specs == ["tunable:fast=true", "tunable"]
    ids = {t.solver: t.run_id for t in tasks}
    assert ids["tunable:fast=true"].startswith(f"{case.name}_tunable_fast=true_")
    assert ids["tunable"].startswith(f"{case.name}_tunable_")
    assert ids["tunable:fast=true"] != ids["tunable"]
    # the default spec keeps the run id a plain name gives (baselines stay valid)
    p = tasks[0].params
    assert run_id(case.name, "tunable", p) == run_id(case.name, solver_spec("tunable").text, p)
    with only_cases(case):
        rec = execute_task(tasks[0], str(tmp_path), {})
    assert rec["solver"] == "tunable" and rec["solver_options"] == "fast=true"
    assert rec["status"] == "completed", rec["reason"]
    assert solver_label(rec) == "tunable:fast=true"
    assert solver_folder(solver_label(rec)) == "tunable_fast=true"
    saved = json.loads((tmp_path / "runs" / f"{tasks[0].run_id}.json").read_text())
    assert saved["solver_options"] == "fast=true"


def test_cli_refuses_a_bad_option_naming_the_allowed_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("numba")
    for argv, msg in (
        (["validate", "diffusion", "--solver", "numba:thread=1"],
         "solver 'numba' has no option 'thread'; its options: threads, sort"),
        (["validate", "all", "--solver", "numba:threads=two"],
         "option threads = 'two' is not allowed: an int >= 0"),
        (["bench", "--solver", "numba:sort=maybe", "--n", "600"],
         "option sort = 'maybe' is not allowed: a bool"),
        (["check", "numba:colour=red"], "its options: threads, sort"),
    ):
        assert cli.main([*argv, "--tier", "smoke", "--out", str(tmp_path)] if argv[0] ==
                        "validate" else argv) == 2
        err = capsys.readouterr().err
        assert msg in err and "Traceback" not in err and err.count("\n") == 1, err


def test_solvers_lists_each_backends_options(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("numba")
    assert cli.main(["solvers", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert [o["name"] for o in rows["numba"]["options"]] == ["threads", "sort", "vectorize"]
    assert rows["reference"]["options"] == []
    assert cli.main(["solvers"]) == 0
    out = capsys.readouterr().out
    assert "options (--solver numba:key=value,...):" in out and "sort (default false" in out
    assert "vectorize (default true" in out


# --------------------------------------------------------------------------- health


class CountingState(ReferenceSolver):
    """Counts how often the state is read."""

    name = "counting"

    def _setup(self, problem: Any) -> None:
        self.reads = 0
        super()._setup(problem)

    def state(self) -> Any:
        self.reads += 1
        return super().state()


def test_the_runner_checks_health_not_the_state() -> None:
    s = CountingState()
    res = run(s, problems.column_in_tank_problem(), max_steps=30)
    assert res.ok and res.n_steps == 30
    assert s.reads <= 3, s.reads  # the end state, its particle count: not once per step


def test_health_of_both_backends_agrees_and_sees_trouble() -> None:
    pytest.importorskip("numba")
    problem = problems.column_in_tank_problem()
    for name in ("reference", "numba"):
        s = make_solver(name)
        s.setup(problem)
        s.step(s.stable_dt())
        h = s.health(0.05)
        vel = s.state().vel[s.state().kind == 0]
        assert h == Health(True, float(np.sqrt((vel**2).sum(axis=1)).max()), 0, 0.0), name
        # trouble in the particles a solver is set up with (state() may be a copy: the numba
        # backend keeps its particles in an order of its own)
        p = problem.particles.copy()
        fluid = np.flatnonzero(p.kind == 0)
        p.pos[fluid[0], 0] = problem.box.hi[0] + 1.0  # a particle far out of the box
        p.vel[fluid[1]] = (30.0, 40.0)
        s = make_solver(name)
        s.setup(dataclasses.replace(problem, particles=p))
        h = s.health(0.05)
        assert (h.finite, h.max_fluid_speed, h.fluid_outside) == (True, 50.0, 1), name
        wall = int(np.flatnonzero(p.kind != 0)[0])
        for column, value in (("pressure", np.nan), ("vel", np.inf), ("vel", -np.inf)):
            bad = p.copy()
            getattr(bad, column)[wall] = value  # one value of one wall particle
            s = make_solver(name)
            s.setup(dataclasses.replace(problem, particles=bad))
            assert not s.health(0.05).finite, (name, column, value)


@pytest.mark.parametrize("name", ["reference", "numba"])
def test_health_or_step_before_setup_says_so(name: str) -> None:
    if name == "numba":
        pytest.importorskip("numba")
    with pytest.raises(RuntimeError, match=rf"^{name}: call setup\(problem\) before health"):
        make_solver(name).health(0.05)
    with pytest.raises(RuntimeError, match=rf"^{name}: call setup\(problem\) before step"):
        make_solver(name).step(0.01)


def test_a_solver_without_health_still_runs() -> None:
    """A backend that predates health() (no SolverBase): the runner checks its state."""

    class Plain:
        name, version = "plain", "1"

        def __init__(self) -> None:
            self.inner = ReferenceSolver()
            self.capabilities = self.inner.capabilities

        def __getattr__(self, key: str) -> Any:
            if key == "health":
                raise AttributeError(key)
            return getattr(self.inner, key)

        def setup(self, problem: Any) -> None:
            self.inner.setup(problem)

        def step(self, dt: float) -> None:
            self.inner.step(dt)
            if self.inner.n_steps == 5:
                self.inner.state().vel[0] = np.inf

    res = run(Plain(), problems.column_in_tank_problem(), max_steps=10)
    assert res.status == "diverged" and "non-finite" in res.reason
