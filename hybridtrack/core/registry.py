"""Name → component factory, per interface kind.

Duplicate names and unknown names are clear errors; each entry remembers the
plugin and distribution that registered it (for ``hybridtrack plugins``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import attrs

from hybridtrack.core.kinds import KINDS


class UnknownComponentError(KeyError):
    """A component name that no loaded plugin registered."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0])


class DuplicateComponentError(ValueError):
    """Two plugins registered the same kind and name."""


@attrs.frozen
class Entry:
    kind: str
    name: str
    factory: Callable[..., Any]
    plugin: str
    distribution: str | None = None
    version: str | None = None

    @property
    def summary(self) -> str:
        doc = (getattr(self.factory, "__doc__", None) or "").strip()
        return doc.splitlines()[0] if doc else ""


class Registry:
    """All registered components, looked up by kind and name."""

    def __init__(self):
        self._entries: dict[str, dict[str, Entry]] = {kind: {} for kind in KINDS}

    def _check_kind(self, kind: str) -> dict[str, Entry]:
        if kind not in self._entries:
            raise ValueError(f"unknown component kind {kind!r}; kinds are {', '.join(KINDS)}")
        return self._entries[kind]

    def add(self, entry: Entry) -> None:
        table = self._check_kind(entry.kind)
        if not entry.name or not isinstance(entry.name, str):
            raise ValueError(f"plugin {entry.plugin!r}: component name must be a non-empty string, got {entry.name!r}")
        if not callable(entry.factory):
            raise ValueError(f"plugin {entry.plugin!r}: factory for {entry.kind} {entry.name!r} is not callable")
        if entry.name in table:
            old = table[entry.name]
            raise DuplicateComponentError(
                f"{entry.kind} {entry.name!r} registered by plugin {entry.plugin!r}"
                f" (distribution {entry.distribution or 'unknown'}) is already registered by plugin {old.plugin!r}"
                f" (distribution {old.distribution or 'unknown'})"
            )
        table[entry.name] = entry

    def entry(self, kind: str, name: str) -> Entry:
        table = self._check_kind(kind)
        try:
            return table[name]
        except KeyError:
            known = ", ".join(sorted(table)) or "none"
            raise UnknownComponentError(f"unknown {kind} {name!r}; known: {known}") from None

    def get(self, kind: str, name: str) -> Callable[..., Any]:
        """The factory registered as ``name`` for ``kind``."""
        return self.entry(kind, name).factory

    def create(self, kind: str, name: str, /, **parameters) -> Any:
        """Build the component ``name`` of ``kind`` with ``parameters``."""
        return self.get(kind, name)(**parameters)

    def names(self, kind: str) -> list[str]:
        return sorted(self._check_kind(kind))

    def entries(self) -> list[Entry]:
        return [entry for kind in KINDS for entry in self._entries[kind].values()]

    def bind(self, kind: str, plugin: str, distribution: str | None, version: str | None, on_error) -> Registrar:
        """A :class:`Registrar` adding entries of ``kind`` for ``plugin``; a class factory that does not
        implement the kind's interface is rejected at registration."""
        return Registrar(self, kind, plugin, distribution, version, on_error)


@attrs.define
class Registrar:
    """What a ``register_<kind>s`` hook receives: ``registry.add(name, factory)``.

    A rejected entry (duplicate or empty name, factory not callable, a class
    that does not implement the kind's interface) goes to ``on_error``; the
    others still register.
    """

    _registry: Registry
    kind: str
    plugin: str
    distribution: str | None
    version: str | None
    _on_error: Callable[[Exception], None]

    def add(self, name: str, factory: Callable[..., Any]) -> None:
        interface = KINDS[self.kind].interface
        if isinstance(factory, type) and not issubclass(factory, interface):
            self._on_error(
                TypeError(
                    f"{self.kind} {name!r} registered by plugin {self.plugin!r} (distribution {self.distribution or 'none'}):"
                    f" class {factory.__qualname__} does not implement {interface.__module__}.{interface.__name__}; not registered"
                )
            )
            return
        try:
            self._registry.add(Entry(self.kind, name, factory, self.plugin, self.distribution, self.version))
        except (DuplicateComponentError, ValueError) as error:
            self._on_error(error)
