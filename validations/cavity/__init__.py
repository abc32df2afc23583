"""Lid-driven cavity; Ghia, Ghia & Shin's (1982) centreline velocities load from ``reference``."""
