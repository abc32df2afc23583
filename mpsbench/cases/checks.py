"""Gates and claims: the two kinds of decision a case makes (docs/method.md section 8).

A *gate* decides the exit status of ``mpsbench validate``: an analytic or tabulated reference
reproduced by the recommended configuration, the harness's own oracles, convergence where
theory predicts it.  ``passed`` is True / False, or None when the study lacks the runs.

A *claim* is a statement of a paper tested as a hypothesis: ``passed`` True means supported,
False refuted, None inconclusive.  It carries the claim's id and source, the ``rule`` that
decided it (metric, threshold, which runs) and the evidence (``detail``: the numbers, with
their uncertainty).  A refuted claim is a finding and never changes the exit status unless
``--strict-claims`` is given.

Comparisons inside a rule respect the numerical uncertainty u_num
(:mod:`mpsbench.cases.uncertainty`): :func:`below` and :func:`less` answer True or False only
when the margin exceeds the uncertainty and None (undecided) otherwise; :func:`decide` turns a
rule's comparisons into a verdict: refuted when one goes against the claim, supported when all
go its way, inconclusive otherwise (undecided comparisons, or no data).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

GATE = "gate"
CLAIM = "claim"
SUPPORTED, REFUTED, INCONCLUSIVE = "supported", "refuted", "inconclusive"


@dataclass
class CaseCheck:
    """One decision of a case.

    ``kind`` is ``"gate"`` (the default: every check of a plugin case is a gate) or
    ``"claim"``.  For a gate ``passed`` is pass / fail / None (the data to decide is missing);
    for a claim supported / refuted / None (inconclusive).  ``claim``, ``source`` and ``rule``
    are filled for claims (a gate may state its rule too).
    """

    name: str
    passed: bool | None
    detail: str
    kind: str = GATE
    rule: str = ""
    claim: str = ""  # the claim's id, e.g. "C2"
    source: str = ""
    runs: tuple[str, ...] = ()  # run ids of the evidence

    @property
    def is_claim(self) -> bool:
        return self.kind == CLAIM

    @property
    def verdict(self) -> str:
        """PASS / FAIL / n/a for a gate; supported / refuted / inconclusive for a claim."""
        if self.is_claim:
            return {True: SUPPORTED, False: REFUTED, None: INCONCLUSIVE}[self.passed]
        return {True: "PASS", False: "FAIL", None: "n/a"}[self.passed]

    def to_json(self) -> dict[str, object]:
        return {"name": self.name, "passed": self.passed, "detail": self.detail,
                "kind": self.kind, "rule": self.rule, "claim": self.claim,
                "source": self.source, "runs": list(self.runs)}

    @classmethod
    def from_json(cls, raw: dict[str, object]) -> CaseCheck:
        passed = raw.get("passed")
        runs = raw.get("runs") or ()
        return cls(str(raw["name"]), passed if isinstance(passed, bool) else None,
                   str(raw.get("detail", "")), kind=str(raw.get("kind") or GATE),
                   rule=str(raw.get("rule") or ""), claim=str(raw.get("claim") or ""),
                   source=str(raw.get("source") or ""),
                   runs=tuple(str(r) for r in runs) if isinstance(runs, (list, tuple)) else ())


def gates(checks: Iterable[CaseCheck]) -> list[CaseCheck]:
    return [c for c in checks if not c.is_claim]


def claims(checks: Iterable[CaseCheck]) -> list[CaseCheck]:
    return [c for c in checks if c.is_claim]


@dataclass(frozen=True)
class Claim:
    """A statement of a paper: ``id`` (C1, C2, ...), the statement, where it comes from."""

    id: str
    statement: str
    source: str

    def verdict(self, passed: bool | None, rule: str, evidence: str,
                runs: Iterable[str] = ()) -> CaseCheck:
        """The claim's check: ``passed`` True supported, False refuted, None inconclusive."""
        return CaseCheck(self.statement, passed, evidence, kind=CLAIM, rule=rule, claim=self.id,
                         source=self.source, runs=tuple(runs))

    def no_data(self, rule: str, what: str) -> CaseCheck:
        """Inconclusive for want of runs: ``what`` says which runs the rule needs."""
        return self.verdict(None, rule, f"no data: {what}")


def _u(u: float | None) -> float:
    return 0.0 if u is None else float(u)


def below(value: float, limit: float, u: float | None = None, *,
          converged: bool = True) -> bool | None:
    """value < limit beyond its uncertainty: True when value + u < limit, False when
    value - u >= limit, None in between or when ``converged`` is False (u unknown)."""
    if not math.isfinite(value):
        return None
    if not converged:
        return None
    if value + _u(u) < limit:
        return True
    if value - _u(u) >= limit:
        return False
    return None


def above(value: float, limit: float, u: float | None = None, *,
          converged: bool = True) -> bool | None:
    """value > limit beyond its uncertainty (the mirror of :func:`below`)."""
    if not math.isfinite(value) or not converged:
        return None
    if value - _u(u) > limit:
        return True
    if value + _u(u) <= limit:
        return False
    return None


def less(a: float, b: float, ua: float | None = None, ub: float | None = None, *,
         converged: bool = True) -> bool | None:
    """a < b beyond their combined uncertainty sqrt(ua^2 + ub^2) (None within it)."""
    if not (math.isfinite(a) and math.isfinite(b)) or not converged:
        return None
    u = math.hypot(_u(ua), _u(ub))
    if b - a > u:
        return True
    if a - b > u:
        return False
    return None


def decide(outcomes: Iterable[bool | None]) -> bool | None:
    """A rule's verdict from its comparisons: False if any is False, True if there are some
    and all are True, else None."""
    seen = list(outcomes)
    if any(o is False for o in seen):
        return False
    if seen and all(o is True for o in seen):
        return True
    return None
