"""numba particle-steps/s of the checkout it is imported from, for comparisons across commits.

    PYTHONPATH=<checkout> python tests/benchmarks/numba_across_commits.py N THREADS [LABEL]

A script, not a test (timings belong to benchmarks, and pytest does not collect this file).
``mpsbench bench`` compares solvers inside one process; two versions of the code cannot share
one, so this script runs one version per process: it builds the bench dam break at about N
particles (:func:`workload`, or the older ``mpsbench.bench.workload`` of commits before the
core's layout), sets up ``NumbaSolver(threads=THREADS)`` from the ``solvers`` package of
PYTHONPATH (``VECTORIZE=1`` in the environment: ``vectorize=True``), takes 5 warm-up steps,
times 5 blocks of 20 steps and prints the median, min and max M particle-steps/s, the load and
the source folder it ran.  Interleave the versions, each with its own compile cache, e.g.::

    git worktree add /tmp/old c0d570e
    for round in 1 2 3; do for v in /tmp/old .; do
        NUMBA_CACHE_DIR=/tmp/nc_$(basename $v) PYTHONPATH=$v \\
            python tests/benchmarks/numba_across_commits.py 40000 2 $v
    done; done

(run it once per version first, so that compiling stays out of the timed rounds).
"""

from __future__ import annotations

import os
import statistics
import sys
import time

BLOCKS, STEPS, WARMUP = 5, 20, 5


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3) or not all(a.isdigit() for a in argv[:2]):
        print(__doc__.splitlines()[2].strip(), file=sys.stderr)
        return 2
    n, threads = int(argv[0]), int(argv[1])
    label = argv[2] if len(argv) == 3 else "numba"
    try:
        from mpsbench.testing.bench import workload
    except ImportError:  # commits before the core's layout (mpsbench/bench.py)
        from mpsbench.bench import workload  # type: ignore[no-redef]
    import solvers.numba_backend as backend

    options = {"vectorize": True} if os.environ.get("VECTORIZE") == "1" else {}
    s = backend.NumbaSolver(threads=threads, **options)
    s.setup(workload(n))
    for _ in range(WARMUP):
        s.step(s.stable_dt())
    particles = s.state().n
    rates = []
    for _ in range(BLOCKS):
        t = time.perf_counter()
        for _ in range(STEPS):
            s.step(s.stable_dt())
        rates.append(particles * STEPS / (time.perf_counter() - t) / 1e6)
    print(f"{label} n={particles} threads={threads} median={statistics.median(rates):.3f} "
          f"min={min(rates):.3f} max={max(rates):.3f} M particle-steps/s "
          f"load={os.getloadavg()[0]:.2f} src={os.path.dirname(backend.__file__)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
