"""The conformance checks: what every solver backend must do, whatever its internals.

A check is a :class:`Check`: a name (``check_momentum_pgm2``), the capabilities it needs (a
solver that does not declare them gets a skip with the reason) and a function that raises
``AssertionError`` with a readable message when the solver does not conform.  Checks create
fresh solver instances themselves (from a name, a class, or a deep copy of an instance), so one
check can compare two runs.

Every check is small (at most a few hundred particles and a few dozen steps).
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mpsbench.physics.config import FlowPhysics, Inflow, Models, Region, TimeStepping
from mpsbench.physics.gradients import GRADIENTS
from mpsbench.physics.laplacians import LAPLACIANS
from mpsbench.physics.particles import Box, Kind, Particles
from mpsbench.physics.weights import WEIGHTS
from mpsbench.run.protocol import (
    SCHEMES,
    Capabilities,
    Problem,
    Solver,
    Status,
    UnsupportedProblem,
)
from mpsbench.run.specs import get_solver_class, make_solver

from . import problems

SolverSpec = Any  # a registry name, a solver class or a solver instance
Needs = Mapping[str, frozenset[str]]


class SkipCheck(Exception):
    """The check does not apply to this solver; the message says why."""


# --------------------------------------------------------------------------- solver handling


def fresh_solver(spec: SolverSpec) -> Solver:
    """A new, not yet set-up solver: from a name, a class, or a deep copy of an instance."""
    if isinstance(spec, (str, type)):
        return make_solver(spec)
    return copy.deepcopy(spec)


def capabilities_of(spec: SolverSpec) -> Capabilities:
    obj = spec if not isinstance(spec, str) else get_solver_class(spec)
    caps = getattr(obj, "capabilities", None)
    return caps if isinstance(caps, Capabilities) else Capabilities()


def solver_label(spec: SolverSpec) -> str:
    """A short label for ids: the registry name, or the solver's ``name`` attribute."""
    if isinstance(spec, str):
        return spec
    name = getattr(spec, "name", None)
    if isinstance(name, str) and name:
        return name
    return spec.__name__ if isinstance(spec, type) else type(spec).__name__


def expected_failures(spec: SolverSpec) -> dict[str, str]:
    """The solver's declared expected failures: check name -> reason."""
    obj = spec if not isinstance(spec, str) else get_solver_class(spec)
    declared = getattr(obj, "expected_failures", None) or {}
    return {str(k): str(v) for k, v in dict(declared).items()}


def declared(caps: Capabilities, category: str) -> list[str]:
    """Names a solver declares in a model category (all registered ones when it says "any")."""
    have = getattr(caps, category)
    registry = {"laplacians": LAPLACIANS, "weights": WEIGHTS, "gradients": GRADIENTS}[category]
    names = registry.names()
    return names if have is None else [n for n in names if n in have]


def _supports(caps: Capabilities, category: str, item: str) -> bool:
    """Whether a problem asking for ``item`` of ``category`` runs on the solver (a category
    it ``ignores`` runs with any item: it is not used)."""
    if category in caps.ignores:
        return True
    have = getattr(caps, category, None)
    return have is None or item in have


_SINGULAR = {
    "boundaries": "boundary",
    "features": "feature",
    "laplacians": "laplacian",
    "weights": "weight",
    "gradients": "gradient",
}


def _missing(caps: Capabilities, needs: Needs) -> list[str]:
    """What a check needs that the solver lacks; a category it ``ignores`` is lacking (a check
    of MPS Laplacians tests nothing on a code that has none)."""
    out = []
    for category, items in needs.items():
        if category in caps.ignores:
            out.append(f"{category} (it uses none of them: Capabilities.ignores)")
            continue
        if not hasattr(caps, category):  # an ignorable setting: only ``ignores`` gates it
            continue
        for item in sorted(items):
            if not _supports(caps, category, item):
                out.append(f"{_SINGULAR.get(category, category)} {item!r}")
    return out


def _pick(caps: Capabilities, category: str, preferred: str) -> str:
    """``preferred`` when the solver supports it, else the first model it declares."""
    if _supports(caps, category, preferred):
        return preferred
    names = declared(caps, category)
    if not names:
        raise SkipCheck(f"solver declares no {category}")
    return names[0]


def _models(caps: Capabilities, **overrides: Any) -> Models:
    base = {
        "weight": _pick(caps, "weights", "wf2"),
        "laplacian": _pick(caps, "laplacians", "xu-jin"),
        "gradient": _pick(caps, "gradients", "pgm1"),
    }
    return Models(**{**base, **overrides})


# --------------------------------------------------------------------------- the Check object


@dataclass(frozen=True)
class Check:
    """One conformance check.

    ``needs`` maps capability categories to the items the check needs (for a skip before it
    runs); the function may still raise :class:`SkipCheck` when what it needs depends on more
    than one capability.
    """

    name: str
    func: Callable[..., None]
    description: str
    needs: Needs = field(default_factory=dict)
    kwargs: Mapping[str, Any] = field(default_factory=dict)

    def skip_reason(self, caps: Capabilities) -> str | None:
        missing = _missing(caps, self.needs)
        return "solver does not declare " + ", ".join(missing) if missing else None


    def __call__(self, solver: SolverSpec) -> None:
        """Run the check on ``solver`` (name, class or instance); raises on failure."""
        caps = capabilities_of(solver)
        reason = self.skip_reason(caps)
        if reason:
            raise SkipCheck(reason)
        with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"):
            self.func(lambda: fresh_solver(solver), caps, **self.kwargs)

    def __repr__(self) -> str:
        return f"<Check {self.name}>"


Factory = Callable[[], Solver]


# --------------------------------------------------------------------------- helpers


def _fixed_dt(make: Factory, problem: Problem, factor: float = 1.0) -> float:
    """``factor`` x the solver's own stable dt for ``problem`` (from a throwaway instance)."""
    s = make()
    s.setup(problem)
    dt = float(s.stable_dt())
    assert math.isfinite(dt) and dt > 0, f"stable_dt() returned {dt!r}, expected a number > 0"
    return factor * dt


def _with_dt(problem: Problem, dt: float) -> Problem:
    return dataclasses.replace(problem, time_stepping=TimeStepping(dt=dt))


def _advance(s: Solver, n: int, dt: float | None = None) -> None:
    for _ in range(n):
        s.step(float(s.stable_dt()) if dt is None else dt)


def _flow_problem(caps: Capabilities, **physics: Any) -> Problem:
    """A small supported flow problem: a column in a tank, else a periodic box."""
    if _supports(caps, "boundaries", "walls"):
        return problems.column_in_tank_problem(models=_models(caps), **physics)
    if _supports(caps, "boundaries", "periodic"):
        return problems.periodic_flow_problem(models=_models(caps, n0_from="lattice"), **physics)
    raise SkipCheck("solver declares neither boundary 'walls' nor 'periodic' for flow")


def _problems_for_physics(caps: Capabilities) -> Iterator[Problem]:
    if _supports(caps, "physics", "diffusion") and _supports(caps, "boundaries", "periodic"):
        yield problems.diffusion_problem(
            _pick(caps, "laplacians", "xu-jin"), _pick(caps, "weights", "wf2"), value=None
        )
    if _supports(caps, "physics", "flow"):
        try:
            yield _flow_problem(caps)
        except SkipCheck:
            pass


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b))


# --------------------------------------------------------------------------- the checks


def check_api_shape(make: Factory, caps: Capabilities) -> None:
    """The solver implements the protocol with the right attribute types and a fresh state."""
    s = make()
    members = (
        "name",
        "version",
        "capabilities",
        "time",
        "n_steps",
        "status",
        "setup",
        "stable_dt",
        "step",
        "state",
        "diagnostics",
    )
    missing = [m for m in members if not hasattr(s, m)]
    assert not missing, f"solver lacks {', '.join(missing)} (mpsbench.run.protocol.Solver)"
    assert isinstance(s, Solver), "solver is not an instance of mpsbench.run.protocol.Solver"
    assert isinstance(s.name, str) and s.name, f"name must be a non-empty str, got {s.name!r}"
    assert isinstance(s.version, str), f"version must be a str, got {type(s.version).__name__}"
    assert isinstance(s.capabilities, Capabilities), (
        "capabilities must be mpsbench.run.protocol.Capabilities, got "
        f"{type(s.capabilities).__name__}"
    )
    for f in dataclasses.fields(Capabilities):
        value = getattr(s.capabilities, f.name)
        if f.name == "scheme":
            assert value in SCHEMES, f"capabilities.scheme must be one of {', '.join(SCHEMES)}"
            continue
        optional = f.name in ("laplacians", "weights", "gradients")
        ok = (value is None and optional) or (
            isinstance(value, frozenset) and all(isinstance(v, str) for v in value)
        )
        what = "a frozenset of str" + (" or None" if optional else "")
        assert ok, f"capabilities.{f.name} must be {what}"
        if optional and value is not None:
            registry = {"laplacians": LAPLACIANS, "weights": WEIGHTS, "gradients": GRADIENTS}
            unknown = sorted(v for v in value if v not in registry[f.name])
            assert not unknown, f"capabilities.{f.name} names unregistered models {unknown}"
    assert s.status == Status.READY and isinstance(s.status, Status), (
        f"a new solver must have status Status.READY, got {s.status!r}"
    )
    assert s.time == 0.0 and s.n_steps == 0, (
        f"a new solver must start at time 0 and step 0, got {s.time!r}, {s.n_steps!r}"
    )
    try:
        s.step(1e-4)
    except Exception:  # noqa: BLE001 - any exception is the right answer here
        pass
    else:
        raise AssertionError("step() before setup() must raise, it returned silently")


def check_lifecycle(make: Factory, caps: Capabilities) -> None:
    """setup/stable_dt/step/state/diagnostics behave; time, n_steps and status advance."""
    tried = 0
    for problem in _problems_for_physics(caps):
        tried += 1
        what = f"[{problem.name}]"
        before = problem.particles.copy()
        s = make()
        s.setup(problem)
        assert s.status == Status.RUNNING, f"{what} status after setup is {s.status!r}, not running"
        assert s.time == 0.0 and s.n_steps == 0, f"{what} setup must start at time 0, step 0"
        st = s.state()
        assert isinstance(st, Particles), f"{what} state() returned {type(st).__name__}"
        assert st.n == before.n, f"{what} state() has {st.n} particles, the problem {before.n}"
        assert st.pos.shape == (st.n, 2) and st.vel.shape == (st.n, 2), f"{what} bad shapes"
        dt = s.stable_dt()
        assert isinstance(dt, (float, np.floating)) and math.isfinite(dt) and dt > 0, (
            f"{what} stable_dt() returned {dt!r}, expected a finite float > 0"
        )
        dt = float(dt)
        for k in range(3):
            s.step(dt)
            assert s.n_steps == k + 1, f"{what} n_steps is {s.n_steps} after {k + 1} steps"
            assert math.isclose(s.time, (k + 1) * dt, rel_tol=1e-12), (
                f"{what} time is {s.time!r} after {k + 1} steps of {dt!r} s"
            )
        st = s.state()
        for name in ("pos", "vel", "pressure"):
            assert np.all(np.isfinite(getattr(st, name))), f"{what} non-finite state().{name}"
        diag = s.diagnostics()
        assert isinstance(diag, dict), f"{what} diagnostics() returned {type(diag).__name__}"
        nd = diag.get("number_density")
        if nd is not None:
            nd = np.asarray(nd)
            assert nd.shape == (st.n,) and np.all(np.isfinite(nd)), (
                f"{what} diagnostics()['number_density'] must be finite with shape ({st.n},)"
            )
        after = problem.particles
        for name in ("pos", "vel", "pressure", "kind"):
            assert _same(getattr(before, name), getattr(after, name)), (
                f"{what} the solver changed Problem.particles.{name}: setup() must copy it"
            )
        # a fixed time step in the problem is what stable_dt() returns
        s.setup(_with_dt(problem, 0.5 * dt))
        assert s.time == 0.0 and s.n_steps == 0, f"{what} a second setup() must restart the clock"
        assert s.stable_dt() == 0.5 * dt, (
            f"{what} stable_dt() must return Problem.time_stepping.dt when it is fixed"
        )
    if not tried:
        raise SkipCheck("solver declares neither periodic diffusion nor a flow it can run")


def _capability_probes() -> Iterator[tuple[str, Problem]]:
    """(label, problem) pairs that each need one more capability than a basic flow."""
    models = Models(n0_from="lattice")

    def base(**physics: Any) -> Problem:
        return problems.column_in_tank_problem(nx=4, ny=4, width_cells=8, models=models, **physics)

    yield "physics 'diffusion'", problems.diffusion_problem(n_side=8, value=None)
    yield (
        "physics 'flow' + boundary 'periodic'",
        problems.periodic_flow_problem(n_side=8, models=models),
    )
    yield "boundary 'walls'", base()
    yield "boundary 'periodic-x' + 'walls'", problems.channel_problem(nx=8, ny=4, models=models)
    yield (
        "boundary 'moving-walls'",
        problems.channel_problem(nx=8, ny=4, models=models, top_velocity=(0.01, 0.0)),
    )
    yield (
        "boundary 'sliding-walls'",
        problems.channel_problem(nx=8, ny=4, models=models, top_velocity=(0.01, 0.0),
                                 sliding=True),
    )
    yield "boundary 'inflow' + 'outflow'", problems.open_channel_problem(nx=8, ny=4, models=models)
    p = base()
    yield "boundary 'outflow'", dataclasses.replace(p, outflows=(Region((0.5, 0.0), (0.6, 0.1)),))
    yield (
        "boundary 'inflow'",
        dataclasses.replace(p, inflow=Inflow((0.0, 0.12), (0.04, 0.12), (0.0, -0.1), layers=2)),
    )
    yield "boundary 'periodic-y'", _periodic_y_probe(models)
    for feature, physics in (
        ("collision", {"collision": True}),
        ("stabilization", {"stabilization": True}),
        ("mirror-walls", {"wall_velocity": "mirror"}),
    ):
        yield f"feature {feature!r}", base(**physics)
    yield (
        "feature 'gradient-correction'",
        problems.diffusion_problem(n_side=8, value=None, gradient_correction=True),
    )
    for name in LAPLACIANS.names():
        yield f"laplacian {name!r}", problems.diffusion_problem(name, n_side=8, value=None)
    for name in WEIGHTS.names():
        yield (
            f"weight {name!r}",
            problems.column_in_tank_problem(
                nx=4, ny=4, width_cells=8, models=Models(weight=name, n0_from="lattice")
            ),
        )
    for name in GRADIENTS.names():
        yield (
            f"gradient {name!r}",
            problems.column_in_tank_problem(
                nx=4, ny=4, width_cells=8, models=Models(gradient=name, n0_from="lattice")
            ),
        )


def _periodic_y_probe(models: Models) -> Problem:
    """A y-periodic channel: the x-periodic channel turned by 90 degrees."""
    p = problems.channel_problem(nx=8, ny=4, models=models)
    parts = p.particles.copy()
    parts.pos[:] = parts.pos[:, ::-1]
    parts.vel[:] = parts.vel[:, ::-1]
    nx, ny = parts.fields["wall_nx"].copy(), parts.fields["wall_ny"].copy()
    parts.fields["wall_nx"], parts.fields["wall_ny"] = ny, nx
    lo, hi = p.box.lo, p.box.hi
    box = Box((lo[1], lo[0]), (hi[1], hi[0]), (False, True))
    return dataclasses.replace(p, particles=parts, box=box, name="channel-y")


def check_capabilities_honoured(make: Factory, caps: Capabilities) -> None:
    """Declared capabilities are accepted by setup(); undeclared ones raise UnsupportedProblem."""
    wrong = []
    for label, problem in _capability_probes():
        gaps = caps.gaps(problem)
        s = make()
        try:
            s.setup(problem)
        except UnsupportedProblem as exc:
            if not gaps:
                wrong.append(f"{label}: declared but setup() raised UnsupportedProblem ({exc})")
            continue
        except Exception as exc:  # noqa: BLE001 - reported as a failure
            wrong.append(f"{label}: setup() raised {type(exc).__name__}: {exc}")
            continue
        if gaps:
            wrong.append(
                f"{label}: not declared ({'; '.join(gaps)}) but setup() did not raise "
                "mpsbench.run.protocol.UnsupportedProblem"
            )
    assert not wrong, "; ".join(wrong)


def check_determinism(make: Factory, caps: Capabilities, n_steps: int = 10) -> None:
    """The same problem run twice gives bitwise the same state after ``n_steps`` steps."""
    builders: list[Callable[[], Problem]] = []
    if _supports(caps, "physics", "flow"):
        if _supports(caps, "boundaries", "periodic"):
            builders.append(
                lambda: problems.periodic_flow_problem(
                    velocity=0.05, models=_models(caps, n0_from="lattice")
                )
            )
        if _supports(caps, "boundaries", "walls"):
            builders.append(lambda: problems.column_in_tank_problem(models=_models(caps)))
    if _supports(caps, "physics", "diffusion") and _supports(caps, "boundaries", "periodic"):
        builders.append(
            lambda: problems.diffusion_problem(_pick(caps, "laplacians", "xu-jin"), value=None)
        )
    if not builders:
        raise SkipCheck("no problem the kit can build is supported")
    for build in builders:
        dt = _fixed_dt(make, build())
        states = []
        for _ in range(2):
            s = make()
            s.setup(_with_dt(build(), dt))
            _advance(s, n_steps)
            states.append(s.state().copy())
        a, b = states
        name = build().name
        for attr in ("pos", "vel", "pressure", "kind"):
            assert _same(getattr(a, attr), getattr(b, attr)), (
                f"[{name}] two runs of the same problem differ in {attr} after {n_steps} steps"
            )
        for key in set(a.fields) | set(b.fields):
            assert key in a.fields and key in b.fields and _same(a.fields[key], b.fields[key]), (
                f"[{name}] two runs of the same problem differ in field {key!r}"
            )


def check_uniform_diffusion(
    make: Factory,
    caps: Capabilities,
    laplacian: str,
    gradient_correction: bool = False,
    n_steps: int = 10,
) -> None:
    """A uniform scalar stays uniform under diffusion on a jittered periodic lattice."""
    value = 3.7
    weight = _pick(caps, "weights", "wf2")
    problem = problems.diffusion_problem(
        laplacian, weight, value=value, gradient_correction=gradient_correction
    )
    s = make()
    s.setup(problem)
    _advance(s, n_steps)
    phi = s.state().fields["phi"]
    err = float(np.max(np.abs(phi - value)))
    assert err <= 1e-12 * value, (
        f"uniform field {value} drifted by {err:.3g} after {n_steps} steps with {laplacian!r}"
    )


def check_rest_periodic(make: Factory, caps: Capabilities, n_steps: int = 20) -> None:
    """A uniformly compressed fluid at rest in a periodic box, without gravity, stays at rest.

    The lattice is squeezed to 0.98 l0 (n0 from the ideal lattice), so every particle carries
    the same positive pressure: only the symmetry of the pressure gradient (every gradient
    model the solver declares) keeps it at rest.
    """
    for gradient in declared(caps, "gradients"):
        problem = problems.periodic_flow_problem(
            amplitude=0.0, squeeze=0.98, models=_models(caps, gradient=gradient, n0_from="lattice")
        )
        ph = problem.physics
        assert isinstance(ph, FlowPhysics)
        x0 = problem.particles.pos.copy()
        s = make()
        s.setup(problem)
        _advance(s, n_steps)
        st = s.state()
        fluid = st.kind == Kind.FLUID
        assert np.all(st.pressure[fluid] > 0), (
            f"[{gradient}] a fluid compressed to 0.98 l0 must carry a positive pressure"
        )
        speed = float(np.sqrt((st.vel**2).sum(axis=1)).max())
        d = st.pos - x0
        problem.box.minimum_image(d)
        moved = float(np.sqrt((d**2).sum(axis=1)).max())
        # round-off only: the pair terms of a uniform pressure cancel on the lattice
        assert speed <= 1e-9 * ph.c0, (
            f"[{gradient}] resting fluid reached speed {speed:.3g} m/s in {n_steps} steps"
        )
        assert moved <= 1e-9 * problem.l0, (
            f"[{gradient}] resting fluid moved by {moved:.3g} m in {n_steps} steps"
        )


def check_momentum(make: Factory, caps: Capabilities, gradient: str, n_steps: int = 20) -> None:
    """Total fluid momentum is conserved in a periodic box (momentum-conserving gradients).

    Jittered start with random velocities, no gravity, no walls, nu > 0.  The change in
    sum(u) must be round-off relative to sum(|u|) + the total pressure impulse.
    """
    problem = problems.periodic_flow_problem(
        velocity=0.2, models=_models(caps, gradient=gradient, n0_from="lattice")
    )
    s = make()
    s.setup(problem)
    m0 = s.state().vel.sum(axis=0).copy()
    scale = 0.0
    for _ in range(n_steps):
        v_before = s.state().vel.copy()
        s.step(float(s.stable_dt()))
        scale += float(np.abs(s.state().vel - v_before).sum())  # sum of |impulses|
    st = s.state()
    assert st.n == problem.particles.n
    scale += float(np.abs(st.vel).sum())
    drift = float(np.abs(st.vel.sum(axis=0) - m0).max())
    assert scale > 0, "nothing moved: the check is meaningless"
    assert drift <= 1e-12 * scale, (
        f"sum of velocities changed by {drift:.3g} m/s with {gradient!r} "
        f"(scale sum|du| + sum|u| = {scale:.3g} m/s)"
    )


def check_particle_count(make: Factory, caps: Capabilities, n_steps: int = 20) -> None:
    """Without inflow or outflow the particle count and the kinds never change."""
    problem = _flow_problem(caps)
    kinds0 = np.bincount(problem.particles.kind, minlength=len(Kind))
    s = make()
    s.setup(problem)
    for k in range(n_steps):
        s.step(float(s.stable_dt()))
        st = s.state()
        kinds = np.bincount(st.kind, minlength=len(Kind))
        assert st.n == problem.particles.n and _same(kinds, kinds0), (
            f"[{problem.name}] particle counts by kind went from {kinds0.tolist()} to "
            f"{kinds.tolist()} at step {k + 1} without inflow or outflow"
        )


def check_divergence_reported(make: Factory, caps: Capabilities, factor: float = 20.0) -> None:
    """A run with a huge fixed dt ends as status 'diverged' with a reason, not an exception."""
    from mpsbench.run.runner import run

    problem = _flow_problem(caps)
    dt = _fixed_dt(make, problem, factor)
    result = run(make(), _with_dt(problem, dt), max_steps=200)
    assert result.status == Status.DIVERGED, (
        f"[{problem.name}] dt = {factor:g} x stable dt ended with status {result.status.value!r}"
        + (f": {result.reason}" if result.reason else "")
        + ", expected 'diverged'"
    )
    assert result.reason, "a diverged run must carry a reason"


# --------------------------------------------------------------------------- the catalogue


def api_checks() -> list[Check]:
    """The protocol and invariant checks, in the order they run (model-specific checks once per
    registered model); the physics checks are :mod:`.physics_checks`, every check
    :func:`mpsbench.testing.catalogue.all_checks`."""
    flow_periodic = {"physics": frozenset({"flow"}), "boundaries": frozenset({"periodic"})}
    diffusion = {"physics": frozenset({"diffusion"}), "boundaries": frozenset({"periodic"})}
    checks = [
        Check("check_api_shape", check_api_shape, "protocol members, types, fresh state"),
        Check(
            "check_lifecycle",
            check_lifecycle,
            "setup/stable_dt/step/state/diagnostics; time, n_steps, status",
        ),
        Check(
            "check_capabilities_honoured",
            check_capabilities_honoured,
            "declared capabilities accepted, undeclared ones raise UnsupportedProblem",
        ),
        Check("check_determinism", check_determinism, "same inputs, bitwise same state"),
    ]
    for lap in LAPLACIANS.names():
        checks.append(
            Check(
                f"check_uniform_diffusion_{lap}",
                check_uniform_diffusion,
                f"a uniform scalar stays uniform under {lap} diffusion",
                needs={**diffusion, "laplacians": frozenset({lap})},
                kwargs={"laplacian": lap},
            )
        )
    checks.append(
        Check(
            "check_uniform_diffusion_xu-jin-corrected",
            check_uniform_diffusion,
            "a uniform scalar stays uniform under xu-jin diffusion with gradient correction",
            needs={
                **diffusion,
                "laplacians": frozenset({"xu-jin"}),
                "features": frozenset({"gradient-correction"}),
            },
            kwargs={"laplacian": "xu-jin", "gradient_correction": True},
        )
    )
    checks.append(
        Check(
            "check_rest_periodic",
            check_rest_periodic,
            "a resting periodic fluid without gravity stays at rest",
            needs=flow_periodic,
        )
    )
    for grad in ("pgm2", "pgm3"):
        checks.append(
            Check(
                f"check_momentum_{grad}",
                check_momentum,
                f"momentum conserved in a periodic box with {grad}",
                needs={**flow_periodic, "gradients": frozenset({grad})},
                kwargs={"gradient": grad},
            )
        )
    checks.append(
        Check(
            "check_particle_count",
            check_particle_count,
            "particle count conserved without inflow/outflow",
            needs={"physics": frozenset({"flow"})},
        )
    )
    checks.append(
        Check(
            "check_divergence_reported",
            check_divergence_reported,
            "a blow-up is reported by the runner as 'diverged'",
            needs={"physics": frozenset({"flow"})},
        )
    )
    return checks
