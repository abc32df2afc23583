"""Decaying 2-D Taylor-Green vortex on a periodic square; its exact fields are in ``reference``."""
