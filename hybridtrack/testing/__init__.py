"""Contract checks for hybridtrack components, usable by any plugin's tests.

``check_motion_model``, ``check_sensor``, ``check_estimator``,
``check_detector``, ``check_solver``, ``check_algorithm`` (and
``check_component(kind, component)``) exercise the interface contracts of
:mod:`hybridtrack.core.interfaces` and :mod:`hybridtrack.core.algorithm` with small
generated inputs and raise ``AssertionError`` naming the component and the
broken rule.  ``build_example(factory)`` builds a component from its
``example_parameters``.  Installed with hybridtrack, the pytest plugin
:mod:`hybridtrack.testing.pytest_plugin` exposes them as the
``hybridtrack_contracts`` fixture.
"""

from hybridtrack.testing._reference import LinearPositionSensor, cv_transition, example_state
from hybridtrack.testing.contracts import (
    build_example,
    check_algorithm,
    check_algorithm_batch,
    check_component,
    check_detector,
    check_estimator,
    check_motion_model,
    check_sensor,
    check_solver,
    example_parameters,
)

__all__ = [
    "LinearPositionSensor",
    "build_example",
    "check_algorithm",
    "check_algorithm_batch",
    "check_component",
    "check_detector",
    "check_estimator",
    "check_motion_model",
    "check_sensor",
    "check_solver",
    "cv_transition",
    "example_parameters",
    "example_state",
]
