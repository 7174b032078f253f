"""Contract checks for hybridtrack components, usable by any plugin's tests: :mod:`hybridtrack.testing.contracts`
(``check_<kind>``, ``check_component``, ``build_example``), the ``hybridtrack_contracts`` fixture of the pytest plugin
:mod:`hybridtrack.testing.pytest_plugin`."""

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
