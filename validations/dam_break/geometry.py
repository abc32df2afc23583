"""The two dam-break geometries (Koshizuka & Oka 1996, Lobovsky et al. 2014; docs/method.md).

Kept apart from :mod:`.case` so that the analysis and the figures can name a geometry without
importing the case definition (which imports them lazily: a module of its own keeps the
imports one way).
"""

from __future__ import annotations

from dataclasses import dataclass

G = 9.81


@dataclass(frozen=True)
class Geometry:
    """Column L x H [m] at the back wall of a tank W [m] long with side walls wall_height [m].

    ``collision``: whether every tier runs this geometry with the collision model, i.e. whether
    it belongs to the variants' own models there (the tiers and the analysis read it)."""

    column_width: float
    column_height: float
    tank_length: float
    wall_height: float
    collision: bool = False


GEOMETRIES = {
    "koshizuka-oka": Geometry(0.146, 0.292, 0.584, 0.45),
    # a close spray pair ends some runs without the collision model (the case's docstring)
    "lobovsky": Geometry(0.6, 0.3, 1.61, 0.6, collision=True),
}
