"""Registries: lazy import paths, unknown names, broken plugins, entry points, validation."""

from __future__ import annotations

import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

import mpsbench.registry as registry_module
from mpsbench.physics.laplacians import LAPLACIANS, _validate_laplacian
from mpsbench.physics.weights import _validate_weight
from mpsbench.registry import PluginLoadError, Registry, UnknownNameError, import_path
from mpsbench.run.protocol import SOLVERS, _validate_solver

MODULE = "mpsbench_test_plugin_mod"


@pytest.fixture
def plugin_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """A throw-away importable module with a good weight, a bad one and a solver-ish class."""
    (tmp_path / f"{MODULE}.py").write_text(
        textwrap.dedent(
            '''
            """A plugin module for the registry tests."""
            import numpy as np

            class Good:
                """A good weighting function."""
                @staticmethod
                def w_inside(r, re): return 1.0 - r / re
                @staticmethod
                def dw_inside(r, re): return -1.0 / re
                @staticmethod
                def d2w_inside(r, re): return 0.0 * r

            class NoDerivative:
                @staticmethod
                def w_inside(r, re): return r

            class MethodWeight(Good):
                def dw_inside(self, r, re): return -1.0 / re

            class NotASolver:
                name = "x"

            VALUE = 42
            '''
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, MODULE, raising=False)
    yield MODULE
    sys.modules.pop(MODULE, None)


def fake_entry_points(eps: dict[str, list[tuple[str, str, str | None]]]) -> Any:
    def entry_points(*, group: str) -> list[SimpleNamespace]:
        return [
            SimpleNamespace(
                name=name, value=value, dist=None if dist is None else SimpleNamespace(name=dist)
            )
            for name, value, dist in eps.get(group, [])
        ]

    return entry_points


def test_import_path_forms(plugin_module: str) -> None:
    assert import_path(f"{plugin_module}:VALUE") == 42
    assert import_path(f"{plugin_module}.VALUE") == 42
    assert import_path("mpsbench.physics.weights:WF2.name") == "wf2"  # nested attribute
    with pytest.raises(ModuleNotFoundError):
        import_path("no_such_module_xyz:thing")


def test_entries_load_lazily(plugin_module: str) -> None:
    reg: Registry[Any] = Registry("thing")
    reg.register("good", f"{plugin_module}:Good", description="described")
    assert reg.names() == ["good"] and "good" in reg and list(reg) == ["good"]
    assert not reg.entry("good").loaded
    assert plugin_module not in sys.modules  # listing did not import it
    cls = reg.get("good")
    assert plugin_module in sys.modules
    assert cls.__name__ == "Good" and reg.entry("good").loaded
    assert reg.get("good") is cls  # loaded once, then cached
    assert reg.entry("good").description == "described"


def test_description_defaults_to_first_doc_line(plugin_module: str) -> None:
    reg: Registry[Any] = Registry("thing")
    reg.register("good", f"{plugin_module}:Good")
    reg.get("good")
    assert reg.entry("good").description == "A good weighting function."


def test_unknown_name_lists_known_names() -> None:
    reg: Registry[Any] = Registry("gizmo")
    reg.register("alpha", 1)
    reg.register("beta", 2)
    with pytest.raises(UnknownNameError, match=r"unknown gizmo 'gamma'; known gizmos: alpha, beta"):
        reg.get("gamma")
    with pytest.raises(UnknownNameError, match=r"known gizmos: \(none\)"):
        Registry("gizmo").entry("x")


def test_register_rules() -> None:
    reg: Registry[Any] = Registry("gizmo")
    reg.register("a", 1)
    with pytest.raises(ValueError, match="gizmo 'a' is already registered"):
        reg.register("a", 2)
    reg.register("a", 3, replace=True)
    assert reg.get("a") == 3
    # names become folder names of a report: nothing that climbs out of a folder or hides
    for bad in ("", None, 5, "a/b", "../x", "..", ".hidden", "a\\b", "x\x00y", "a..b", "a b",
                "x" * 101):
        with pytest.raises(ValueError, match="gizmo name .* is not allowed"):
            reg.register(bad, 1)  # type: ignore[arg-type]
    for good in ("wf1", "xu-jin-analytic", "my_model.v2", "a+b", "9lives"):
        reg.register(good, 1)
        reg.unregister(good)
    reg.unregister("a")
    reg.unregister("never-there")  # no error
    assert reg.names() == []


def test_broken_entry_reports_reason_and_spares_the_others(plugin_module: str) -> None:
    reg: Registry[Any] = Registry("weighting function", validate=_validate_weight)
    reg.register("good", f"{plugin_module}:Good")
    reg.register("missing-module", "no_such_module_xyz.sub:Thing")
    reg.register("missing-attr", f"{plugin_module}:Nope")
    reg.register("wrong-shape", f"{plugin_module}:NoDerivative")

    with pytest.raises(PluginLoadError) as info:
        reg.get("missing-module")
    msg = str(info.value)
    assert "weighting function 'missing-module' (builtin) could not be loaded" in msg
    assert "ModuleNotFoundError" in msg and "no_such_module_xyz" in msg
    # the failure is remembered, with the same reason, without importing again
    with pytest.raises(PluginLoadError, match="is unavailable: ModuleNotFoundError"):
        reg.get("missing-module")

    with pytest.raises(PluginLoadError, match="AttributeError"):
        reg.get("missing-attr")
    with pytest.raises(
        PluginLoadError, match=r"TypeError: weighting function 'NoDerivative' has no "
        r"dw_inside\(r, re\)"
    ):
        reg.get("wrong-shape")
    assert not reg.entry("wrong-shape").loaded
    # a formula must be a static method: the numba backend compiles the function itself
    reg.register("method", f"{plugin_module}:MethodWeight")
    with pytest.raises(PluginLoadError, match=r"has dw_inside as a method: make it a "
                       r"@staticmethod of \(r, re\)"):
        reg.get("method")

    assert reg.get("good").__name__ == "Good"
    report = reg.try_load_all()
    assert report["good"] is None
    for name, error in [("missing-module", "ModuleNotFoundError"),
                        ("missing-attr", "AttributeError"), ("wrong-shape", "TypeError"),
                        ("method", "TypeError")]:
        message = report[name]
        assert message is not None and message.startswith(error), (name, message)


def test_entry_points_are_scanned_once_and_builtins_win(
    plugin_module: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[str] = []
    inner = fake_entry_points(
        {
            "test.group": [
                ("plugin-good", f"{plugin_module}:Good", "thirdparty"),
                ("plugin-broken", "no_such_module_xyz:Thing", None),
                ("builtin", f"{plugin_module}:NoDerivative", "shadow"),
            ],
            "other.group": [("elsewhere", f"{plugin_module}:Good", "x")],
        }
    )

    def entry_points(*, group: str) -> Any:
        calls.append(group)
        return inner(group=group)

    monkeypatch.setattr(registry_module, "entry_points", entry_points)
    reg: Registry[Any] = Registry(
        "weighting function", group="test.group", validate=_validate_weight
    )
    reg.register("builtin", f"{plugin_module}:Good")
    assert reg.names() == ["builtin", "plugin-broken", "plugin-good"]
    assert reg.names() == ["builtin", "plugin-broken", "plugin-good"]
    assert calls == ["test.group"]
    assert reg.entry("plugin-good").origin == "entry-point:thirdparty"
    assert reg.entry("plugin-broken").origin == "entry-point:?"
    assert reg.entry("builtin").origin == "builtin"
    assert reg.get("builtin").__name__ == "Good"  # not shadowed by the plugin
    assert reg.get("plugin-good").__name__ == "Good"
    with pytest.raises(PluginLoadError, match=r"'plugin-broken' \(entry-point:\?\) could not"):
        reg.get("plugin-broken")
    with pytest.raises(UnknownNameError, match="plugin-good"):
        reg.get("elsewhere")


def test_registry_without_group_never_scans(monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(**_: Any) -> Any:
        raise AssertionError("scanned")

    monkeypatch.setattr(registry_module, "entry_points", boom)
    reg: Registry[Any] = Registry("thing")
    reg.register("a", 1)
    assert reg.names() == ["a"]


def test_solver_validation_rejects_wrong_shapes(plugin_module: str) -> None:
    reg: Registry[type] = Registry("solver", validate=_validate_solver)
    reg.register("not-a-class", f"{plugin_module}:VALUE")
    reg.register("incomplete", f"{plugin_module}:NotASolver")
    with pytest.raises(PluginLoadError, match="a solver entry must be a class, got int"):
        reg.get("not-a-class")
    with pytest.raises(PluginLoadError, match="lacks version, capabilities, setup, stable_dt"):
        reg.get("incomplete")


def test_laplacian_validation(plugin_module: str) -> None:
    reg: Registry[Any] = Registry("Laplacian model", validate=_validate_laplacian)
    reg.register("bad", f"{plugin_module}:Good")
    with pytest.raises(PluginLoadError, match=r"has no pair\(r, w, dw, d2w\)"):
        reg.get("bad")


def test_builtin_registries_are_populated() -> None:
    assert LAPLACIANS.names() == ["khayyer-gotoh", "koshizuka-oka", "xu-jin", "xu-jin-analytic"]
    assert "reference" in SOLVERS
    for name in LAPLACIANS.names():
        assert LAPLACIANS.entry(name).source  # every model cites where it comes from
