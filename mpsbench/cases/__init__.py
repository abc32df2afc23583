"""Validation cases: parameters, tiers, the :class:`Case` base class and the case registry.

The definitions live in :mod:`mpsbench.cases.case` (cases), :mod:`.checks` (gates and claims),
:mod:`.refinement` and :mod:`.uncertainty` (numerical and validation uncertainty),
:mod:`.analysis` (record frames, selection, pivots, orders, bounds, formatting) and
:mod:`.plotting` (figure helpers); the names a case author needs are re-exported here
(``from mpsbench.cases import Case, Param``; ``Refinement`` comes from
:mod:`.refinement`, which imports pandas).
"""

from .case import CASES, TIERS, Case, CaseRun, Grid, Param, RefinementGrid, case_order, get_case
from .checks import CLAIM, GATE, CaseCheck, Claim

__all__ = ["CASES", "CLAIM", "GATE", "TIERS", "Case", "CaseCheck", "CaseRun", "Claim", "Grid",
           "Param", "RefinementGrid", "case_order", "get_case"]
