"""Small problems for the conformance kit and the backend tests (a few hundred particles each).

Every builder is deterministic (seeded jitter and velocities) and returns a fresh
:class:`~mpsbench.run.protocol.Problem`, so two calls give bitwise identical inputs.  Units are SI;
the defaults describe water-like particles at l0 = 1 cm.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mpsbench.physics.config import (
    DiffusionPhysics,
    FlowPhysics,
    Inflow,
    Models,
    Region,
    TimeStepping,
    WallMotion,
)
from mpsbench.physics.operators import lattice_pairs
from mpsbench.physics.particles import Box, Particles, block, jitter, tank, wall_layers
from mpsbench.run.protocol import Problem

G = 9.81  # m/s^2


def periodic_lattice(
    n_side: int = 12,
    l0: float = 0.01,
    amplitude: float = 0.0,
    seed: int = 0,
    squeeze: float = 1.0,
) -> tuple[Particles, Box]:
    """A fully periodic ``n_side`` x ``n_side`` fluid lattice, optionally jittered.

    ``amplitude`` is the jitter half-width as a fraction of ``l0``; ``squeeze`` < 1 puts the
    particles ``squeeze * l0`` apart (a uniformly compressed fluid when n0 comes from the ideal
    lattice of spacing l0).
    """
    pos, box = lattice_pairs(n_side, squeeze * l0)
    p = Particles.from_positions(pos)
    if amplitude:
        jitter(p, amplitude * l0, seed)
        box.wrap(p.pos)
    return p, box


def diffusion_problem(
    laplacian: str = "xu-jin",
    weight: str = "wf2",
    *,
    n_side: int = 12,
    l0: float | None = None,
    amplitude: float = 0.1,
    seed: int = 1,
    value: float | None = 3.7,
    kappa: float = 1.0,
    re_ratio: float = 3.1,
    gradient_correction: bool = False,
    dt: float | None = None,
) -> Problem:
    """Scalar diffusion on a (jittered) periodic unit square.

    ``value`` set: a uniform field of that value; ``value=None``: sin(2 pi x) sin(2 pi y).
    ``l0`` defaults to 1 / ``n_side`` (the unit square).
    """
    l0 = 1.0 / n_side if l0 is None else l0
    p, box = periodic_lattice(n_side, l0, amplitude, seed)
    if value is None:
        x, y = p.pos[:, 0], p.pos[:, 1]
        p.fields["phi"] = np.sin(2 * np.pi * x) * np.sin(2 * np.pi * y)
    else:
        p.fields["phi"] = np.full(p.n, float(value))
    models = Models(
        weight=weight,
        laplacian=laplacian,
        re_ratio=re_ratio,
        gradient_correction=gradient_correction,
        n0_from="lattice" if amplitude else "initial",
    )
    return Problem(
        p, box, l0, DiffusionPhysics(kappa=kappa), models, TimeStepping(dt=dt), name="diffusion"
    )


def periodic_flow_problem(
    *,
    n_side: int = 12,
    l0: float = 0.01,
    amplitude: float = 0.1,
    seed: int = 2,
    velocity: float = 0.0,
    squeeze: float = 1.0,
    models: Models | None = None,
    dt: float | None = None,
    **physics: Any,
) -> Problem:
    """WC-MPS flow of a (jittered) fluid filling a fully periodic box, no gravity by default.

    ``squeeze``: see :func:`periodic_lattice`.

    ``velocity`` > 0 gives every particle a seeded random velocity with components uniform in
    [-velocity, velocity] plus a uniform drift (velocity/2, -velocity/4), so the total momentum
    is not zero.  ``physics`` overrides :class:`~mpsbench.physics.config.FlowPhysics` fields.
    """
    p, box = periodic_lattice(n_side, l0, amplitude, seed, squeeze)
    if velocity:
        rng = np.random.default_rng(seed + 1000)
        p.vel[:] = rng.uniform(-velocity, velocity, size=(p.n, 2))
        p.vel += (0.5 * velocity, -0.25 * velocity)
    if models is None:
        models = Models(n0_from="lattice" if amplitude else "initial")
    ph = FlowPhysics(**{"gravity": (0.0, 0.0), "nu": 1.0e-6, "c0": 10.0, **physics})
    return Problem(p, box, l0, ph, models, TimeStepping(dt=dt), name="periodic-flow")


def column_in_tank_problem(
    *,
    nx: int = 8,
    ny: int = 12,
    l0: float = 0.01,
    width_cells: int = 20,
    models: Models | None = None,
    dt: float | None = None,
    **physics: Any,
) -> Problem:
    """A small dam break: an ``nx`` x ``ny`` water column in the left corner of an open tank.

    c0 = 10 sqrt(2 g H) with H the column height.  The box reaches 3 H above the tank walls
    so splashes do not count as leaving the domain.
    """
    width = width_cells * l0
    height = ny * l0
    fluid = block(0.0, 0.0, nx, ny, l0)
    walls = tank(width, 1.5 * height, l0)
    p = Particles.concat([fluid, walls])
    c0 = 10.0 * math.sqrt(2.0 * G * height)
    ph = FlowPhysics(**{"c0": c0, "gravity": (0.0, -G), **physics})
    ext = 5.0 * l0
    box = Box((-ext, -ext), (width + ext, 4.0 * height))
    return Problem(p, box, l0, ph, models or Models(), TimeStepping(dt=dt), name="column-in-tank")


def dam_break_problem(
    *,
    l0: float = 0.01,
    column: tuple[float, float] = (0.146, 0.292),
    tank_length: float = 0.584,
    box_top: float = 1.0,
    models: Models | None = None,
    dt: float | None = None,
    **physics: Any,
) -> Problem:
    """The Koshizuka & Oka dam break: a column L x H in a tank ``tank_length`` long.

    Particle counts are rounded to whole cells of ``l0``.  c0 = 10 sqrt(2 g H); default
    models: WF2, PGM1, r_e = 2.1 l0 (3.1 l0 for the Laplacian), the ``xu-jin`` Laplacian.
    """
    nx = int(round(column[0] / l0))
    ny = int(round(column[1] / l0))
    fluid = block(0.0, 0.0, nx, ny, l0)
    walls = tank(tank_length, 0.6, l0)
    p = Particles.concat([fluid, walls])
    c0 = 10.0 * math.sqrt(2.0 * G * column[1])
    ph = FlowPhysics(**{"c0": c0, "gravity": (0.0, -G), **physics})
    if models is None:
        models = Models(
            weight="wf2",
            laplacian="xu-jin",
            gradient="pgm1",
            re_ratio=2.1,
            re_ratio_laplacian=3.1,
        )
    ext = 5.0 * l0
    box = Box((-ext, -ext), (tank_length + ext, box_top))
    return Problem(p, box, l0, ph, models, TimeStepping(dt=dt), name="dam-break")


def channel_problem(
    *,
    nx: int = 12,
    ny: int = 8,
    l0: float = 0.01,
    top_velocity: tuple[float, float] | None = None,
    sliding: bool = False,
    models: Models | None = None,
    dt: float | None = None,
    **physics: Any,
) -> Problem:
    """An x-periodic channel of ``ny`` fluid rows between a floor and a lid (no gravity).

    With ``top_velocity`` the lid rows carry ``wall_tag`` 1 and a
    :class:`~mpsbench.physics.config.WallMotion` moves them (Couette flow); with ``sliding``
    they carry that velocity in place (``displace=False``).
    """
    length = nx * l0
    height = ny * l0
    fluid = block(0.0, 0.0, nx, ny, l0)
    floor = wall_layers(0.0, length, 0.0, l0, side="below")
    lid = wall_layers(0.0, length, height, l0, side="above")
    floor.fields["wall_tag"] = np.zeros(floor.n)
    lid.fields["wall_tag"] = np.ones(lid.n)
    fluid.fields["wall_tag"] = np.full(fluid.n, -1.0)
    p = Particles.concat([fluid, floor, lid])
    ph = FlowPhysics(**{"gravity": (0.0, 0.0), "nu": 1.0e-6, "c0": 1.0, **physics})
    motions = () if top_velocity is None else (
        WallMotion(1, top_velocity, displace=not sliding),)
    box = Box((0.0, -5.0 * l0), (length, height + 5.0 * l0), (True, False))
    return Problem(
        p,
        box,
        l0,
        ph,
        models or Models(),
        TimeStepping(dt=dt),
        wall_motions=motions,
        name="channel",
    )


def open_channel_problem(
    *,
    nx: int = 20,
    ny: int = 6,
    l0: float = 0.01,
    speed: float = 0.1,
    models: Models | None = None,
    dt: float | None = None,
    **physics: Any,
) -> Problem:
    """Fluid entering at x = 0 with ``speed`` and leaving through an outflow region at the end.

    A floor and a lid bound the channel; no gravity.  The outflow region starts at x = nx l0.
    """
    length = nx * l0
    height = ny * l0
    fluid = block(0.0, 0.0, nx, ny, l0)
    fluid.vel[:, 0] = speed
    ext = 8 * l0  # walls extend upstream under the reservoir and downstream past the outlet
    floor = wall_layers(-ext, length + ext, 0.0, l0, side="below")
    lid = wall_layers(-ext, length + ext, height, l0, side="above")
    p = Particles.concat([fluid, floor, lid])
    ph = FlowPhysics(**{"gravity": (0.0, 0.0), "nu": 1.0e-6, "c0": 20.0 * speed, **physics})
    inflow = Inflow(start=(0.0, 0.0), end=(0.0, height), velocity=(speed, 0.0), layers=4)
    outflow = Region((length, -l0), (length + ext, height + l0))
    box = Box((-ext - 2 * l0, -6 * l0), (length + ext + 2 * l0, height + 6 * l0))
    return Problem(
        p,
        box,
        l0,
        ph,
        models or Models(),
        TimeStepping(dt=dt),
        inflow=inflow,
        outflows=(outflow,),
        name="open-channel",
    )
