"""Case.inactive_without: parameters that do nothing while a flag is false go back to their
defaults in expand(), so a tier (or --set) never makes the same run twice under two names."""

from __future__ import annotations

from mpsbench.cases import Case, Param


class Flagged(Case):
    name = "flagged"
    params = (
        Param("stabilization", False, "flag", kind=bool),
        Param("alpha_s", 0.01, "only with the flag", minimum=0.0, maximum=1.0),
        Param("l0", 0.1, "spacing", minimum=0.0, exclusive_minimum=True),
    )
    tiers = {"smoke": [{"stabilization": [False, True], "alpha_s": [0.01, 0.02],
                        "l0": [0.1, 0.05]}]}
    inactive_without = {"stabilization": ("alpha_s",)}


class Plain(Flagged):
    name = "plain"
    inactive_without = {}


def test_inactive_parameters_are_reset_and_the_runs_merged() -> None:
    runs = Flagged().expand("smoke")
    off = [r for r in runs if not r["stabilization"]]
    on = [r for r in runs if r["stabilization"]]
    assert len(off) == 2 and all(r["alpha_s"] == 0.01 for r in off)  # one per l0
    assert sorted((r["alpha_s"], r["l0"]) for r in on) == [(0.01, 0.05), (0.01, 0.1),
                                                           (0.02, 0.05), (0.02, 0.1)]
    # without the declaration every combination is its own run
    assert len(Plain().expand("smoke")) == 8
    # overrides go through the same rule
    assert {r["alpha_s"] for r in Flagged().expand("smoke", {"alpha_s": [0.5]})
            if not r["stabilization"]} == {0.01}
