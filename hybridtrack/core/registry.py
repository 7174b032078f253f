"""Name → component factory, per interface kind.

Duplicate names and unknown names are clear errors; each entry remembers the
plugin and distribution that registered it (for ``hybridtrack plugins``).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from typing import Any

import attrs

from hybridtrack.core.components import Labelled, require
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
        """Build the component ``name`` of ``kind`` with ``parameters``.

        A factory with a ``registry`` parameter (a component composed of other components, e.g. a detector
        wrapping another one, an algorithm over a bank) is handed this registry unless ``parameters`` name one,
        so the parts it resolves come from where it came from.
        """
        factory = self.get(kind, name)
        if "registry" not in parameters and accepts_registry(factory):
            parameters["registry"] = self
        return factory(**parameters)

    def check(self, kind: str, name: str, component) -> Any:
        """``component``, built by the factory registered as ``name`` of ``kind``, if it implements the kind's
        interface; otherwise a TypeError naming the component, the plugin and the distribution that registered
        the factory, and what the object lacks."""
        try:
            return require(component, KINDS[kind].interface, f"{kind} {name!r}")
        except TypeError as error:
            entry = self.entry(kind, name)
            raise TypeError(
                f"{error} (the factory of {kind} {name!r} registered by plugin {entry.plugin!r}"
                f" (distribution {entry.distribution or 'none'}) returned a {type(component).__name__})"
            ) from None

    def resolve(self, kind: str, spec) -> Any:
        """A component of ``kind`` from an object, a registered name, ``(name, parameters)`` or ``(name, parameters, label)``.

        The object (given or built) must implement the interface of ``kind``
        (:data:`hybridtrack.core.kinds.KINDS`); a wrong type is a TypeError
        naming the interface, and a factory returning the wrong type names the
        registered component, its plugin and distribution (:meth:`check`).  A label (third item, or a
        ``"label"`` key in the parameters) names the instance in a run (estimators and detectors).
        """
        self._check_kind(kind)
        base = KINDS[kind].interface
        if not isinstance(spec, (str, tuple)):
            return require(spec, base, kind)
        if isinstance(spec, str):
            spec = (spec, {})
        if not (
            len(spec) in (2, 3)
            and isinstance(spec[0], str)
            and isinstance(spec[1], Mapping)
            and (len(spec) == 2 or isinstance(spec[2], str))
        ):
            raise TypeError(
                f"{kind}: expected a {base.__name__}, a registered name, (name, parameters) or (name, parameters, label), got {spec!r}"
            )
        name, parameters = spec[0], dict(spec[1])
        label = spec[2] if len(spec) == 3 else parameters.pop("label", None)
        component = self.check(kind, name, self.create(kind, name, **parameters))
        if label is not None:
            if not isinstance(component, Labelled):
                raise ValueError(f"{kind} {name!r}: a label names estimators and detectors; {kind}s have none")
            component.label = label
        return component

    def names(self, kind: str) -> list[str]:
        return sorted(self._check_kind(kind))

    def entries(self) -> list[Entry]:
        return [entry for kind in KINDS for entry in self._entries[kind].values()]

    def bind(self, kind: str, plugin: str, distribution: str | None, version: str | None, on_error) -> Registrar:
        """A :class:`Registrar` adding entries of ``kind`` for ``plugin``; a class factory that does not
        implement the kind's interface is rejected at registration."""
        return Registrar(self, kind, plugin, distribution, version, on_error)


def registry_or_default(registry: Registry | None) -> Registry:
    """``registry``, or when None the default registry of the installed plugins (:func:`hybridtrack.get_registry`,
    loaded on first use, so that a plugin importing the contract does not load the plugin system)."""
    if registry is None:
        import hybridtrack

        return hybridtrack.get_registry()
    return registry


def accepts_registry(factory: Callable[..., Any]) -> bool:
    """Whether ``factory`` takes a ``registry`` keyword (a composite component)."""
    try:
        return "registry" in inspect.signature(factory).parameters
    except (TypeError, ValueError):  # a builtin or C callable without a signature
        return False


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
