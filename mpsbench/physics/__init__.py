"""Physics: particles, weighting functions, neighbour lists, the MPS operators and models,
boundary treatments and the problem configuration.  Nothing here knows a solver, a case or a
report."""
