"""hybridtrack-zigzag: an example third-party plugin adding the ``weave`` motion mode.

hybridtrack finds this module through the entry point ``zigzag`` of the
``hybridtrack`` group (see ``pyproject.toml``) and calls its hooks with a
registry; nothing else ties it to hybridtrack.
"""

from hybridtrack import hookimpl
from hybridtrack_zigzag.weave import Weave

__all__ = ["Weave", "register_motion_models"]


@hookimpl
def register_motion_models(registry):
    registry.add("weave", Weave)
