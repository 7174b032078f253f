"""hybridtrack: estimation of hybrid (mode-switching) motion.

Layers, imports pointing downwards (``docs/architecture.md``): core ← sdk ←
engine ← algorithms ← recording / io ← apps ← cli.  The user surface is
importable from here: ``hookimpl`` at once, every other name on first use
(PEP 562), so a plugin importing :mod:`hybridtrack.core` loads nothing above
it.
"""

import importlib
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

from hybridtrack.core.hookspecs import hookimpl

#: name → module of the names imported on first use (PEP 562)
LAZY = {
    "Detector": "hybridtrack.core.interfaces",
    "DetectorStep": "hybridtrack.core.interfaces",
    "Estimator": "hybridtrack.core.interfaces",
    "Innovation": "hybridtrack.core.interfaces",
    "LinearTransition": "hybridtrack.core.interfaces",
    "MotionModel": "hybridtrack.core.interfaces",
    "Sensor": "hybridtrack.core.interfaces",
    "Solution": "hybridtrack.core.interfaces",
    "Solver": "hybridtrack.core.interfaces",
    "TransitionBank": "hybridtrack.core.interfaces",
    "Decision": "hybridtrack.core.types",
    "Gaussian": "hybridtrack.core.types",
    "Measurement": "hybridtrack.core.types",
    "SEED001_TABLE1": "hybridtrack.engine.schedule",
    "Schedule": "hybridtrack.engine.schedule",
    "Segment": "hybridtrack.engine.schedule",
    "get_registry": "hybridtrack.core.plugins",
    "load_plugins": "hybridtrack.core.plugins",
    "Pipeline": "hybridtrack.engine.pipeline",
    "simulate": "hybridtrack.engine.simulate",
    "simulate_trajectory": "hybridtrack.engine.simulate",
    "simulate_measurements": "hybridtrack.engine.simulate",
    "KnownSwitchAdaptive": "hybridtrack.algorithms.known_switch",
    "UnknownChangeAdaptive": "hybridtrack.algorithms.unknown_change",
    "MultipleModelEstimator": "hybridtrack.algorithms.multiple_model",
    "run_known_modes": "hybridtrack.algorithms.known_modes",
    "RerunRecorder": "hybridtrack.recording",
    "NullRecorder": "hybridtrack.recording",
    "read_measurement_file": "hybridtrack.io.measurement_files",
    "read_tracks": "hybridtrack.io.track_files",
    "label_track": "hybridtrack.apps.mode_labels",
    **dict.fromkeys(["gospa", "ospa", "gospa_over_time", "ospa_over_time", "track_quality"], "hybridtrack.engine.metrics"),
    "MultiTargetTracker": "hybridtrack.algorithms.multitarget.tracker",
}


def __getattr__(name: str):
    if name in LAZY:
        value = getattr(importlib.import_module(LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'hybridtrack' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(LAZY))


try:
    __version__ = _version("hybridtrack")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"

__all__ = [*LAZY, "__version__", "hookimpl"]  # noqa: F822  (the LAZY names resolve through __getattr__)
