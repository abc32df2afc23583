"""Validation cases (installed as ``mpsbench.validations``), reached through the case registry."""
