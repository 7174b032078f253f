"""Linear position sensor: z = H x + v, v ~ N(0, R) (SPEC §2; seed 000, measurement model).

H selects state components by name, so the same sensor serves the 4-state
layout ("x", "vx", "y", "vy") — H = [[1,0,0,0],[0,0,1,0]] for (x, y),
[1,0,0,0] for x only — and the 6-state constant-acceleration layout, where it
picks positions 0 and 3.  Several sensors with their own ``name`` (node id),
components and R form an N-node network (:class:`hybridtrack.sdk.network.SensorNetwork`).

``time_jitter`` σ_t (seconds, default 0): the fix is stamped with a time off by
δt ~ N(0, σ_t²) (ADS-B and AIS receivers stamp on receipt), so it lies v δt
along the track from where the object was: z = H x + v δt + w, and R(x) =
R + σ_t² v vᵀ with v the velocity components ("vx", "vy" for ("x", "y")) of
the state — an along-track error growing with the speed (|v| σ_t: 20 m at
200 m/s and 0.1 s), the cross-track error R alone.  The update evaluates it at
each filter's predicted state (``Sensor.state_noise``).
"""

from __future__ import annotations

from abc import abstractmethod
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


class SelectionSensor(Sensor):
    """A linear sensor whose z is the state's named ``components`` (H a selection): what the position sensor and the
    velocity sensor (``velocity.py``) share; a subclass gives ``name``, ``components`` and R (``noise_cov``)."""

    @property
    @abstractmethod
    def noise_cov(self) -> np.ndarray:
        """R (m, m)."""

    def indices(self, layout: Sequence[str]) -> list[int]:
        """Indices of the measured components in ``layout`` (H as a selection)."""
        layout = tuple(layout)
        missing = [c for c in self.components if c not in layout]
        if missing:
            raise ValueError(f"sensor {self.name!r} measures {missing} not in the state layout {layout}")
        return [layout.index(c) for c in self.components]

    def matrix(self, layout: Sequence[str]) -> np.ndarray:
        """H (m, n): row i selects component ``components[i]`` of ``layout``."""
        H = np.zeros((len(self.components), len(tuple(layout))))
        H[np.arange(len(self.components)), self.indices(layout)] = 1.0
        return H

    def measure(self, x, layout):
        return np.asarray(x, dtype=float)[..., self.indices(layout)]

    def jacobian(self, x, layout):
        x = np.asarray(x, dtype=float)
        return np.broadcast_to(self.matrix(layout), x.shape[:-1] + (len(self.components), len(tuple(layout)))).copy()


@attrs.frozen
class PositionSensor(SelectionSensor):
    """Linear sensor measuring the named state components (default ``("x", "y")``) with noise R."""

    registry_name: ClassVar[str] = "position"
    linear: ClassVar[bool] = True

    name: str = "position"
    components: tuple[str, ...] = attrs.field(default=("x", "y"), converter=_components)
    noise_cov: np.ndarray = attrs.field(default=None, eq=attrs.cmp_using(eq=np.array_equal))
    time_jitter: float = attrs.field(default=0.0, converter=float, kw_only=True)

    def __attrs_post_init__(self):
        m = len(self.components)
        R = np.diag(np.full(m, 0.01)) if self.noise_cov is None else self.noise_cov
        object.__setattr__(self, "noise_cov", check_covariance(R, "noise_cov", m, definite=True, readonly=True))
        if not (np.isfinite(self.time_jitter) and self.time_jitter >= 0):
            raise ValueError(
                f"time_jitter: expected the σ of the time-stamp error in seconds, a finite number ≥ 0, got {self.time_jitter!r}"
            )

    @property
    def noise_depends_on_state(self) -> bool:
        return self.time_jitter > 0

    def velocity_indices(self, layout: Sequence[str]) -> list[int]:
        """Where the rate of each measured component ("v" + name: "vx" for "x") stands in ``layout``."""
        layout = tuple(layout)
        rates = ["v" + c for c in self.components]
        missing = [r for r in rates if r not in layout]
        if missing:
            raise ValueError(f"sensor {self.name!r}: time_jitter needs the velocities {missing}, not in the state layout {layout}")
        return [layout.index(r) for r in rates]

    def state_noise(self, x, layout):
        """σ_t² v vᵀ at x (..., n) → (..., m, m) (module docstring)."""
        v = (
            np.asarray(x, dtype=float)[..., self.velocity_indices(layout)]
            if self.time_jitter > 0
            else np.zeros(np.shape(x)[:-1] + (len(self.components),))
        )
        return self.time_jitter**2 * v[..., :, None] * v[..., None, :]

    def simulate(self, x, layout, rng):
        """z = H x + v δt + w, δt ~ N(0, σ_t²), w ~ N(0, R) (module docstring)."""
        z = super().simulate(x, layout, rng)
        if self.time_jitter > 0:
            v = np.asarray(x, dtype=float)[..., self.velocity_indices(layout)]
            z = z + v * (self.time_jitter * rng.standard_normal(v.shape[:-1] + (1,)))
        return z


@hookimpl
def register_sensors(registry):
    registry.add(PositionSensor.registry_name, PositionSensor)
