"""The semi-implicit backend: MPS with a pressure Poisson equation, numpy + scipy.sparse.

The scheme (the PPE step, backward-Euler diffusion, the time step without sound speed, what each
linear solve records) is :class:`mpsbench.run.implicit_scheme.SemiImplicitScheme`; the pieces of
the step it shares with WC-MPS (neighbour list, viscous term, predictor, pressure gradient,
collision, stabilization, moves, open boundaries) are the reference backend's numpy hooks
(:class:`mpsbench.solvers.reference.ReferenceSolver`), so the two backends differ in step 3
alone.  This module adds the hooks of the PPE: the chosen Laplacian as a scipy.sparse matrix over
the particles that carry a pressure, the velocity divergence and the neighbour offset.

Options (a spec such as ``implicit:source=mixed,linear_solver=pyamg``): the PPE source, the
relaxation weight of the mixed source, the free-surface rule, the linear solver, its
preconditioner, tolerance and iteration cap, and where the quasi-compressibility term applies
(docs/method.md section 10).  Physics options (clipping, beta, collision, stabilization, the
viscous wall treatment) come from the problem as for every backend.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpsbench.solvers.reference import ReferenceSolver
from numpy.typing import NDArray

from mpsbench.params import Option
from mpsbench.physics.neighbours import PairList
from mpsbench.physics.operators import divergence
from mpsbench.physics.ppe import COMPRESSIBILITY, SOURCES, SURFACE_RULES, neighbour_offset
from mpsbench.physics.weights import within_support
from mpsbench.run.implicit_scheme import SemiImplicitScheme
from mpsbench.run.linsolve import METHODS, PRECONDITIONERS
from mpsbench.run.protocol import Capabilities
from mpsbench.run.scheme import SCHEME_BOUNDARIES, SCHEME_FEATURES

FloatArray = NDArray[np.float64]


class ImplicitSolver(SemiImplicitScheme, ReferenceSolver):
    """Semi-implicit MPS (PPE) and backward-Euler diffusion on the reference's pair lists."""

    name = "implicit"
    version = "1.0"
    capabilities = Capabilities(scheme="semi-implicit", boundaries=SCHEME_BOUNDARIES,
                                features=SCHEME_FEATURES)
    bench_default = False  # `mpsbench bench` times it only when asked (--solver implicit)
    options = (
        Option("source", "density", "PPE source: density (n* - n0), divergence (div u*), "
               "mixed (divergence + relaxation x density)", kind=str, choices=SOURCES),
        Option("relaxation", 0.01, "gamma of the mixed source (Tanaka & Masunaga 2010)",
               minimum=0.0, maximum=1.0),
        Option("density_relaxation", 0.2, "alpha of the density source (1: Koshizuka & Oka "
               "1996; 0.2 as MPS-Basic)", minimum=0.0, exclusive_minimum=True, maximum=1.0),
        Option("surface", "density", "free-surface rule: density (n* < beta n0) or "
               "distribution (and an off-centre neighbourhood)", kind=str, choices=SURFACE_RULES),
        Option("surface_offset", 0.2, "neighbour offset [l0] above which a fluid particle "
               "with n* < beta n0 is on the surface (rule distribution)", minimum=0.0),
        Option("linear_solver", "cg", "cg (BiCGSTAB when the matrix is not symmetric), "
               "bicgstab, pyamg (extra mpsbench[pyamg]) or direct", kind=str, choices=METHODS),
        Option("preconditioner", "jacobi", "of cg / bicgstab: jacobi, ilu (bicgstab only) or "
               "none", kind=str, choices=PRECONDITIONERS),
        Option("tol", 1e-8, "relative residual of the linear solve", minimum=0.0,
               exclusive_minimum=True, maximum=0.1),
        Option("max_iterations", 0, "iteration cap; 0: max(1000, 10 x unknowns)", kind=int,
               minimum=0),
        Option("compressibility", "closed", "where the quasi-compressibility 1/(c0 dt)^2 "
               "enters: closed (groups without a free surface) or all", kind=str,
               choices=COMPRESSIBILITY),
        Option("blas_threads", 1, "BLAS threads of the linear solves (0: the library's "
               "default; on a shared machine more threads made CG slower)", kind=int, minimum=0),
    )

    def _pressure_pairs(self) -> PairList:
        """The current pairs within r_e,lap without a dummy particle."""
        pairs = self.pairs
        keep = self.neigh.no_dummy & within_support(pairs.r, self.re_lap)
        return PairList(pairs.i[keep], pairs.j[keep], pairs.dx[keep], pairs.r[keep], pairs.n,
                        self.re_lap)

    def _ppe_laplacian(self) -> sp.csr_matrix:
        lap = self.laplacian.matrix(self._pressure_pairs(), self.weight, self.re_lap,
                                    self.n0_lap, self.lam)
        lap.eliminate_zeros()
        return lap

    def _divergence(self) -> FloatArray:
        # Pairs of a dummy particle with a boundary particle moving rigidly with it are not in
        # the list (solvers/reference/neighbours.py): their velocity difference is zero.
        return divergence(self.pairs, self.p.vel, self._w, self.n0)

    def _neighbour_offset(self) -> FloatArray:
        pairs = self.pairs
        moment = pairs.sum_vec_antisym(self._w[:, None] * pairs.dx)
        return neighbour_offset(moment, self.number_density)

    def _diffusion_matrix(self) -> sp.csr_matrix:
        return self.matrix
