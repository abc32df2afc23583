"""Solver specs: a backend's name with option values, ``numba:threads=1,sort=true``.

A backend declares its options (``SolverBase.options``: :class:`mpsbench.params.Option`, as a
case declares its parameters).  :func:`solver_spec` parses and validates a spec from the command
line (``--solver``), a study file or a record; :func:`make_solver` builds the solver from it.  A
record keeps the name (``solver``) and the canonical options (``solver_options``) apart, and a
run id names the non-default options.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mpsbench.errors import ConfigError
from mpsbench.params import Option
from mpsbench.run.protocol import SOLVERS, Solver, _validate_solver


@dataclass(frozen=True)
class SolverSpec:
    """A solver name with option values: ``numba``, ``numba:threads=1,sort=true``.

    ``options`` holds the values that differ from the backend's defaults, in the order the
    backend declares them, so equal settings give equal specs (and run ids); :attr:`text` is the
    canonical spec and :attr:`options_text` its ``key=value,...`` part ('' for the defaults).
    """

    name: str
    options: tuple[tuple[str, Any], ...] = ()
    options_text: str = ""

    @property
    def text(self) -> str:
        return f"{self.name}:{self.options_text}" if self.options_text else self.name

    def __str__(self) -> str:
        return self.text

    @property
    def kwargs(self) -> dict[str, Any]:
        return dict(self.options)


def solver_spec(text: str | SolverSpec) -> SolverSpec:
    """Parse and validate ``NAME[:key=value,...]`` against the backend's declared options.

    Unknown names raise the registry's error; an unknown option or a bad value raises
    :class:`ConfigError` naming the allowed ones.
    """
    if isinstance(text, SolverSpec):
        return text
    if not isinstance(text, str):
        raise ConfigError(f"solver = {text!r} is not allowed: a name such as 'numba' or "
                          "'numba:threads=1'")
    name, sep, rest = text.strip().partition(":")
    cls = SOLVERS.get(name.strip())
    declared: tuple[Option, ...] = tuple(getattr(cls, "options", ()) or ())
    known = {o.name: o for o in declared}
    values: dict[str, Any] = {}
    if sep:
        for item in rest.split(","):
            key, eq, raw = item.partition("=")
            key = key.strip()
            if not eq or not key:
                raise ConfigError(f"solver {text!r}: option {item.strip()!r} is not KEY=VALUE")
            if key not in known:
                allowed = ", ".join(known) if known else "none (it takes no options)"
                raise ConfigError(f"solver {name.strip()!r} has no option {key!r}; its options: "
                                  f"{allowed}")
            if key in values:
                raise ConfigError(f"solver {text!r}: option {key!r} given twice")
            try:
                values[key] = known[key].parse(raw.strip())
            except ConfigError as exc:
                raise ConfigError(f"solver {name.strip()!r}: {exc}") from None
    kept = tuple((o.name, values[o.name]) for o in declared
                 if o.name in values and values[o.name] != o.default)
    text_part = ",".join(f"{k}={known[k].format(v)}" for k, v in kept)
    return SolverSpec(name.strip(), kept, text_part)


def solver_options(cls: Any) -> list[dict[str, Any]]:
    """A backend's declared options as rows (name, kind, default, allowed, help) for listings."""
    return [{"name": o.name, "kind": o.kind.__name__, "default": o.default,
             "default_text": o.format(o.default), "allowed": o.allowed(), "help": o.help}
            for o in tuple(getattr(cls, "options", ()) or ())]


def get_solver_class(name_or_cls: str | type | SolverSpec) -> type:
    """A solver class from a registry name, a spec (its options are checked too) or the class."""
    if isinstance(name_or_cls, (str, SolverSpec)):
        return SOLVERS.get(solver_spec(name_or_cls).name)
    _validate_solver(name_or_cls)
    return name_or_cls


def make_solver(spec: str | type | SolverSpec | Solver) -> Solver:
    """A fresh solver instance from a spec (``numba:threads=1``), a class, or an instance
    (returned as is)."""
    if isinstance(spec, (str, SolverSpec)):
        parsed = solver_spec(spec)
        return SOLVERS.get(parsed.name)(**parsed.kwargs)
    if isinstance(spec, type):
        return get_solver_class(spec)()
    return spec
