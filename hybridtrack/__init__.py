"""hybridtrack: estimation of hybrid (mode-switching) motion.

The kernel defines the interfaces (:mod:`hybridtrack.interfaces`), the value
types (:mod:`hybridtrack.types`) and the plugin system
(:mod:`hybridtrack.plugins`); algorithms are plugins found through the
``hybridtrack`` entry-point group.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

from hybridtrack.hookspecs import hookimpl
from hybridtrack.interfaces import (
    Detector,
    DetectorStep,
    Estimator,
    Innovation,
    LinearTransition,
    MotionModel,
    Sensor,
    Solution,
    Solver,
    TransitionBank,
)
from hybridtrack.plugins import get_registry, load_plugins
from hybridtrack.types import SEED001_TABLE1, Decision, Gaussian, Measurement, Schedule, Segment

try:
    __version__ = _version("hybridtrack")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"

__all__ = [
    "Decision",
    "Detector",
    "DetectorStep",
    "Estimator",
    "Gaussian",
    "Innovation",
    "LinearTransition",
    "Measurement",
    "MotionModel",
    "SEED001_TABLE1",
    "Schedule",
    "Segment",
    "Sensor",
    "Solution",
    "Solver",
    "TransitionBank",
    "__version__",
    "get_registry",
    "hookimpl",
    "load_plugins",
]
