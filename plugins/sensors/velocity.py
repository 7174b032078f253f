"""Velocity from a reported course and speed over ground (AIS, ADS-B, GPS receivers): z = (vx, vy) + w.

A receiver that reports its course over ground χ (clockwise from north) and
speed s gives the east/north velocity z = (s sin χ, s cos χ) =: (vx, vy), a
linear measurement of the state's ("vx", "vy") (H a selection, as for the
position sensor).  Its error is not isotropic: the receiver's velocity error
σ_s (m/s) in every direction, and the course error σ_χ (rad) across the track,
σ_χ |v| m/s, so

    R(x) = σ_s² I + σ_χ² |v|² u⊥ u⊥ᵀ = σ_s² I + σ_χ² (|v|² I − v vᵀ),

u⊥ the unit normal of the velocity v of the state (the linearized polar-to-
Cartesian error of the measured (s, χ); Bar-Shalom, Li & Kirubarajan,
*Estimation with Applications to Tracking and Navigation*, Wiley 2001, §10.4.3,
with (range, bearing) → (speed, course)).  At rest R = σ_s² I: the course of a
stopped object carries no information and this form gives it none.  The update
evaluates R(x) at each filter's predicted state (``Sensor.state_noise``).
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack_plugins.sensors.position import SelectionSensor


def _sigma(name: str, unit: str):
    def check(value):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name}: expected a finite number of {unit} ≥ 0, got {value!r}")
        return float(value)

    return check


@attrs.frozen
class VelocitySensor(SelectionSensor):
    """Linear sensor of ("vx", "vy") with the course/speed error shape R(x) of the module docstring:
    ``speed_sigma`` σ_s (m/s, > 0), ``course_sigma`` σ_χ (radians, ≥ 0)."""

    registry_name: ClassVar[str] = "velocity"
    linear: ClassVar[bool] = True
    components: ClassVar[tuple[str, ...]] = ("vx", "vy")

    name: str = "velocity"
    speed_sigma: float = attrs.field(default=0.1, converter=_sigma("speed_sigma", "m/s"))
    course_sigma: float = attrs.field(default=0.0, converter=_sigma("course_sigma", "radians"))

    def __attrs_post_init__(self):
        if self.speed_sigma <= 0:
            raise ValueError(f"speed_sigma: expected a finite number of m/s > 0, got {self.speed_sigma!r}")

    @property
    def noise_cov(self) -> np.ndarray:
        """σ_s² I: the state-independent part of R(x)."""
        return self.speed_sigma**2 * np.eye(2)

    @property
    def noise_depends_on_state(self) -> bool:
        return self.course_sigma > 0

    def state_noise(self, x, layout):
        """σ_χ² (|v|² I − v vᵀ) at x (..., n) → (..., 2, 2), the course part of R(x) (module docstring)."""
        v = np.asarray(x, dtype=float)[..., self.indices(layout)]
        speed2 = np.sum(v * v, axis=-1)[..., None, None]
        return self.course_sigma**2 * (speed2 * np.eye(2) - v[..., :, None] * v[..., None, :])

    def simulate(self, x, layout, rng):
        """z = v + σ_s w + σ_χ |v| w⊥ u⊥, w ~ N(0, I), w⊥ ~ N(0, 1): noise of covariance R(x) (module docstring)."""
        v = self.measure(x, layout)
        normal = np.stack([-v[..., 1], v[..., 0]], axis=-1)  # |v| u⊥
        across = self.course_sigma * rng.standard_normal(v.shape[:-1] + (1,))
        return v + self.speed_sigma * rng.standard_normal(v.shape) + across * normal


@hookimpl
def register_sensors(registry):
    registry.add(VelocitySensor.registry_name, VelocitySensor)
