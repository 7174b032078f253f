"""pluggy hook specifications: one ``register_<kind>s(registry)`` hook per component kind, and ``register_commands``.

A plugin module implements any of them with :data:`hookimpl` (``docs/plugins.md`` §2); a kind's hook calls
``registry.add(name, factory)`` for each component it provides (``factory`` takes keyword parameters and returns
the component; kinds, hooks and interfaces: :data:`hybridtrack.core.kinds.KINDS`).  ``register_commands(commands)``
adds sub-commands to the ``hybridtrack`` command line (:class:`hybridtrack.core.commands.Commands`).
"""

import pluggy

PROJECT = "hybridtrack"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def register_motion_models(registry):
    """Register MotionModel factories."""


@hookspec
def register_sensors(registry):
    """Register Sensor factories."""


@hookspec
def register_estimators(registry):
    """Register Estimator factories."""


@hookspec
def register_detectors(registry):
    """Register Detector factories."""


@hookspec
def register_solvers(registry):
    """Register Solver factories."""


@hookspec
def register_algorithms(registry):
    """Register Algorithm factories (:class:`hybridtrack.core.algorithm.Algorithm`)."""


@hookspec
def register_commands(commands):
    """Add sub-commands of the command line: ``commands.add(name, help, configure, run)``."""
