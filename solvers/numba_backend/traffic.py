"""Bytes a numba WC-MPS step streams through memory, from the arrays each pass touches (not a test).

    python -m mpsbench.solvers.numba_backend.traffic [--n 40000] [--threads 2] [--steps 20]
                                                     [--bandwidth 43]

Sets up the benchmark dam break (:func:`mpsbench.testing.bench.workload`), runs a few steps,
then counts, per pass of :mod:`.fused`, the bytes of the arrays its kernel reads or writes
once per particle (a read-and-write array twice) and of the neighbour indices it walks
(``nbr``, 4 B an entry; the p_min row of PGM1 walks them a second time), plus a neighbour
rebuild's traffic times the rebuilds per step.  Gathers of a neighbour's position, velocity or
pressure are taken as cache hits: the particles are sorted along a Z curve (:mod:`.layout`), so
a row's neighbours were loaded by the rows just before it.  This is the floor of the traffic,
not a measurement of it; with the measured step rate it gives the fraction of a memory
bandwidth bound (``--bandwidth`` in GB/s; the README's machine: 25 on one thread, 43 on two).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from typing import Any

import numpy as np

from . import fused
from .solver import NumbaSolver


def _bytes(*arrays: np.ndarray) -> int:
    return sum(int(a.nbytes) for a in arrays)


def pass_bytes(s: NumbaSolver) -> dict[str, float]:
    """Bytes per step of each pass of a set-up flow solver (the arrays its kernel streams)."""
    p = s.p
    big = s.neigh.csr
    assert big is not None
    small = s.neigh.small if s.neigh.small is not None else big
    ph: Any = s.problem.physics if s.problem is not None else None
    twice = 2 if s._pmin_mode == fused.PMIN_ROW else 1
    out: dict[str, float] = {
        "predict": _bytes(big.offsets, big.nbr, s._X, s._V, p.kind, s._Xref, s._X2, s._V2),
        "density_pressure": _bytes(small.offsets, small.nbr, s._X, s.static_n, p.kind,
                                   s.number_density, p.pressure, s.free_surface, s._inner),
        "correct": _bytes(small.offsets, s._X, p.pressure, s._no_dummy, p.kind, s._V, s._V,
                          s._DU) + twice * small.nbr.nbytes,
        "move": _bytes(small.offsets, small.nbr, s._X, s._V, s._DU, p.kind, s._inner, s._Xref,
                       s._X2, s._V2),
        "health": _bytes(s._X, s._V, p.pressure, p.kind),
    }
    if ph is not None and ph.collision:
        out["collide"] = _bytes(small.offsets, small.nbr, s._X, s._W, p.kind, s._V, s._V,
                                s._DU, s._DU)
    return out


def rebuild_bytes(s: NumbaSolver) -> float:
    """One rebuild: the Z keys and their sort, every per-particle array permuted (read and
    write), the cell build (positions in cell order, the candidates written and compacted into
    the big list) and the sub-list read from it."""
    p = s.p
    big = s.neigh.csr
    assert big is not None
    small = s.neigh.small if s.neigh.small is not None else big
    per_particle = _bytes(s._X, s._V, p.kind, p.pressure, s.number_density, s.free_surface,
                          s.static_n, s.group, s.loose, s._no_dummy)
    keys = 4 * 8 * p.n  # keys, argsort (read, write, order)
    cells = 2 * s._X.nbytes + 3 * big.nbr.nbytes + big.offsets.nbytes
    sub = big.nbr.nbytes + small.nbr.nbytes + small.offsets.nbytes
    return float(keys + 2 * per_particle + cells + sub)


def main(argv: list[str] | None = None) -> None:
    from mpsbench.testing.bench import workload

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=40_000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=20, help="steps per timed block (5 blocks)")
    ap.add_argument("--bandwidth", type=float, default=None,
                    help="GB/s of the bound (default: 25 on one thread, 43 on more)")
    args = ap.parse_args(argv)
    bw = 1e9 * (args.bandwidth or (25.0 if args.threads == 1 else 43.0))
    s = NumbaSolver(threads=args.threads)
    s.setup(workload(args.n))
    for _ in range(5):
        s.step(s.stable_dt())
    builds0 = s.neigh.builds
    rates = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(args.steps):
            s.step(s.stable_dt())
        rates.append(s.p.n * args.steps / (time.perf_counter() - t0))
    per_step = (s.neigh.builds - builds0) / (5 * args.steps)
    n = s.p.n
    passes = pass_bytes(s)
    rebuild = per_step * rebuild_bytes(s)
    total = (sum(passes.values()) + rebuild) / n
    rate = statistics.median(rates)
    big = s.neigh.csr
    assert big is not None
    small = s.neigh.small if s.neigh.small is not None else big
    print(f"n = {n}, threads = {s.threads}; list entries per particle {len(big.nbr) / n:.1f} "
          f"(r_max + skin), {len(small.nbr) / n:.1f} (r_e + skin); rebuilds per step "
          f"{per_step:.3f}")
    for name, b in passes.items():
        print(f"  {name:<18} {b / n:7.1f} B per particle")
    print(f"  {'rebuild':<18} {rebuild / n:7.1f} B per particle (amortised)")
    print(f"{total:.0f} B per particle-step; measured {rate / 1e6:.3f} M particle-steps/s (median "
          f"of 5 blocks of {args.steps}) = {total * rate / 1e9:.2f} GB/s, "
          f"{100 * total * rate / bw:.1f} % of {bw / 1e9:.0f} GB/s; load "
          f"{os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
