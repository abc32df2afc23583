"""Built-in solver backends (installed as ``mpsbench.solvers``), reached through the registry."""
