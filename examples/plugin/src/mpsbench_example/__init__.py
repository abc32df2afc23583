"""Example mpsbench plugin: the ``ko-local`` Laplacian and the ``example`` solver.

Nothing here registers itself on import: mpsbench finds both through the entry points declared
in this package's ``pyproject.toml`` and imports them on first use.
"""

__version__ = "0.1.0"
