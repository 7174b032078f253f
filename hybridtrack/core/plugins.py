"""Plugin loading on pluggy: modules (or objects) with :data:`hybridtrack.hookimpl` functions from the ``hybridtrack``
entry-point group, this project's own first (so a built-in's name stays its own), each kind of
:data:`hybridtrack.core.kinds.KINDS` through its hook, sub-commands through ``register_commands``.  Faults are isolated
(any ``BaseException`` but ``KeyboardInterrupt``: a :class:`PluginWarning` naming the plugin and its distribution,
the others still load), ``HYBRIDTRACK_DISABLE_PLUGINS`` blocks plugins by entry-point name, family or distribution,
and a factory returning the wrong type is caught at first use (:func:`resolve`, :func:`check_component`) by a
TypeError naming the plugin and distribution: ``docs/plugins.md`` §3, §4, §6.
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Iterable
from importlib.metadata import entry_points

import attrs
import pluggy

from hybridtrack.core import hookspecs
from hybridtrack.core.commands import Command, Commands
from hybridtrack.core.components import require
from hybridtrack.core.kinds import KINDS
from hybridtrack.core.registry import Registry, registry_or_default

ENTRY_POINT_GROUP = "hybridtrack"
DISABLE_ENV = "HYBRIDTRACK_DISABLE_PLUGINS"


class PluginWarning(UserWarning):
    """A plugin could not be loaded or one of its components was rejected."""


class PluginError(RuntimeError):
    """Raised instead of :class:`PluginWarning` when loading strictly."""


@attrs.frozen
class PluginInfo:
    """A loaded plugin: its name, and the distribution that ships it (None for objects registered in code)."""

    name: str
    distribution: str | None = None
    version: str | None = None


@attrs.frozen
class LoadedPlugins:
    """The outcome of :func:`load_plugins`: the registry, the plugins, the commands they add and what went wrong."""

    registry: Registry
    plugins: tuple[PluginInfo, ...]
    problems: tuple[str, ...]
    manager: pluggy.PluginManager = attrs.field(repr=False)
    commands: dict[str, Command] = attrs.field(factory=dict, repr=False)


def disabled_from_env() -> set[str]:
    return {name.strip() for name in os.environ.get(DISABLE_ENV, "").split(",") if name.strip()}


def _family(name: str) -> str:
    return name.partition(".")[0]


def load_plugins(
    extra: Iterable[object] = (),
    *,
    entrypoints: bool = True,
    disabled: Iterable[str] | None = None,
    strict: bool = False,
    builtins: Iterable[object] = (),
) -> LoadedPlugins:
    """Load the ``builtins``, the entry-point plugins (unless ``entrypoints=False``) and the ``extra`` plugin objects.

    ``builtins`` are the application's own plugin objects (the command line's
    commands): loaded first, so their names stay theirs, never disabled, and
    not listed in ``plugins``.
    ``disabled`` defaults to the names in ``HYBRIDTRACK_DISABLE_PLUGINS``.
    Problems are warned about (``strict=True``: raised as :class:`PluginError`);
    problems with ``builtins`` and ``extra`` objects always raise, since the caller wrote them.
    """
    blocked = disabled_from_env() if disabled is None else set(disabled)
    manager = pluggy.PluginManager(hookspecs.PROJECT)
    manager.add_hookspecs(hookspecs)
    infos: dict[str, PluginInfo] = {}
    problems: list[str] = []

    def report(message: str, raise_it: bool) -> None:
        problems.append(message)
        if strict or raise_it:
            raise PluginError(message)
        warnings.warn(message, PluginWarning, stacklevel=3)

    def register(obj: object, info: PluginInfo, from_code: bool) -> None:
        try:
            manager.register(obj, name=info.name)
            manager.check_pending()
        except Exception as error:  # noqa: BLE001 - any fault of a plugin is reported, not fatal
            if manager.is_registered(obj):
                manager.unregister(obj)
            report(f"plugin {info.name!r} (distribution {info.distribution or 'none'}) was not loaded: {error}", from_code)
            return
        infos[info.name] = info

    builtins = list(builtins)
    own = [PluginInfo(getattr(obj, "__name__", None) or type(obj).__name__) for obj in builtins]
    for obj, info in zip(builtins, own):
        register(obj, info, from_code=True)
    extra = [(getattr(obj, "__name__", None) or type(obj).__name__, obj) for obj in extra]
    points = sorted(entry_points(group=ENTRY_POINT_GROUP), key=_load_order)
    known = {point.name for point in points} | {_family(point.name) for point in points}
    known |= {point.dist.name for point in points if getattr(point, "dist", None)}
    known |= {name for name, _ in extra}
    if blocked - known:
        report(
            f"{DISABLE_ENV if disabled is None else 'disabled'}: no installed plugin or distribution is named"
            f" {', '.join(map(repr, sorted(blocked - known)))}; known: {', '.join(sorted(known)) or 'none'}",
            False,
        )
    if entrypoints:
        for point in points:
            dist = getattr(point, "dist", None)
            info = PluginInfo(point.name, dist.name if dist else None, dist.version if dist else None)
            if blocked & {point.name, _family(point.name), info.distribution}:
                manager.set_blocked(point.name)
                continue
            if point.name in infos:
                report(f"plugin {point.name!r} (distribution {info.distribution}) duplicates an entry-point name; skipped", False)
                continue
            try:
                obj = point.load()
            except KeyboardInterrupt:  # indistinguishable from the user's Ctrl-C: let it interrupt
                raise
            except BaseException as error:  # noqa: BLE001 - SystemExit, GeneratorExit... of a plugin's import must not end the program
                report(f"plugin {point.name!r} (distribution {info.distribution or 'unknown'}) failed to import: {error!r}", False)
                continue
            register(obj, info, from_code=False)

    for name, obj in extra:
        if name not in blocked:
            register(obj, PluginInfo(name), from_code=True)

    def call(hook_name: str, argument) -> None:
        """Each plugin's implementation of ``hook_name`` with ``argument`` (a registrar, or one made per plugin)."""
        for impl in getattr(manager.hook, hook_name).get_hookimpls():
            info = infos[impl.plugin_name]
            from_code = info.distribution is None
            try:
                impl.function(**{arg: argument(info, from_code) for arg in impl.argnames})
            except (PluginError, KeyboardInterrupt):
                raise
            except BaseException as error:  # noqa: BLE001
                report(f"plugin {info.name!r} (distribution {info.distribution or 'none'}) failed in {hook_name}: {error!r}", from_code)

    registry = Registry()
    for kind in KINDS.values():
        call(
            kind.hook,
            lambda info, from_code, kind=kind.name: registry.bind(
                kind, info.name, info.distribution, info.version, on_error=lambda error: report(str(error), from_code)
            ),
        )
    commands: dict[str, Command] = {}
    call("register_commands", lambda info, from_code: Commands(commands, info.name, lambda error: report(str(error), from_code)))
    plugins = tuple(info for info in infos.values() if info not in own)
    return LoadedPlugins(registry, plugins, tuple(problems), manager, commands)


def _load_order(point) -> tuple[bool, str]:
    """This project's own plugins first, then the others by name: a third-party
    component reusing a built-in name is the one rejected, whatever its name sorts as."""
    dist = getattr(point, "dist", None)
    return (dist is None or dist.name != hookspecs.PROJECT, point.name)


@functools.cache
def default_plugins() -> LoadedPlugins:
    """The plugins from entry points, loaded once per process (see :func:`reset`)."""
    return load_plugins()


def get_registry() -> Registry:
    """The default registry (entry-point plugins, honouring ``HYBRIDTRACK_DISABLE_PLUGINS``)."""
    return default_plugins().registry


def reset() -> None:
    """Forget the cached default plugins (after installing a plugin or changing the environment)."""
    default_plugins.cache_clear()


def check_component(kind: str, name: str, component, registry: Registry | None = None):
    """``component`` if it implements the interface of ``kind`` (:meth:`Registry.check` on the default registry
    when ``registry`` is None)."""
    return registry_or_default(registry).check(kind, name, component)


def resolve(kind: str, spec, registry: Registry | None = None):
    """A component of ``kind`` from an object, a name, ``(name, parameters)`` or ``(name, parameters, label)``
    (:meth:`Registry.resolve` on the default registry when ``registry`` is None)."""
    if not isinstance(spec, (str, tuple)) and kind in KINDS:
        return require(spec, KINDS[kind].interface, kind)  # an object needs no registry
    return registry_or_default(registry).resolve(kind, spec)
