"""hybridtrack-zigzag: an example third-party plugin.

It adds the ``weave`` motion mode, the ``info_kalman`` estimator, the
``cumulative_llr`` detector and the ``most_likely`` algorithm.  hybridtrack finds this module through the entry
point ``zigzag`` of the ``hybridtrack`` group (see ``pyproject.toml``) and
calls its hooks with a registry; nothing else ties it to hybridtrack.
"""

from hybridtrack import hookimpl
from hybridtrack_zigzag.algorithm import MostLikely
from hybridtrack_zigzag.detector import CumulativeLLR
from hybridtrack_zigzag.estimator import InfoKalman
from hybridtrack_zigzag.weave import Weave

__all__ = [
    "CumulativeLLR",
    "InfoKalman",
    "MostLikely",
    "Weave",
    "register_algorithms",
    "register_detectors",
    "register_estimators",
    "register_motion_models",
]


@hookimpl
def register_motion_models(registry):
    registry.add("weave", Weave)


@hookimpl
def register_estimators(registry):
    registry.add("info_kalman", InfoKalman)


@hookimpl
def register_detectors(registry):
    registry.add("cumulative_llr", CumulativeLLR)


@hookimpl
def register_algorithms(registry):
    registry.add("most_likely", MostLikely)
