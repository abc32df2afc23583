#!/usr/bin/env python3
"""A small standalone viscous-flow MPS code speaking mpsbench's external-solver file protocol
(docs/external-solvers.md).  It does not import mpsbench: it stands for a C++ or Fortran code.

Physics: incompressible-free viscous flow without pressure (gravity must be zero, so it suits
shear flows such as Couette): du_i/dt = nu <Lap u>_i with the Koshizuka-Oka Laplacian
2d / (lambda n0) sum_j (u_j - u_i) w(r_ij), w = r_e / r - 1 (r < r_e), r_e = re_ratio l0 from
the problem's models, n0 and lambda of the square lattice, forward Euler with its own time step
lambda / (8 nu) (a quarter of the explicit stability limit), cut to land on each requested
time.  Wall and dummy particles carry their velocity (the problem's wall motions) and move with
it.  Periodic axes by the minimum image.  Usage: mini_mps.py RUN_FOLDER (then the line
protocol on stdin/stdout).
"""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import numpy as np


def lattice(re: float) -> tuple[float, float]:
    """n0 and lambda [l0^2] of a square lattice of unit spacing for w = re / r - 1."""
    k = int(math.ceil(re))
    n0 = lam = 0.0
    for i in range(-k, k + 1):
        for j in range(-k, k + 1):
            r = math.hypot(i, j)
            if 0 < r < re:
                w = re / r - 1.0
                n0 += w
                lam += r * r * w
    return n0, lam / n0


class Flow:
    def __init__(self, folder: Path) -> None:
        spec = json.loads((folder / "problem.json").read_text())
        self.spec = spec
        with open(folder / spec["particles"]["file"], newline="") as fh:
            rows = list(csv.DictReader(fh))
        self.n = len(rows)
        col = lambda name: np.array([float(r[name]) for r in rows])  # noqa: E731
        self.pos = np.column_stack([col("x"), col("y")])
        self.vel = np.column_stack([col("u"), col("v")])
        self.kind = col("kind").astype(int)
        fluid_kind = spec["kinds"]["fluid"]
        self.fluid = self.kind == fluid_kind
        if "wall_tag" in rows[0]:
            tag = col("wall_tag")
            for m in spec["wall_motions"]:
                self.vel[(tag == m["tag"]) & ~self.fluid] = m["velocity"]
        self.l0 = float(spec["l0"])
        self.re = float(spec["models"]["re_ratio"]) * self.l0
        n0, lam = lattice(float(spec["models"]["re_ratio"]))
        self.n0, self.lam = n0, lam * self.l0**2
        self.nu = float(spec["physics"]["nu"])
        self.lo = np.array(spec["box"]["lo"], float)
        self.length = np.array(spec["box"]["hi"], float) - self.lo
        self.periodic = np.array(spec["box"]["periodic"], bool)
        self.dt = self.lam / (8.0 * self.nu) if self.nu > 0 else math.inf
        self.t = 0.0
        self.steps = 0

    def unsupported(self) -> str:
        ph = self.spec["physics"]
        if ph.get("kind") != "flow":
            return f"physics {ph.get('kind')!r}: only viscous flow"
        if any(g != 0 for g in ph["gravity"]):
            return "gravity: this code has no pressure solver (shear flows only)"
        if self.nu <= 0:
            return "nu = 0: nothing to compute"
        if ph.get("wall_velocity") != "prescribed":
            return f"wall_velocity {ph.get('wall_velocity')!r}: only prescribed"
        return ""

    def laplacian_u(self) -> np.ndarray:
        d = self.pos[None, :, :] - self.pos[:, None, :]  # d[i, j] = x_j - x_i
        for ax in range(2):
            if self.periodic[ax]:
                d[..., ax] -= self.length[ax] * np.round(d[..., ax] / self.length[ax])
        r = np.hypot(d[..., 0], d[..., 1])
        np.fill_diagonal(r, np.inf)
        w = np.where(r < self.re, self.re / r - 1.0, 0.0)
        du = self.vel[None, :, :] - self.vel[:, None, :]
        return (4.0 / (self.lam * self.n0)) * np.einsum("ij,ijk->ik", w, du)

    def advance(self, target: float) -> None:
        k = max(1, math.ceil((target - self.t) / self.dt - 1e-9))
        h = (target - self.t) / k
        for _ in range(k):
            acc = self.nu * self.laplacian_u()
            self.vel[self.fluid] += h * acc[self.fluid]
            self.pos += h * self.vel  # boundary rows move with their (prescribed) velocity
            for ax in range(2):
                if self.periodic[ax]:
                    self.pos[:, ax] = self.lo[ax] + np.mod(self.pos[:, ax] - self.lo[ax],
                                                           self.length[ax])
            self.steps += 1
        self.t = target
        if not np.isfinite(self.vel).all():
            raise FloatingPointError("non-finite velocity")

    def write(self, path: Path) -> None:
        data = np.column_stack([np.arange(self.n), self.pos, self.vel, np.zeros(self.n)])
        np.savetxt(path, data, fmt=["%d"] + ["%.17g"] * 5, delimiter=",",
                   header="id,x,y,u,v,p", comments="")


def main() -> int:
    folder = Path(sys.argv[1])
    flow = None
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        if words[0] == "hello":
            try:
                flow = Flow(folder)
                why = flow.unsupported()
            except (OSError, KeyError, ValueError) as exc:
                print(f"error cannot read the problem: {exc}", flush=True)
                continue
            print(f"unsupported {why}" if why else "ready", flush=True)
        elif words[0] == "advance" and flow is not None:
            try:
                flow.advance(float(words[1]))
            except FloatingPointError as exc:
                print(f"diverged {exc}", flush=True)
                continue
            flow.write(folder / words[2])
            print(f"ok {flow.t!r} {flow.steps}", flush=True)
        elif words[0] == "quit":
            break
        else:
            print(f"error unknown or early command {words[0]!r}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
