"""The reference backend's neighbour upkeep and memory per particle (issue 20's two targets).

    python tests/benchmarks/reference_upkeep.py [N] [STEPS]

A script, not a test (timings belong to benchmarks, and pytest does not collect this file).  It
builds the bench dam break (:func:`mpsbench.testing.bench.workload`) at N particles (default
40,000) and prints, in one process:

* upkeep: the wall time of ``SkinnedPairs.get`` (pair refresh and rebuilds) as a share of the
  wall time of STEPS steps (default 30), after three warm-up steps, without a profiler (a
  profiler inflates the many small calls);
* memory: every allocation traced from before ``setup`` (``tracemalloc``): the bytes held
  between steps and the highest point during a step, per particle, the problem excluded.

Run it two or three times, interleaved with the code you compare against, and say the load.
"""

from __future__ import annotations

import sys
import time
import tracemalloc
from typing import Any

from mpsbench.solvers.reference import ReferenceSolver
from mpsbench.solvers.reference import neighbours as skinned

from mpsbench.testing.bench import workload


def upkeep_share(n: int, steps: int) -> tuple[float, float, int]:
    """(ms per step, upkeep share in %, rebuilds) over ``steps`` steps."""
    spent = [0.0]
    original = skinned.SkinnedPairs.get

    def timed(self: Any, *args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return original(self, *args, **kwargs)
        finally:
            spent[0] += time.perf_counter() - t

    skinned.SkinnedPairs.get = timed
    try:
        s = ReferenceSolver()
        s.setup(workload(n))
        dt = s.stable_dt()
        for _ in range(3):
            s.step(dt)
        builds = s.neigh.builds
        spent[0] = 0.0
        t0 = time.perf_counter()
        for _ in range(steps):
            s.step(dt)
        wall = time.perf_counter() - t0
        return 1e3 * wall / steps, 100.0 * spent[0] / wall, s.neigh.builds - builds
    finally:
        skinned.SkinnedPairs.get = original


def memory_per_particle(n: int, steps: int = 12) -> tuple[int, float, float]:
    """(particles, bytes held between steps, highest bytes during a step), per particle."""
    problem = workload(n)
    tracemalloc.start()
    try:
        base, _ = tracemalloc.get_traced_memory()
        s = ReferenceSolver()
        s.setup(problem)
        dt = s.stable_dt()
        for _ in range(3):
            s.step(dt)
        held = worst = 0
        for _ in range(steps):  # enough steps to include rebuilds
            current, _ = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
            s.step(dt)
            _, peak = tracemalloc.get_traced_memory()
            held, worst = max(held, current - base), max(worst, peak - base)
        particles = s.p.n
        return particles, held / particles, worst / particles
    finally:
        tracemalloc.stop()


def main(argv: list[str]) -> None:
    n = int(argv[0]) if argv else 40_000
    steps = int(argv[1]) if len(argv) > 1 else 30
    ms, share, builds = upkeep_share(n, steps)
    print(f"upkeep: {ms:.1f} ms per step, SkinnedPairs.get {share:.1f} % of it "
          f"({steps} steps, {builds} rebuilds)")
    particles, held, peak = memory_per_particle(n)
    print(f"memory: {particles} particles, held {held:.0f} B/particle, highest during a step "
          f"{peak:.0f} B/particle")


if __name__ == "__main__":
    main(sys.argv[1:])
