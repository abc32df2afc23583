"""Name -> object registries shared by kernels, models, solvers and cases.

A registry entry is either an object or an import path ``"package.module:attr"`` that is imported
on first use, so listing names never imports a heavy backend.  Third-party packages add entries
through an entry-point group; an entry point that fails to load is recorded with its reason
instead of breaking the others.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any, Generic, TypeVar

from mpsbench.errors import MpsbenchError

T = TypeVar("T")

OWN_DISTRIBUTION = "mpsbench"
"""Entry points of this distribution are the built-ins (declared in its pyproject.toml)."""


NAME_CHARS = "letters, digits, '.', '_', '+', '-'; starting with a letter or digit; at most 100"
"""What a registered name may contain (:func:`check_name`): names of cases and solvers become
folder and file names of a results folder, so none may climb out of it or hide in it."""

_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,99}")


class UnknownNameError(MpsbenchError, KeyError, ValueError):
    """Raised for a name no registry entry carries; the message lists the known names."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class PluginLoadError(MpsbenchError, RuntimeError):
    """An entry could not be imported or did not have the expected shape."""


class BadNameError(MpsbenchError, ValueError):
    """A name that may not be registered (or read back from a record): see :data:`NAME_CHARS`."""


def name_problem(name: object) -> str | None:
    """Why ``name`` is not a valid case/solver/model name (None when it is)."""
    if not isinstance(name, str):
        return f"a string, got {type(name).__name__}"
    if not _NAME_RE.fullmatch(name) or ".." in name:
        return NAME_CHARS + " characters, no '..'"
    return None


def check_name(kind: str, name: object) -> str:
    """``name`` if it may name a ``kind`` (it is used as a path component); else BadNameError."""
    problem = name_problem(name)
    if problem is not None:
        raise BadNameError(f"{kind} name {name!r} is not allowed: {problem}")
    assert isinstance(name, str)
    return name


@dataclass
class Entry:
    name: str
    target: Any  # the object, or an import path "module:attr"
    description: str = ""
    source: str = ""
    origin: str = "builtin"  # "builtin", "entry-point:<dist>", or "user"
    error: str | None = None  # set when loading failed

    @property
    def loaded(self) -> bool:
        return not isinstance(self.target, str)


def import_path(path: str) -> Any:
    """Import ``"pkg.module:attr"`` (or ``"pkg.module.attr"``) and return the attribute."""
    if ":" in path:
        module_name, _, attr = path.partition(":")
    else:
        module_name, _, attr = path.rpartition(".")
    module = importlib.import_module(module_name)
    obj: Any = module
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


@dataclass
class Registry(Generic[T]):
    """A lazily loading name registry.

    ``kind`` names what is registered ("weighting function", "solver", ...) for messages;
    ``group`` is the entry-point group scanned on first lookup; ``validate`` checks a loaded
    object and raises with a reason when it has the wrong shape.
    """

    kind: str
    group: str | None = None
    validate: Callable[[Any], None] | None = None
    _entries: dict[str, Entry] = field(default_factory=dict)
    _scanned: bool = False
    ignored: list[Entry] = field(default_factory=list)
    """Entry points not used because the name was taken (each with the reason in ``error``)."""

    def register(
        self,
        name: str,
        target: Any,
        *,
        description: str = "",
        source: str = "",
        origin: str = "builtin",
        replace: bool = False,
    ) -> None:
        check_name(self.kind, name)
        if name in self._entries and not replace:
            raise ValueError(f"{self.kind} {name!r} is already registered")
        self._entries[name] = Entry(name, target, description, source, origin)

    def _scan_entry_points(self) -> None:
        if self._scanned or self.group is None:
            self._scanned = True
            return
        self._scanned = True
        self.ignored = []
        found = []
        for ep in entry_points(group=self.group):
            dist = getattr(ep.dist, "name", "?") if ep.dist is not None else "?"
            found.append((dist != OWN_DISTRIBUTION, dist, ep))
        # mpsbench's own entry points (its built-ins) first: they win a name over plugins
        for _, dist, ep in sorted(found, key=lambda f: f[0]):
            origin = "builtin" if dist == OWN_DISTRIBUTION else f"entry-point:{dist}"
            problem = name_problem(ep.name)
            if problem is not None:  # e.g. a '/' in it: it would name folders of a report
                self.ignored.append(Entry(ep.name, ep.value, origin=origin,
                                          error=f"ignored: the name is not allowed: {problem}"))
                continue
            if ep.name in self._entries:
                # built-ins (and the first plugin of a name) win; the loser is reported
                taken = self._entries[ep.name].origin
                self.ignored.append(Entry(
                    ep.name, ep.value, origin=origin,
                    error=f"ignored: the name is taken by {taken} {self.kind} {ep.name!r}",
                ))
                continue
            self._entries[ep.name] = Entry(ep.name, ep.value, origin=origin)

    def names(self) -> list[str]:
        self._scan_entry_points()
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        self._scan_entry_points()
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def entry(self, name: str) -> Entry:
        self._scan_entry_points()
        try:
            return self._entries[name]
        except KeyError:
            known = ", ".join(self.names()) or "(none)"
            raise UnknownNameError(
                f"unknown {self.kind} {name!r}; known {self.kind}s: {known}"
            ) from None

    def get(self, name: str) -> T:
        entry = self.entry(name)
        if entry.error is not None:
            raise PluginLoadError(
                f"{self.kind} {name!r} ({entry.origin}) is unavailable: {entry.error}"
            )
        if not entry.loaded:
            try:
                obj = import_path(entry.target)
                if self.validate is not None:
                    self.validate(obj)
            except Exception as exc:  # noqa: BLE001 - a plugin may raise anything on import
                entry.error = f"{type(exc).__name__}: {exc}"
                raise PluginLoadError(
                    f"{self.kind} {name!r} ({entry.origin}) could not be loaded: {entry.error}"
                ) from exc
            entry.target = obj
            if not entry.description:
                entry.description = _first_doc_line(obj)
        return entry.target

    def try_load_all(self) -> dict[str, str | None]:
        """Load every entry; return name -> error message (None when it loaded)."""
        out: dict[str, str | None] = {}
        for name in self.names():
            try:
                self.get(name)
                out[name] = None
            except PluginLoadError:
                out[name] = self._entries[name].error
        return out

    def unregister(self, name: str) -> None:
        self._entries.pop(name, None)


def _first_doc_line(obj: Any) -> str:
    doc = getattr(obj, "description", None) or getattr(obj, "__doc__", None) or ""
    return doc.strip().splitlines()[0] if doc.strip() else ""
