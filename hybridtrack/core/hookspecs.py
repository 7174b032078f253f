"""pluggy hook specifications: one ``register_<kind>s(registry)`` hook per interface.

A plugin module implements any of them with :data:`hookimpl` and calls
``registry.add(name, factory)`` for each component it provides; ``factory``
is a class or callable that takes keyword parameters and returns the component.

    from hybridtrack import hookimpl

    @hookimpl
    def register_motion_models(registry):
        registry.add("zigzag", ZigZag)
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


#: hook name for each interface kind
HOOKS = {
    "motion_model": "register_motion_models",
    "sensor": "register_sensors",
    "estimator": "register_estimators",
    "detector": "register_detectors",
    "solver": "register_solvers",
}
