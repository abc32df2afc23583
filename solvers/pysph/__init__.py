"""PySPH (https://pysph.readthedocs.io) behind the Solver protocol: ``pysph-wcsph`` and
``pysph-edac`` (an optional extra: ``pip install "mpsbench[pysph]"``).

Importing this package without PySPH raises ImportError with the install command, so the
registry lists both backends as unavailable with that reason (``mpsbench solvers``).
"""

from __future__ import annotations

import importlib.util

INSTALL_HINT = ('pip install "mpsbench[pysph]" (PySPH 1.0b2 builds from its source in about '
                "8 minutes; it needs a C++ compiler with OpenMP, at run time too)")

if importlib.util.find_spec("pysph") is None or importlib.util.find_spec("compyle") is None:
    raise ImportError(f"PySPH is not installed: {INSTALL_HINT}")

from .solver import PySPHEDAC, PySPHSolver, PySPHWCSPH  # noqa: E402

__all__ = ["INSTALL_HINT", "PySPHEDAC", "PySPHSolver", "PySPHWCSPH"]
