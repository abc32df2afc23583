"""The water-jet case's parameters (defaults, units, allowed values), apart from the case so
that its tables can name them without importing the case (no import cycle)."""

from __future__ import annotations

from mpsbench.cases import Param
from mpsbench.cases import analysis as an

B, L0_COARSE, L0_FINE, L0_FINEST = 0.1, 0.01, 0.005, 0.0025  # default b; l0 = b/10, 20, 40

PARAMS = (
    Param("b", B, "jet width", "m", minimum=0.0, exclusive_minimum=True),
    Param("U", 1.0, "jet speed", "m/s", minimum=0.0, exclusive_minimum=True),
    Param("nozzle_gap", 2.0, "nozzle (inlet line) height above the plate", "b", minimum=1.0),
    Param("plate_length", 6.0, "plate length (centred on the jet)", "b", minimum=6.0),
    Param("l0", L0_FINE, "particle spacing (b/l0 must be a whole number)", "m",
          minimum=0.0, exclusive_minimum=True),
    Param("gradient", "pgm1", "pressure-gradient model", kind=str,
          choices=an.gradient_names()),
    Param("stabilization", True, "stabilization (docs/method.md 5) on/off", kind=bool),
    Param("alpha_s", 0.01, "stabilization coefficient", "", minimum=0.0, maximum=1.0),
    Param("stabilization_walls", True,
          "wall and dummy particles are neighbours in the stabilization sum", kind=bool),
    Param("collision_distance", 0.0, "collision distance alpha_c (0 = no collision model)",
          "l0", minimum=0.0, maximum=0.99),
    Param("weight", "wf2", "weighting function", kind=str, choices=an.weight_names()),
    Param("laplacian", "xu-jin", "Laplacian model (viscous term)", kind=str,
          choices=an.laplacian_names()),
    Param("re_ratio", 2.1, "r_e / l0", "", minimum=1.0, maximum=10.0),
    Param("c0_ratio", 10.0, "sound speed c0 / U", "", minimum=1.0),
    Param("cfl", 0.2, "Courant number of dt = cfl l0 / (c0 + |u|max)", "",
          minimum=0.0, exclusive_minimum=True, maximum=1.0),
    Param("t_end", 7.0, "end time", "b/U", minimum=0.0, exclusive_minimum=True),
    Param("t_window", 3.0, "averaging window before t_end", "b/U",
          minimum=0.0, exclusive_minimum=True),
)
