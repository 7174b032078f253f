"""The component kinds, in one table: the registry's kind name, the hook that registers it, its interface.

The loader calls each kind's hook, the registry keeps one table per kind,
``hybridtrack plugins`` lists them and :mod:`hybridtrack.testing` checks them,
all from :data:`KINDS`.
"""

from __future__ import annotations

import attrs

from hybridtrack.core.algorithm import Algorithm
from hybridtrack.core.interfaces import Detector, Estimator, MotionModel, Sensor, Solver


@attrs.frozen
class Kind:
    """A component kind: ``name`` (the registry's), ``hook`` (``register_<kind>s(registry)``), ``interface``."""

    name: str
    hook: str
    interface: type


#: kind name → :class:`Kind`, in listing order
KINDS: dict[str, Kind] = {
    kind.name: kind
    for kind in (
        Kind("motion_model", "register_motion_models", MotionModel),
        Kind("sensor", "register_sensors", Sensor),
        Kind("estimator", "register_estimators", Estimator),
        Kind("detector", "register_detectors", Detector),
        Kind("solver", "register_solvers", Solver),
        Kind("algorithm", "register_algorithms", Algorithm),
    )
}
