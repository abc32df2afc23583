"""Quick timing of the numba compute layer against the numpy operators (not a test).

    python -m mpsbench.solvers.numba_backend.timing [--side 200] [--re 3.1] [--skin 0.3]

A jittered ``side`` x ``side`` lattice (l0 = 1) in a periodic box; one pass of: neighbour
build, number density, Laplacian (xu-jin, wf2) of a vector field, pgm1.  Prints the best wall
time and the CPU time of each piece (CPU time is the honest figure on a shared machine: it sums
all threads, so wall ~ CPU / threads when the cores are free).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numba
import numpy as np

from mpsbench.physics import operators as ops
from mpsbench.physics.gradients import get_gradient
from mpsbench.physics.laplacians import get_laplacian
from mpsbench.physics.neighbours import build_pairs
from mpsbench.physics.particles import Box
from mpsbench.physics.weights import get_weight

from . import cells, formulas, geometry, kernels


def _time(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """(best wall, best CPU) in ms over ``repeat`` calls after one warm-up call."""
    fn()
    walls, cpus = [], []
    for _ in range(repeat):
        c0, w0 = time.process_time(), time.perf_counter()
        fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return 1e3 * min(walls), 1e3 * min(cpus)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=200)
    ap.add_argument("--re", type=float, default=3.1, help="r_e / l0")
    ap.add_argument("--skin", type=float, default=0.0, help="neighbour skin / l0")
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--threads", type=int, default=None)
    ns = ap.parse_args(argv)
    if ns.threads:
        numba.set_num_threads(ns.threads)

    side, re = ns.side, ns.re
    rng = np.random.default_rng(1)
    ix, iy = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    pos = np.column_stack([ix.ravel() + 0.5, iy.ravel() + 0.5])
    pos += rng.uniform(-0.05, 0.05, pos.shape)
    box = Box((0.0, 0.0), (float(side), float(side)), (True, True))
    n = len(pos)
    period = geometry.box_period(box)
    wf = get_weight("wf2")
    n0, lam = ops.lattice_constants(wf, re, 1.0)
    lap = get_laplacian("xu-jin")
    pgm1 = get_gradient("pgm1")
    fm = formulas.compile_models(wf, lap, pgm1)
    pref = lap.prefactor(n0, lam)
    k_density = kernels.number_density(fm.weight)
    k_laplacian = kernels.laplacian_field(fm.weight, fm.laplacian)
    k_pmin = kernels.neighbour_min(fm.weight)
    k_pgm1 = kernels.pressure_gradient(fm.weight, fm.gradient)
    all_rows = np.zeros(0, dtype=np.bool_)
    u = rng.normal(size=(n, 2))
    p = np.abs(rng.normal(size=n))
    mask = np.ones(n, bool)
    nd, lv, g, rows = np.empty(n), np.empty((n, 2)), np.empty((n, 2)), np.empty(n)
    pmin = np.empty(n)
    cutoff = re + ns.skin
    state = {"csr": cells.build_csr(pos, cutoff, box)}

    def build() -> None:
        state["csr"] = cells.build_csr(pos, cutoff, box)

    def density() -> None:
        c = state["csr"]
        k_density(c.offsets, c.nbr, pos, period, re, nd)

    def laplacian() -> None:
        c = state["csr"]
        k_laplacian(c.offsets, c.nbr, pos, period, u, re, pref, kernels.NO_MOMENT, ops.DIM / n0,
                    False, lv, rows, all_rows)

    def pressure() -> None:
        c = state["csr"]
        k_pmin(c.offsets, c.nbr, pos, period, p, mask, re, pmin)
        k_pgm1(c.offsets, c.nbr, pos, period, p, pmin, mask, re, pgm1.prefactor(n0), g, all_rows)

    def numba_pass() -> None:
        build()
        density()
        laplacian()
        pressure()

    def numpy_pass() -> None:
        pl = build_pairs(pos, re, box)
        w = wf.w(pl.r, re)
        ops.number_density(pl, w)
        lap.apply(pl, u, wf, re, n0, lam)
        pgm1(pl, p, w, n0)

    entries = len(state["csr"].nbr) / n
    print(
        f"N = {n}, r_e = {re} l0, cut-off = {cutoff} l0 ({entries:.1f} entries per particle), "
        f"numba threads = {numba.get_num_threads()}"
    )
    table = [
        ("numba: cell-list build (CSR)", build),
        ("numba: number density", density),
        ("numba: Laplacian (vector) + row sums", laplacian),
        ("numba: pgm1", pressure),
        ("numba: whole pass", numba_pass),
        ("numpy: build_pairs + the same three", numpy_pass),
    ]
    print(f"{'':38s} {'wall ms':>9s} {'CPU ms':>9s}")
    for name, fn in table:
        wall, cpu = _time(fn, ns.repeat if "numpy" not in name else max(3, ns.repeat // 3))
        print(f"{name:38s} {wall:9.2f} {cpu:9.2f}")


if __name__ == "__main__":
    main()
