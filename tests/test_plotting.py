"""The shared figure helpers (mpsbench.cases.plotting): panel labels of refinement figures and
how figures are saved."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from mpsbench.cases import plotting as pl


def sets(*keys: dict[str, object]) -> list[SimpleNamespace]:
    return [SimpleNamespace(key=tuple(k.items())) for k in keys]


def test_set_labels_name_what_differs_between_the_sets() -> None:
    got = pl.set_labels(sets(
        {"laplacian": "xu-jin", "weight": "wf2", "re_ratio": 3.1, "dt": 1e-4, "l0": None},
        {"laplacian": "xu-jin", "weight": "wf1", "re_ratio": 3.1, "dt": 1e-4, "l0": None},
        {"laplacian": "xu-jin", "weight": "wf2", "re_ratio": 3.1, "dt": None, "l0": 0.025},
    ))
    # laplacian and re_ratio are shared: not shown; None (the refined parameter) left out
    assert got == ["dt=0.0001, weight=wf2", "dt=0.0001, weight=wf1", "l0=0.025, weight=wf2"]


def test_set_labels_of_one_set_or_equal_keys_are_empty() -> None:
    assert pl.set_labels(sets({"weight": "wf2"})) == [""]
    assert pl.set_labels(sets({"weight": "wf2"}, {"weight": "wf2"})) == ["", ""]


def test_long_set_labels_break_in_two_lines() -> None:
    a = {"laplacian": "koshizuka-oka", "weight": "wf1", "re_ratio": 2.1, "jitter": 0.1}
    b = {"laplacian": "khayyer-gotoh", "weight": "wf2", "re_ratio": 3.5, "jitter": 0.0}
    first, second = pl.set_labels(sets(a, b))
    assert first == "jitter=0.1, laplacian=koshizuka-oka,\nre_ratio=2.1, weight=wf1"
    assert second.count("\n") == 1


def test_a_laid_out_figure_is_saved_at_its_own_size(tmp_path: Path) -> None:
    png = pytest.importorskip("matplotlib.image")
    fig, axes = pl.figure(1, 1)  # constrained layout: saved as laid out
    axes[0, 0].plot([0, 1], [0, 1])
    img = png.imread(pl.save(fig, tmp_path / "a.png"))
    assert img.shape[:2] == (round(3.6 * 110), round(4.6 * 110))
    plain = pl.pyplot().figure(figsize=(4.6, 3.6))  # no layout engine: cropped to its content
    plain.add_subplot().plot([0, 1], [0, 1])
    img = png.imread(pl.save(plain, tmp_path / "b.png"))
    assert img.shape[:2] != (round(3.6 * 110), round(4.6 * 110))
