"""``mpsbench models`` and ``mpsbench solvers``: what is registered, with descriptions."""

from __future__ import annotations

import argparse
import json
from typing import Any

ORDER = 10


def register(sub: Any) -> None:
    p = sub.add_parser("models", help="list weighting functions, Laplacians and pressure gradients")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_models)
    p = sub.add_parser("solvers", help="list solver backends, their capabilities and options")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_solvers)


def models_catalog() -> dict[str, list[dict[str, Any]]]:
    from mpsbench.physics.gradients import GRADIENTS
    from mpsbench.physics.laplacians import LAPLACIANS
    from mpsbench.physics.weights import WEIGHTS

    out: dict[str, list[dict[str, Any]]] = {}
    for key, reg in (("weights", WEIGHTS), ("laplacians", LAPLACIANS), ("gradients", GRADIENTS)):
        rows = []
        for name in reg.names():
            error = None
            try:
                reg.get(name)
            except Exception as exc:  # noqa: BLE001 - reported, not raised
                error = str(exc)
            entry = reg.entry(name)
            rows.append(
                {
                    "name": name,
                    "description": entry.description,
                    "source": entry.source,
                    "origin": entry.origin,
                    "available": error is None,
                    "error": error,
                }
            )
        rows += [_ignored_row(e) for e in reg.ignored]
        out[key] = rows
    return out


def _ignored_row(entry: Any) -> dict[str, Any]:
    """A plugin entry point that lost its name to another entry: listed, never loaded."""
    return {"name": entry.name, "description": "", "source": "", "origin": entry.origin,
            "available": False, "error": f"{entry.origin}: {entry.error}"}


def solvers_catalog() -> list[dict[str, Any]]:
    from mpsbench.run.protocol import SOLVERS
    from mpsbench.run.specs import solver_options

    rows = []
    for name in SOLVERS.names():
        entry = SOLVERS.entry(name)
        row: dict[str, Any] = {"name": name, "origin": entry.origin}
        try:
            cls: Any = SOLVERS.get(name)
            row.update(
                available=True,
                version=str(cls.version),
                description=entry.description or (cls.__doc__ or "").strip().split("\n")[0],
                capabilities=cls.capabilities.as_dict(),
                options=solver_options(cls),
                error=None,
            )
        except Exception as exc:  # noqa: BLE001 - an unavailable backend is listed, not fatal
            row.update(available=False, description=entry.description, error=str(exc))
        rows.append(row)
    for ignored in SOLVERS.ignored:
        rows.append({"name": ignored.name, "origin": ignored.origin, "available": False,
                     "description": "", "error": f"{ignored.origin}: {ignored.error}"})
    return rows


def cmd_models(args: argparse.Namespace) -> int:
    cat = models_catalog()
    if args.json:
        print(json.dumps(cat, indent=2))
        return 0
    titles = {"weights": "Weighting functions", "laplacians": "Laplacian models",
              "gradients": "Pressure gradient models"}
    for key, rows in cat.items():
        print(f"{titles[key]}:")
        width = max((len(r["name"]) for r in rows), default=0)
        for r in rows:
            state = "" if r["available"] else f"  [unavailable: {r['error']}]"
            src = f"  ({r['source']})" if r["source"] else ""
            print(f"  {r['name']:<{width}}  {r['description']}{src}{state}")
        print()
    return 0


def cmd_solvers(args: argparse.Namespace) -> int:
    rows = solvers_catalog()
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    for r in rows:
        if r["available"]:
            print(f"{r['name']} {r['version']}  {r['description']}")
            for k, v in r["capabilities"].items():
                print(f"    {k:<11} {(', '.join(v) or 'none') if isinstance(v, list) else v}")
            if r["options"]:
                print(f"    options (--solver {r['name']}:key=value,...):")
            for o in r["options"]:
                print(f"      {o['name']} (default {o['default_text']}; {o['allowed']}): "
                      f"{o['help']}")
        else:
            print(f"{r['name']}  [unavailable] {r['error']}")
    return 0
