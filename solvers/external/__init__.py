"""An outside program behind the Solver protocol through files: ``external:program=PATH``.

The file protocol (docs/external-solvers.md has the full text) lets a C++, Fortran or any other
code be validated through a small driver, without linking to Python:

1. The adapter makes a run folder and writes ``problem.json`` (spacing, box, physics, models,
   time stepping, wall motions; SI units) and ``particles.csv`` (one row per particle, in the
   problem's order: ``id,kind,x,y,u,v,p`` and any named fields such as ``wall_tag``).
2. It starts ``PROGRAM RUN_FOLDER`` (a path to an executable; a ``.py`` file runs with this
   Python) with the run folder as working directory, and talks to it by lines on
   stdin/stdout.  The program answers ``ready`` once it has read the problem, or
   ``unsupported REASON`` (the run is recorded unsupported with the reason).
3. For each output time the runner needs (probe times, the end time) the adapter sends
   ``advance T PATH``; the program advances its own simulation, with its own time steps, to
   exactly time T, writes a snapshot ``PATH`` (CSV ``id,x,y,u,v,p``, every particle, any order
   of rows) and answers ``ok T STEPS`` (STEPS: its own time steps so far), or
   ``diverged REASON`` / ``error REASON``.
4. ``quit`` (or end of input, when the harness is gone) ends the program.

The runner computes every probe (profiles, fronts, pressures) from the snapshots, so a program
writes states, not case-specific outputs; the runner's health checks (finite, speed below c0,
inside the box) run on each snapshot.  Anything the program prints to stderr is kept in
``stderr.txt`` of the run folder and its last lines are quoted when it fails.

This backend declares what a generic outside code can take: flow with walls, moving walls and
periodic axes, its own kernels and time step (the MPS model settings do not apply).  A plugin
for a richer code subclasses :class:`ExternalSolver` with its own ``name``, ``program`` and
``capabilities``.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import IO, Any

import numpy as np

from mpsbench.params import Option
from mpsbench.physics.config import FlowPhysics
from mpsbench.physics.particles import Kind, Particles
from mpsbench.run.protocol import Capabilities, Problem, SolverBase, UnsupportedProblem

PROTOCOL_VERSION = 1
SNAPSHOT_COLUMNS = ("id", "x", "y", "u", "v", "p")


def problem_json(problem: Problem, particles_file: str) -> dict[str, Any]:
    """``problem.json``: everything of the :class:`Problem` but the particles (SI units)."""
    ph = problem.physics
    physics = dict(ph.__dict__)
    physics["kind"] = ph.kind
    return {
        "protocol": PROTOCOL_VERSION,
        "name": problem.name,
        "l0": problem.l0,
        "box": {"lo": list(problem.box.lo), "hi": list(problem.box.hi),
                "periodic": list(problem.box.periodic)},
        "physics": physics,
        "models": dict(problem.models.__dict__),
        "time_stepping": dict(problem.time_stepping.__dict__),
        "wall_motions": [{"tag": m.tag, "velocity": list(m.velocity)}
                         for m in problem.wall_motions],
        "kinds": {k.name.lower(): int(k) for k in Kind},
        "particles": {"file": particles_file, "count": problem.particles.n,
                      "columns": ["id", "kind", "x", "y", "u", "v", "p",
                                  *sorted(problem.particles.fields)]},
    }


def write_particles_csv(path: Path, p: Particles) -> None:
    names = sorted(p.fields)
    cols = [np.arange(p.n), p.kind.astype(int), p.pos[:, 0], p.pos[:, 1], p.vel[:, 0],
            p.vel[:, 1], p.pressure, *[p.fields[n] for n in names]]
    header = ",".join(["id", "kind", "x", "y", "u", "v", "p", *names])
    fmt = ["%d", "%d"] + ["%.17g"] * (len(cols) - 2)
    np.savetxt(path, np.column_stack(cols), fmt=fmt, delimiter=",", header=header, comments="")


def read_snapshot(path: Path, n: int) -> np.ndarray:
    """A snapshot as an (n, 5) array x, y, u, v, p in the problem's order."""
    try:
        with open(path, encoding="utf-8") as fh:
            header = [h.strip() for h in fh.readline().split(",")]
            data = np.loadtxt(fh, delimiter=",", ndmin=2)
    except (OSError, ValueError) as exc:
        raise RuntimeError(f"snapshot {path.name}: cannot read: {exc}") from None
    missing = [c for c in SNAPSHOT_COLUMNS if c not in header]
    if missing:
        raise RuntimeError(f"snapshot {path.name}: columns {missing} missing (header "
                           f"{','.join(header)!r}; expected {','.join(SNAPSHOT_COLUMNS)})")
    if data.shape[0] != n:
        raise RuntimeError(f"snapshot {path.name}: {data.shape[0]} rows, the problem has {n} "
                           "particles")
    ids = data[:, header.index("id")].astype(np.int64)
    if not np.array_equal(np.sort(ids), np.arange(n)):
        raise RuntimeError(f"snapshot {path.name}: ids are not 0..{n - 1}, each once")
    out = np.empty((n, 5))
    out[ids] = data[:, [header.index(c) for c in SNAPSHOT_COLUMNS[1:]]]
    return out


CAPABILITIES = Capabilities.own_kernels(
    physics=frozenset({"flow"}),
    boundaries=frozenset({"periodic", "periodic-x", "periodic-y", "walls", "moving-walls"}),
)


class ExternalSolver(SolverBase):
    """An outside program driven through the file protocol (module docstring)."""

    name = "external"
    version = str(PROTOCOL_VERSION)
    capabilities = CAPABILITIES
    # a program can hang or die: each run goes to a supervised worker process
    isolate = True
    program = ""
    options = (
        Option("program", "", "path of the program implementing docs/external-solvers.md "
               "(an executable, or a .py script run with this Python)", kind=str),
        Option("interval", 0.0, "longest advance the runner asks for [s] (0: straight to the "
               "next output time; > 0 also checks the state that often)", minimum=0.0),
        Option("keep", False, "keep the run folder (problem, particles, snapshots, stderr) "
               "after the run", kind=bool),
    )

    def __init__(self, program: str = "", interval: float = 0.0, keep: bool = False) -> None:
        super().__init__()
        self.program_path = program or self.program
        self.interval = float(interval)
        self.keep = bool(keep)
        self.proc: subprocess.Popen[str] | None = None
        self.folder: Path | None = None
        self._state: Particles | None = None
        self._stderr: IO[str] | None = None
        self._k = 0

    # ------------------------------------------------------------------ process
    def _command(self) -> list[str]:
        path = self.program_path
        if not path:
            raise ValueError(f"{self.name}: no program given (--solver "
                             f"{self.name}:program=PATH)")
        found = shutil.which(path) if os.sep not in path else path
        if found is None or not os.path.isfile(found):
            raise ValueError(f"{self.name}: program {path!r} not found")
        found = os.path.abspath(found)
        return [sys.executable, found] if found.endswith(".py") else [found]

    def _send(self, line: str) -> str:
        assert self.proc is not None and self.proc.stdin and self.proc.stdout
        try:
            self.proc.stdin.write(line + "\n")
            self.proc.stdin.flush()
        except BrokenPipeError:
            pass  # it died: the empty answer below says how
        answer = self.proc.stdout.readline()
        if not answer:
            code = self.proc.wait()
            how = f"killed by signal {-code}" if code < 0 else f"exit status {code}"
            raise RuntimeError(f"{self.name}: the program ended ({how}) without answering "
                               f"{line.split()[0]!r}{self._stderr_tail()}")
        return answer.strip()

    def _stderr_tail(self) -> str:
        if self.folder is None or not (self.folder / "stderr.txt").exists():
            return ""
        lines = (self.folder / "stderr.txt").read_text(errors="replace").strip().splitlines()
        return f"; its stderr ends: {' | '.join(lines[-3:])}" if lines else ""

    def close(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                try:
                    assert self.proc.stdin is not None
                    self.proc.stdin.write("quit\n")
                    self.proc.stdin.close()
                    self.proc.wait(timeout=10)
                except (OSError, subprocess.TimeoutExpired):
                    self.proc.kill()
                    self.proc.wait()
            self.proc = None
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None
        if self.folder is not None and not self.keep:
            shutil.rmtree(self.folder, ignore_errors=True)

    def __del__(self) -> None:  # a run ends without telling its solver: stop the program
        try:
            self.close()
        except Exception:  # noqa: BLE001,S110 - interpreter shutdown
            pass

    # ------------------------------------------------------------------ protocol
    def _setup(self, problem: Problem) -> None:
        if not isinstance(problem.physics, FlowPhysics):  # (the capabilities refuse it first)
            raise UnsupportedProblem(self.name, [f"physics {problem.physics.kind!r}"])
        self.close()
        command = self._command()
        self.folder = Path(tempfile.mkdtemp(prefix=f"mpsbench-{self.name}-"))
        write_particles_csv(self.folder / "particles.csv", problem.particles)
        (self.folder / "problem.json").write_text(
            json.dumps(problem_json(problem, "particles.csv"), indent=1))
        self._stderr = open(self.folder / "stderr.txt", "w", encoding="utf-8")  # noqa: SIM115
        self.proc = subprocess.Popen(
            [*command, str(self.folder)], cwd=self.folder, stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=self._stderr, text=True, bufsize=1)
        answer = self._send("hello 1")
        word, _, rest = answer.partition(" ")
        if word == "unsupported":
            self.close()
            raise UnsupportedProblem(self.name, [rest or "(no reason given)"])
        if word != "ready":
            raise RuntimeError(f"{self.name}: expected 'ready', got {answer[:200]!r}")
        self._template = problem.particles.copy()
        self._state = self._template
        self._k = 0
        self.program_steps = 0

    def _advance(self, dt: float) -> None:
        assert self.folder is not None
        target = self.time + dt
        self._k += 1
        snap = self.folder / f"snapshot_{self._k:05d}.csv"
        answer = self._send(f"advance {target!r} {snap.name}")
        word, _, rest = answer.partition(" ")
        if word == "diverged":
            raise FloatingPointError(f"{self.name}: {rest}")
        if word != "ok":
            raise RuntimeError(f"{self.name}: advance to t = {target:.6g} s: "
                               f"{answer[:300]}{self._stderr_tail()}")
        parts = rest.split()
        try:
            reached, steps = float(parts[0]), int(parts[1])
        except (IndexError, ValueError):
            raise RuntimeError(f"{self.name}: expected 'ok T STEPS', got {answer[:200]!r}"
                               ) from None
        if not math.isclose(reached, target, rel_tol=1e-9, abs_tol=1e-12):
            raise RuntimeError(f"{self.name}: asked for t = {target!r}, the program reached "
                               f"{reached!r}")
        data = read_snapshot(snap, self._template.n)
        if not self.keep:
            snap.unlink(missing_ok=True)
        p = self._template.copy()
        p.pos[:] = data[:, 0:2]
        p.vel[:] = data[:, 2:4]
        p.pressure[:] = data[:, 4]
        self._state = p
        new = steps - self.program_steps
        self.program_steps = steps
        self._new_steps = new

    def step(self, dt: float) -> None:
        """One advance; the step count and particle-steps are the program's own."""
        self._require_setup("step()")
        self._advance(dt)
        self.time += dt
        self.n_steps = self.program_steps
        self.counters["particle_steps"] += self._new_steps * self._template.n
        self.counters["advances"] = self.counters.get("advances", 0.0) + 1

    def stable_dt(self) -> float:
        """The program chooses its own steps: the runner advances it to the next output
        time (or by ``interval`` at most)."""
        return self.interval if self.interval > 0 else 1e30

    def state(self) -> Particles:
        if self._state is None:
            raise RuntimeError(f"{self.name}: call setup(problem) before state()")
        return self._state

    def diagnostics(self) -> dict[str, Any]:
        return {"program": self.program_path, "program_steps": getattr(self, "program_steps", 0)}
