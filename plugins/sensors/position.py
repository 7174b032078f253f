"""Linear position sensor: z = H x + v, v ~ N(0, R) (SPEC §2; seed 000, measurement model).

H selects state components by name, so the same sensor serves the 4-state
layout ("x", "vx", "y", "vy") — H = [[1,0,0,0],[0,0,1,0]] for (x, y),
[1,0,0,0] for x only — and the 6-state constant-acceleration layout, where it
picks positions 0 and 3.  Several sensors with their own ``name`` (node id),
components and R form an N-node network (:class:`hybridtrack.sdk.network.SensorNetwork`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.validation import check_covariance


def _components(value) -> tuple[str, ...]:
    value = (value,) if isinstance(value, str) else tuple(value)
    if not value or len(set(value)) != len(value) or not all(isinstance(c, str) and c for c in value):
        raise ValueError(f"components: expected distinct component names such as ('x', 'y'), got {value!r}")
    return value


@attrs.frozen
class PositionSensor(Sensor):
    """Linear sensor measuring the named state components (default ``("x", "y")``) with noise R."""

    registry_name: ClassVar[str] = "position"
    linear: ClassVar[bool] = True

    name: str = "position"
    components: tuple[str, ...] = attrs.field(default=("x", "y"), converter=_components)
    noise_cov: np.ndarray = attrs.field(default=None, eq=attrs.cmp_using(eq=np.array_equal))

    def __attrs_post_init__(self):
        m = len(self.components)
        R = np.diag(np.full(m, 0.01)) if self.noise_cov is None else self.noise_cov
        object.__setattr__(self, "noise_cov", check_covariance(R, "noise_cov", m, definite=True, readonly=True))

    def matrix(self, layout: Sequence[str]) -> np.ndarray:
        """H (m, n): row i selects component ``components[i]`` of ``layout``."""
        H = np.zeros((len(self.components), len(tuple(layout))))
        H[np.arange(len(self.components)), self.indices(layout)] = 1.0
        return H

    def indices(self, layout: Sequence[str]) -> list[int]:
        """Indices of the measured components in ``layout`` (H as a selection)."""
        layout = tuple(layout)
        missing = [c for c in self.components if c not in layout]
        if missing:
            raise ValueError(f"sensor {self.name!r} measures {missing} not in the state layout {layout}")
        return [layout.index(c) for c in self.components]

    def measure(self, x, layout):
        return np.asarray(x, dtype=float)[..., self.indices(layout)]

    def jacobian(self, x, layout):
        x = np.asarray(x, dtype=float)
        return np.broadcast_to(self.matrix(layout), x.shape[:-1] + (len(self.components), len(tuple(layout)))).copy()


@hookimpl
def register_sensors(registry):
    registry.add(PositionSensor.registry_name, PositionSensor)
