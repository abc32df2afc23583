"""Sparse linear solvers for the semi-implicit scheme, with what each solve cost.

:class:`LinearSolver` solves M x = y for the PPE (M symmetric positive definite for the built-in
Laplacians, docs/method.md section 10) and for backward-Euler diffusion, and returns a
:class:`SolveStats`: iterations, the true relative residual ||y - M x|| / ||y||, whether the
tolerance was met, and the set-up and solve times.

Methods (``method``):

* ``cg``: scipy's conjugate gradients; a matrix that is not symmetric (the gradient-corrected
  Laplacian, a plugin model with asymmetric coefficients) goes to BiCGSTAB instead, and the
  stats say so.  Preconditioner ``jacobi`` (the diagonal, default) or ``none``.
* ``bicgstab``: scipy's BiCGSTAB for any matrix; preconditioner ``jacobi``, ``ilu``
  (scipy's incomplete LU) or ``none``.
* ``pyamg``: smoothed-aggregation algebraic multigrid (the optional ``pyamg`` package, extra
  ``mpsbench[pyamg]``) as the preconditioner of CG (BiCGSTAB when not symmetric).
* ``direct``: scipy's sparse LU (an exact solve: tests and small problems).

A solve that does not reach the tolerance raises :class:`NotConverged`: the run is recorded as
failed with the iteration count and residual, never continued on a wrong pressure.

BLAS threads (``blas_threads``, default 1): the Krylov loops are dot products and vector updates
on vectors of 10^4-10^5 entries, which OpenBLAS spreads over its threads; on a shared 2-core
machine (load 7-10) that made a 33k-unknown CG solve ten times slower (2.5 s against 25-31 s,
tests/benchmarks/test_bench_implicit.py at 40k particles).  The solves run inside
``threadpoolctl.threadpool_limits`` with that many threads (0: the library's own setting).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

METHODS = ("cg", "bicgstab", "pyamg", "direct")
PRECONDITIONERS = ("jacobi", "ilu", "none")


class NotConverged(RuntimeError):
    """The linear solve did not reach its tolerance."""


@dataclass(frozen=True)
class SolveStats:
    """One solve: ``method`` actually used (``cg`` may report ``bicgstab``), ``iterations``,
    ``residual`` = ||y - M x|| / ||y|| (0 for y = 0), ``tol``, ``converged``, ``unknowns``,
    ``setup_s`` (preconditioner or hierarchy) and ``solve_s`` [s], ``floor``: the round-off
    floor 100 eps ||M||_inf ||x|| / ||y|| of the residual (converged: residual <= max(10 tol,
    floor))."""

    method: str
    iterations: int
    residual: float
    tol: float
    converged: bool
    unknowns: int
    setup_s: float
    solve_s: float
    floor: float = 0.0


def _norm_inf(m: sp.csr_matrix) -> float:
    """max_i sum_j |m_ij| (an upper bound of ||M||_2 for a symmetric M)."""
    return float(abs(m).sum(axis=1).max()) if m.nnz else 0.0


def pyamg_available() -> bool:
    try:
        import pyamg  # noqa: F401
    except ImportError:
        return False
    return True


class LinearSolver:
    """M x = y with one of :data:`METHODS` (module docstring).

    ``tol``: relative residual; ``max_iterations``: 0 = max(1000, 10 x unknowns).
    ``reuse``: keep the preconditioner while the same matrix object comes back (backward-Euler
    diffusion with a fixed dt); the PPE matrix changes every step and is set up each time.
    """

    def __init__(self, method: str = "cg", preconditioner: str = "jacobi", tol: float = 1e-8,
                 max_iterations: int = 0, blas_threads: int = 1) -> None:
        if method not in METHODS:
            raise ValueError(f"linear_solver = {method!r} is not allowed: one of "
                             f"{', '.join(METHODS)}")
        if preconditioner not in PRECONDITIONERS:
            raise ValueError(f"preconditioner = {preconditioner!r} is not allowed: one of "
                             f"{', '.join(PRECONDITIONERS)}")
        if method == "cg" and preconditioner == "ilu":
            raise ValueError("preconditioner = 'ilu' is not allowed with linear_solver = 'cg': "
                             "incomplete LU is not symmetric (use jacobi, or bicgstab)")
        if method == "pyamg" and not pyamg_available():
            raise ValueError("linear_solver = 'pyamg' needs the pyamg package: "
                             "pip install 'mpsbench[pyamg]'")
        if not (0 < tol < 1):
            raise ValueError(f"tol = {tol!r} is not allowed: a number in (0, 1)")
        self.method = method
        self.preconditioner = preconditioner
        self.tol = float(tol)
        self.max_iterations = int(max_iterations)
        if not (isinstance(blas_threads, int) and blas_threads >= 0):
            raise ValueError(f"blas_threads = {blas_threads!r} is not allowed: an integer >= 0")
        self.blas_threads = blas_threads
        self._cached: tuple[Any, Any] | None = None  # (matrix, preconditioner or hierarchy)

    def solve(self, m: sp.csr_matrix, y: FloatArray, symmetric: bool,
              x0: FloatArray | None = None, reuse: bool = False) -> tuple[FloatArray, SolveStats]:
        if not self.blas_threads:
            return self._solve(m, y, symmetric, x0, reuse)
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=self.blas_threads, user_api="blas"):
            return self._solve(m, y, symmetric, x0, reuse)

    def _solve(self, m: sp.csr_matrix, y: FloatArray, symmetric: bool,
               x0: FloatArray | None, reuse: bool) -> tuple[FloatArray, SolveStats]:
        n = len(y)
        norm_y = float(np.linalg.norm(y))
        if n == 0 or norm_y == 0.0:
            return np.zeros(n), SolveStats(self.method, 0, 0.0, self.tol, True, n, 0.0, 0.0)
        maxiter = self.max_iterations or max(1000, 10 * n)
        t_check = time.perf_counter()
        check_s = 0.0
        if x0 is not None:
            # a start already within the tolerance (or at the round-off floor) is the answer:
            # iterating on round-off would only add noise to it
            r0 = float(np.linalg.norm(y - m @ x0)) / norm_y
            floor0 = self._floor(m, x0, norm_y)
            if r0 <= max(self.tol, floor0):
                return np.array(x0, float), SolveStats(self.method, 0, r0, self.tol, True, n,
                                                       0.0, time.perf_counter() - t_check,
                                                       floor0)
            check_s = time.perf_counter() - t_check
        t0 = time.perf_counter()
        method = self.method
        if method == "cg" and not symmetric:
            method = "bicgstab"
        prec = self._setup(m, method, symmetric, reuse)
        t1 = time.perf_counter()
        iterations = 0

        def count(_: Any) -> None:
            nonlocal iterations
            iterations += 1

        if method == "direct":
            x = np.asarray(prec.solve(y) if prec is not None else spla.spsolve(m.tocsc(), y))
        elif method == "pyamg":
            res: list[float] = []
            x = prec.solve(y, x0=x0, tol=self.tol, maxiter=maxiter,
                           accel="cg" if symmetric else "bicgstab", residuals=res)
            iterations = max(len(res) - 1, 0)
            method = "pyamg-cg" if symmetric else "pyamg-bicgstab"
        else:
            krylov = spla.cg if method == "cg" else spla.bicgstab
            x, _info = krylov(m, y, x0=x0, rtol=self.tol, atol=0.0, maxiter=maxiter, M=prec,
                              callback=count)
        t2 = time.perf_counter()
        residual = float(np.linalg.norm(y - m @ x)) / norm_y
        # Krylov methods test their recursive residual; allow the true one a little slack.  No
        # x in floating point has a true residual below about eps ||M|| ||x|| / ||y|| (the
        # backward-error floor): an ill-conditioned system (a closed group whose level is set by
        # the tiny quasi-compressibility term) reaching that floor has converged as far as any
        # method can, and counts as converged.
        floor = self._floor(m, x, norm_y)
        converged = bool(residual <= max(10.0 * self.tol, floor))
        stats = SolveStats(method, iterations, residual, self.tol, converged, n, t1 - t0,
                           check_s + t2 - t1, floor)
        return np.asarray(x, float), stats

    @staticmethod
    def _floor(m: sp.csr_matrix, x: FloatArray, norm_y: float) -> float:
        return 100.0 * float(np.finfo(float).eps) * _norm_inf(m) * float(np.linalg.norm(x)) / norm_y

    def _setup(self, m: sp.csr_matrix, method: str, symmetric: bool, reuse: bool) -> Any:
        if reuse and self._cached is not None and self._cached[0] is m:
            return self._cached[1]
        prec: Any = None
        if method == "direct":
            prec = spla.splu(m.tocsc()) if reuse else None
        elif method == "pyamg":
            import pyamg

            prec = pyamg.smoothed_aggregation_solver(
                m, symmetry="symmetric" if symmetric else "nonsymmetric")
        elif self.preconditioner == "jacobi":
            d = m.diagonal()
            inv = np.divide(1.0, d, out=np.ones_like(d), where=d != 0)
            prec = sp.diags(inv)
        elif self.preconditioner == "ilu":
            ilu = spla.spilu(m.tocsc(), drop_tol=1e-4, fill_factor=10)
            prec = spla.LinearOperator(m.shape, ilu.solve)
        if reuse:
            self._cached = (m, prec)
        return prec
