"""Named, typed, validated settings: a case's parameters and a solver's options.

A :class:`Param` has a name, a default, a kind (float, int, str or bool), allowed values or
bounds and a help text; :meth:`Param.parse` turns text (``--set key=value``, a solver spec
``numba:threads=1``, a study file) into a checked value, and a bad value raises
:class:`~mpsbench.errors.ConfigError` naming the setting, the value and what is allowed.
Cases (:mod:`mpsbench.cases`) and solver backends (:mod:`mpsbench.run.protocol`) both declare
their settings this way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from mpsbench.errors import ConfigError


@dataclass(frozen=True)
class Param:
    """A named case parameter.  ``kind`` is float, int, str or bool; ``unit`` is documentation."""

    name: str
    default: Any
    help: str = ""
    unit: str = ""
    kind: type = float
    choices: tuple[Any, ...] | None = None
    minimum: float | None = None
    exclusive_minimum: bool = False
    maximum: float | None = None

    role: ClassVar[str] = "parameter"
    """How messages call it ("parameter"; :class:`Option`: "option")."""

    def allowed(self) -> str:
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        bounds = []
        if self.minimum is not None:
            bounds.append(f"{'>' if self.exclusive_minimum else '>='} {self.minimum:g}")
        if self.maximum is not None:
            bounds.append(f"<= {self.maximum:g}")
        kind = self.kind.__name__
        text = f"{'an' if kind[0] in 'aeiou' else 'a'} {kind}"
        return f"{text} {' and '.join(bounds)}" if bounds else text

    def parse(self, text: str) -> Any:
        """Convert text from ``--set key=value`` (or a TOML value) and validate it."""
        value: Any = text
        if isinstance(text, str):
            try:
                if self.kind is bool:
                    low = text.strip().lower()
                    if low not in ("true", "false", "1", "0", "on", "off", "yes", "no"):
                        raise ValueError(text)
                    value = low in ("true", "1", "on", "yes")
                elif self.kind is float:
                    value = _parse_float(text)
                elif self.kind is int:
                    value = int(text)
                else:
                    value = text.strip()
            except (ValueError, ZeroDivisionError, OverflowError):  # "1/0", "1e999/1e-999"
                raise ConfigError(
                    f"{self.role} {self.name} = {_show(text)} is not allowed: "
                    f"{self.allowed()}"
                ) from None
            try:
                return self.check(value)
            except ConfigError:  # name the text as given ("1e999", not inf)
                raise ConfigError(
                    f"{self.role} {self.name} = {_show(text)} is not allowed: "
                    f"{self.allowed()}"
                ) from None
        return self.check(value)

    def check(self, value: Any) -> Any:
        bad = ConfigError(f"{self.role} {self.name} = {_show(value)} is not allowed: "
                          f"{self.allowed()}")
        if self.kind is float and isinstance(value, int) and not isinstance(value, bool):
            try:
                value = float(value)
            except OverflowError:  # an integer beyond the float range
                raise bad from None
        if self.kind is float and not (isinstance(value, float) and math.isfinite(value)):
            raise bad
        if self.kind is int and (not isinstance(value, int) or isinstance(value, bool)):
            raise bad
        if self.kind is bool and not isinstance(value, bool):
            raise bad
        if self.kind is str and not isinstance(value, str):
            raise bad
        if self.choices is not None and value not in self.choices:
            raise bad
        if self.minimum is not None:
            if value < self.minimum or (self.exclusive_minimum and value == self.minimum):
                raise bad
        if self.maximum is not None and value > self.maximum:
            raise bad
        return value


def _show(value: Any) -> str:
    """``repr(value)`` for a message, cut at 200 characters (an integer too long to print, from a
    study file, is described instead: repr raises for more than 4300 digits)."""
    try:
        text = repr(value)
    except ValueError:
        return f"<an integer of {value.bit_length()} bits>"
    return text if len(text) <= 200 else text[:197] + "..."


def _parse_float(text: str) -> float:
    """Floats, plus simple fractions such as ``1/40`` (handy for spacings)."""
    text = text.strip()
    if "/" in text:
        num, _, den = text.partition("/")
        return float(num) / float(den)
    return float(text)


@dataclass(frozen=True)
class Option(Param):
    """A solver backend's option (``--solver numba:threads=1``): a :class:`Param` that messages
    call an option."""

    role: ClassVar[str] = "option"

    def format(self, value: Any) -> str:
        """The canonical text of a value (what :meth:`parse` reads back)."""
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, float):
            return repr(value)
        return str(value)
