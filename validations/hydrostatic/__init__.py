"""Hydrostatic water column at rest: the case's reference solution lives in ``reference``."""
