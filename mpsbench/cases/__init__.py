"""Validation cases: parameters, tiers, the :class:`Case` base class and the case registry.

The definitions live in :mod:`mpsbench.cases.case`; they are re-exported here because a plugin
author writes ``from mpsbench.cases import Case, Param``.
"""

from .case import CASES, TIERS, Case, CaseCheck, CaseRun, Grid, Param, case_order, get_case

__all__ = ["CASES", "TIERS", "Case", "CaseCheck", "CaseRun", "Grid", "Param", "case_order",
           "get_case"]
