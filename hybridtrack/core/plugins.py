"""Plugin loading on pluggy: modules (or objects) with :data:`hybridtrack.hookimpl` functions from the ``hybridtrack``
entry-point group, this project's own first (so a built-in's name stays its own), each kind of
:data:`hybridtrack.core.kinds.KINDS` through its hook, sub-commands through ``register_commands``.  Faults are isolated
(any ``BaseException`` but ``KeyboardInterrupt``: a :class:`PluginWarning` naming the plugin and its distribution,
the others still load), ``HYBRIDTRACK_DISABLE_PLUGINS`` blocks plugins by entry-point name, family or distribution,
and a factory returning the wrong type is caught at first use (:func:`resolve`, :func:`check_component`) by a
TypeError naming the plugin and distribution: ``docs/plugins.md`` §3, §4, §6.  A name that only a blocked plugin
registers is reported as disabled, naming that plugin (:class:`PluginRegistry`), not as unknown; a spec that is
none of the accepted forms is a TypeError listing them (:func:`resolve`).
"""

from __future__ import annotations

import functools
import numbers
import os
import warnings
from collections.abc import Iterable, Mapping
from importlib.metadata import entry_points

import attrs
import pluggy

from hybridtrack.core import hookspecs
from hybridtrack.core.commands import Command, Commands
from hybridtrack.core.components import require
from hybridtrack.core.kinds import KINDS
from hybridtrack.core.registry import Registry, UnknownComponentError, registry_or_default

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


class PluginRegistry(Registry):
    """The :class:`Registry` :func:`load_plugins` fills, knowing which plugins it blocked (``blocked``, their
    :class:`PluginInfo`; ``blocked_by`` says how: ``HYBRIDTRACK_DISABLE_PLUGINS=…`` or ``disabled=[…]``).

    An unknown name that one of the blocked plugins registers is an :class:`UnknownComponentError` saying so:
    ``motion_model 'left_turn' is disabled by HYBRIDTRACK_DISABLE_PLUGINS=motion: plugin 'motion.linear_modes'
    (distribution hybridtrack) registers it; known: …``.  Finding that plugin loads the plugins once more with
    nothing blocked (warnings silenced, nothing kept), only when such a name is asked for.
    """

    def __init__(self, blocked: Iterable[PluginInfo] = (), blocked_by: str = DISABLE_ENV, blocked_objects: Iterable[object] = ()):
        super().__init__()
        self.blocked = tuple(blocked)
        self.blocked_by = blocked_by
        self.blocked_objects = tuple(blocked_objects)  # blocked plugin objects given in code (``extra``)

    def entry(self, kind: str, name: str):
        try:
            return super().entry(kind, name)
        except UnknownComponentError:
            provider = self.blocked_provider(kind, name) if self.blocked else None
            if provider is None:
                raise
            known = ", ".join(self.names(kind)) or "none"
            raise UnknownComponentError(
                f"{kind} {name!r} is disabled by {self.blocked_by}: plugin {provider.name!r}"
                f" (distribution {provider.distribution or 'none'}) registers it; known: {known}"
            ) from None

    def blocked_provider(self, kind: str, name: str) -> PluginInfo | None:
        """The blocked plugin that registers ``name`` of ``kind``, or None."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                everything = load_plugins(extra=self.blocked_objects, disabled=())
            except PluginError:
                return None
        try:
            plugin = everything.registry.entry(kind, name).plugin
        except (UnknownComponentError, ValueError):
            return None
        return next((info for info in self.blocked if info.name == plugin), None)


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
    blocked_by = f"{DISABLE_ENV}={os.environ.get(DISABLE_ENV, '')}" if disabled is None else f"disabled={sorted(blocked)}"
    blocked_infos: list[PluginInfo] = []
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
                blocked_infos.append(info)
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

    blocked_objects = []
    for name, obj in extra:
        if name not in blocked:
            register(obj, PluginInfo(name), from_code=True)
        else:
            blocked_infos.append(PluginInfo(name))
            blocked_objects.append(obj)

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

    registry = PluginRegistry(blocked_infos, blocked_by, blocked_objects)
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


#: plain data that is never a component: given as a spec, the error lists the accepted spec forms
_DATA = (list, Mapping, set, frozenset, numbers.Number, bytes, type(None))


def _is_spec_tuple(spec: tuple) -> bool:
    """(name, parameters) or (name, parameters, label)."""
    return (
        len(spec) in (2, 3) and isinstance(spec[0], str) and isinstance(spec[1], Mapping) and (len(spec) == 2 or isinstance(spec[2], str))
    )


def _spec_error(kind: str, spec) -> TypeError:
    """The TypeError of a spec of none of the accepted forms: the forms, what was got, and a hint for a near miss."""
    hint = "; a list is not a spec: write a tuple" if isinstance(spec, list) else ""
    if isinstance(spec, (list, tuple)) and len(spec) >= 2 and isinstance(spec[0], str) and not isinstance(spec[1], Mapping):
        hint = f"; the parameters go in a mapping by name: ({spec[0]!r}, {{'parameter': value, …}})"
    return TypeError(
        f"{kind}: expected a registered name, (name, {{parameters}}), (name, {{parameters}}, label) or a"
        f" {KINDS[kind].interface.__name__} object, got {type(spec).__name__} {spec!r}{hint}"
    )


def resolve(kind: str, spec, registry: Registry | None = None):
    """A component of ``kind`` from an object, a name, ``(name, parameters)`` or ``(name, parameters, label)``
    (:meth:`Registry.resolve` on the default registry when ``registry`` is None).

    A spec of none of these forms (a list, a tuple of another shape, a number, a mapping, None) is a TypeError
    listing the accepted forms and naming what was got; an object of the wrong type names what it lacks."""
    if kind in KINDS and not isinstance(spec, KINDS[kind].interface):
        if isinstance(spec, _DATA) or (isinstance(spec, tuple) and not _is_spec_tuple(spec)):
            raise _spec_error(kind, spec)
        if not isinstance(spec, (str, tuple)):
            return require(spec, KINDS[kind].interface, kind)  # an object needs no registry
    return registry_or_default(registry).resolve(kind, spec)
