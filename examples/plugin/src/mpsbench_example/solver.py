"""``example``: a solver backend that wraps mpsbench's reference backend and runs ko-local.

It shows the protocol a backend implements.  :class:`~mpsbench.run.protocol.SolverBase` keeps the
bookkeeping (time, step count, status, counters) and checks the declared capabilities in
``setup``; a backend supplies ``_setup``, ``_advance``, ``stable_dt`` and ``state``.  Here each
of them hands over to a ReferenceSolver, as a wrapper around an external code would.

The capabilities say this backend runs only the ``ko-local`` Laplacian: a problem asking for
another one is refused with the reason (``UnsupportedProblem``), and the conformance kit picks
ko-local for its checks.
"""

from __future__ import annotations

import dataclasses

from mpsbench.solvers.reference import ReferenceSolver

from mpsbench.run.protocol import Capabilities, SolverBase


class ExampleSolver(SolverBase):
    """The reference WC-MPS / diffusion backend restricted to the ko-local Laplacian."""

    name = "example"
    version = "0.1.0"
    capabilities: Capabilities = dataclasses.replace(
        ReferenceSolver.capabilities, laplacians=frozenset({"ko-local"})
    )

    def __init__(self) -> None:
        super().__init__()
        self._inner = ReferenceSolver()

    def _setup(self, problem):
        self._inner.setup(problem)

    def _advance(self, dt):
        self._inner.time = self.time  # the runner may round our clock onto an event time
        self._inner.step(dt)
        self.counters["neighbour_builds"] = self._inner.counters.get("neighbour_builds", 0.0)

    def stable_dt(self):
        """The largest stable time step [s], as the reference backend computes it."""
        return self._inner.stable_dt()

    def state(self):
        """The current particles (a view)."""
        return self._inner.state()

    def diagnostics(self):
        return self._inner.diagnostics()
