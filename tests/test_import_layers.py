"""The import graph of the whole tree: layers, the core without its built-ins, no cycles.

The graph is read from the sources with ``ast`` (every ``import`` and ``from ... import``, at
module level or inside functions; those under ``if TYPE_CHECKING:`` do not run and are left
out), with the package mapping of pyproject.toml: ``mpsbench/`` is ``mpsbench``, ``solvers/``
is ``mpsbench.solvers`` and ``validations/`` is ``mpsbench.validations`` (import-linter's graph
builder walks a package's own folder only, so it would not see those two).  Contracts:

* the core runs one way, from the command line down: cli (with ``__main__`` and the pytest
  plugin: the entry points) -> commands -> testing -> results -> cases -> run -> physics ->
  (registry, errors, params); a module may import its own layer and the layers below it, never
  one above;
* the core never imports ``mpsbench.solvers`` or ``mpsbench.validations`` (the built-ins come in
  through entry points, as plugins do), and those two never import each other;
* no import cycle anywhere, solvers/ and validations/ included.

``.ci/run`` runs this file as its own step; it is part of the default ``pytest`` too.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"mpsbench": ROOT / "mpsbench", "mpsbench.solvers": ROOT / "solvers",
            "mpsbench.validations": ROOT / "validations"}

LAYERS = ("cli", "commands", "testing", "results", "cases", "run", "physics", "base")
"""Top to bottom; ``base`` is ``mpsbench`` itself, ``registry``, ``errors`` and ``params``."""
OUTSIDE = ("mpsbench.solvers", "mpsbench.validations")

Graph = dict[str, set[str]]


def modules(packages: dict[str, Path]) -> dict[str, Path]:
    """Module name -> source file (a package is its ``__init__.py``)."""
    out: dict[str, Path] = {}
    for name, folder in packages.items():
        for path in sorted(folder.rglob("*.py")):
            rel = path.relative_to(folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            if any(not p.isidentifier() for p in parts):
                continue
            out[".".join([name, *parts])] = path
    return out


def _runtime_nodes(tree: ast.Module) -> Iterable[ast.AST]:
    """Every node except what sits under ``if TYPE_CHECKING:``."""
    todo: list[ast.AST] = [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo.extend(node.orelse)
            continue
        yield node
        todo.extend(ast.iter_child_nodes(node))


def import_graph(packages: dict[str, Path]) -> Graph:
    """Module -> the project modules it imports."""
    mods = modules(packages)
    graph: Graph = {m: set() for m in mods}

    def target(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    for mod, path in mods.items():
        is_package = path.name == "__init__.py"
        here = mod if is_package else mod.rpartition(".")[0]
        for node in _runtime_nodes(ast.parse(path.read_text(), str(path))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = here.split(".")
                    up = up[: len(up) - (node.level - 1)]
                    base = ".".join([*up, base] if base else up)
                # ``from pkg import sub`` imports the submodule; ``from mod import attr`` the
                # module itself
                subs = [f"{base}.{a.name}" for a in node.names]
                names = [n for n in subs if n in mods] or [base]
                if len(names) < len(subs):
                    names.append(base)
            for name in names:
                found = target(name)
                if found is not None and found != mod:
                    graph[mod].add(found)
    return graph


def layer(module: str) -> str | None:
    """The core layer of a module (None outside the core: solvers/, validations/)."""
    if any(module == o or module.startswith(o + ".") for o in OUTSIDE):
        return None
    parts = module.split(".")
    head = parts[1] if len(parts) > 1 else ""
    if head in ("cli", "__main__", "pytest_plugin"):  # the entry points into the package
        return "cli"
    if head in LAYERS:
        return head
    return "base"  # mpsbench, registry, errors, params


def layer_violations(graph: Graph) -> list[str]:
    out = []
    for mod, targets in sorted(graph.items()):
        mine = layer(mod)
        for t in sorted(targets):
            theirs = layer(t)
            if mine is None or theirs is None:
                continue
            if LAYERS.index(theirs) < LAYERS.index(mine):
                out.append(f"{mod} ({mine}) imports {t} ({theirs}), a layer above it")
    return out


def outside_violations(graph: Graph) -> list[str]:
    out = []
    for mod, targets in sorted(graph.items()):
        home = next((o for o in OUTSIDE if mod == o or mod.startswith(o + ".")), None)
        for t in sorted(targets):
            theirs = next((o for o in OUTSIDE if t == o or t.startswith(o + ".")), None)
            if theirs is not None and theirs != home:
                where = "the core" if home is None else home
                out.append(f"{mod} ({where}) imports {t}")
    return out


def cycles(graph: Graph) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


@pytest.fixture(scope="module")
def graph() -> Graph:
    return import_graph(PACKAGES)


def test_the_graph_covers_the_whole_tree(graph: Graph) -> None:
    for name in ("mpsbench.cli", "mpsbench.run.scheme", "mpsbench.solvers.numba_backend.kernels",
                 "mpsbench.validations.dam_break.case"):
        assert name in graph
    assert "mpsbench.run.protocol" in graph["mpsbench.run.scheme"]
    assert "mpsbench.solvers.numba_backend.formulas" in graph[
        "mpsbench.solvers.numba_backend.kernels"]  # relative imports resolved


def test_core_layers_run_one_way(graph: Graph) -> None:
    bad = layer_violations(graph)
    assert not bad, "\n".join(bad)


def test_core_never_imports_its_builtins(graph: Graph) -> None:
    bad = outside_violations(graph)
    assert not bad, "\n".join(bad)


def test_no_import_cycles(graph: Graph) -> None:
    found = cycles(graph)
    assert not found, "\n".join(" <-> ".join(c) for c in found)


def test_the_checks_find_what_they_look_for(tmp_path: Path) -> None:
    """A small tree with a cycle, an upward import and a core module importing a solver."""
    files = {
        "core/__init__.py": "",
        "core/physics/__init__.py": "",
        "core/physics/a.py": "from core.run import b\n",
        "core/run/__init__.py": "",
        "core/run/b.py": "def f():\n    from ..physics import a\n",
        "core/run/c.py": "import core.solvers.s\n",
        "core/run/d.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                         "    import core.solvers.s\n",
        "solv/__init__.py": "",
        "solv/s.py": "from core.run import c\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    g = import_graph({"core": tmp_path / "core", "core.solvers": tmp_path / "solv"})
    renamed = {k.replace("core", "mpsbench", 1): {t.replace("core", "mpsbench", 1) for t in v}
               for k, v in g.items()}
    assert layer_violations(renamed) == [
        "mpsbench.physics.a (physics) imports mpsbench.run.b (run), a layer above it"
    ]
    assert outside_violations(renamed) == [
        "mpsbench.run.c (the core) imports mpsbench.solvers.s"
    ]
    assert sorted(map(tuple, cycles(renamed))) == [
        ("mpsbench.physics.a", "mpsbench.run.b"), ("mpsbench.run.c", "mpsbench.solvers.s")
    ]
