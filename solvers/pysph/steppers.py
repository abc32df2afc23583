"""PySPH integrator steps of this backend (imports PySPH: load only when it is installed).

PySPH turns an ``IntegratorStep``'s methods into C++ from their source text: no comments or
annotations on their ``def`` lines (a ``# type: ignore`` there breaks the translation).
"""

from pysph.sph.integrator_step import IntegratorStep


class MovingWallStep(IntegratorStep):
    """Boundary particles moving at their own (u, v): EDAC has no stepper for solids."""

    def initialize(self, d_idx, d_x0, d_y0, d_x, d_y):
        d_x0[d_idx] = d_x[d_idx]
        d_y0[d_idx] = d_y[d_idx]

    def stage1(self, d_idx, d_x0, d_y0, d_x, d_y, d_u, d_v, dt):
        d_x[d_idx] = d_x0[d_idx] + 0.5 * dt * d_u[d_idx]
        d_y[d_idx] = d_y0[d_idx] + 0.5 * dt * d_v[d_idx]

    def stage2(self, d_idx, d_x0, d_y0, d_x, d_y, d_u, d_v, dt):
        d_x[d_idx] = d_x0[d_idx] + dt * d_u[d_idx]
        d_y[d_idx] = d_y0[d_idx] + dt * d_v[d_idx]
