"""Sub-commands of the ``mpsbench`` CLI, one module each (see :mod:`mpsbench.cli`)."""
