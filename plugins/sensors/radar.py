"""Radar: range ρ and azimuth θ with white noise (SPEC §2, seed 003 "measurement model").

Angle convention (seed 003: z = (ρ cos θ, ρ sin θ)): θ is measured from the
+x axis counter-clockwise, ρ and θ relative to the radar site (x_r, y_r).

* ``radar`` (:class:`RadarSensor`): converts each polar measurement to the
  Cartesian pseudo-measurement z = (x_r + ρ cos θ, y_r + ρ sin θ) — a linear
  sensor whose H selects ("x", "y") — with the converted covariance
  R(z) = J diag(σ_ρ², σ_θ²) Jᵀ, J = [[cos θ, −ρ sin θ], [sin θ, ρ cos θ]],
  evaluated at the measured (ρ, θ) (linearized conversion, Bar-Shalom, Li &
  Kirubarajan 2001 §1.7; accurate while ρ σ_θ² / σ_ρ ≪ 1).
  ``measurement_noise(z)`` returns it; ``noise_cov`` is the polar diag(σ_ρ², σ_θ²).
* ``radar_polar`` (:class:`PolarRadarSensor`): the nonlinear sensor
  h(x) = (ρ, θ) for extended filters, azimuth innovations wrapped to (−π, π].
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.validation import as_float_array, check_positive
from hybridtrack.sdk.linalg import wrap_angle


def _positions(x, layout: Sequence[str]):
    layout = tuple(layout)
    if "x" not in layout or "y" not in layout:
        raise ValueError(f"layout: radar needs components 'x' and 'y', got {layout}")
    x = np.asarray(x, dtype=float)
    return x[..., layout.index("x")], x[..., layout.index("y")]


_positive = lambda instance, attribute, value: check_positive(value, attribute.name)


@attrs.frozen
class _RadarBase(Sensor):
    name: str = "radar"
    range_std: float = attrs.field(default=10.0, validator=_positive)
    azimuth_std: float = attrs.field(default=float(np.deg2rad(0.2)), validator=_positive)
    site: tuple[float, float] = attrs.field(
        default=(0.0, 0.0), converter=lambda s: tuple(float(v) for v in as_float_array(s, "site", (2,)))
    )

    @property
    def noise_cov(self) -> np.ndarray:
        """Polar noise diag(σ_ρ², σ_θ²)."""
        return np.diag([self.range_std**2, self.azimuth_std**2])

    def polar(self, x, layout: Sequence[str]) -> np.ndarray:
        """(ρ, θ) of states x (..., n) seen from the site."""
        return self.to_polar(np.stack(_positions(x, layout), axis=-1))

    def to_polar(self, z) -> np.ndarray:
        """(ρ, θ) of a position z (..., 2) (e.g. a pseudo-measurement) seen from the site."""
        z = np.asarray(z, dtype=float)
        dx, dy = z[..., 0] - self.site[0], z[..., 1] - self.site[1]
        return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx)], axis=-1)

    def simulate_polar(self, x, layout: Sequence[str], rng: np.random.Generator) -> np.ndarray:
        """(ρ, θ) + noise, θ wrapped to (−π, π]."""
        p = self.polar(x, layout)
        p = p + rng.standard_normal(p.shape) * np.array([self.range_std, self.azimuth_std])
        p[..., 1] = wrap_angle(p[..., 1])
        return p

    def to_cartesian(self, polar) -> np.ndarray:
        """z = site + (ρ cos θ, ρ sin θ) for polar (..., 2)."""
        polar = np.asarray(polar, dtype=float)
        rho, theta = polar[..., 0], polar[..., 1]
        return np.stack([self.site[0] + rho * np.cos(theta), self.site[1] + rho * np.sin(theta)], axis=-1)

    def converted_covariance(self, polar) -> np.ndarray:
        """R = J diag(σ_ρ², σ_θ²) Jᵀ at polar (..., 2) → (..., 2, 2)."""
        polar = np.asarray(polar, dtype=float)
        rho, theta = polar[..., 0], polar[..., 1]
        c, s = np.cos(theta), np.sin(theta)
        sr2, st2 = self.range_std**2, (rho * self.azimuth_std) ** 2
        R = np.empty(polar.shape[:-1] + (2, 2))
        R[..., 0, 0] = sr2 * c * c + st2 * s * s
        R[..., 1, 1] = sr2 * s * s + st2 * c * c
        R[..., 0, 1] = R[..., 1, 0] = (sr2 - st2) * s * c
        return R


@attrs.frozen
class RadarSensor(_RadarBase):
    """Radar as Cartesian pseudo-measurements z = (x, y) with the converted covariance R(z)."""

    registry_name: ClassVar[str] = "radar"
    linear: ClassVar[bool] = True

    def measure(self, x, layout):
        return np.stack(_positions(x, layout), axis=-1)

    def jacobian(self, x, layout):
        layout = tuple(layout)
        _positions(np.zeros(len(layout)), layout)
        H = np.zeros((2, len(layout)))
        H[0, layout.index("x")] = H[1, layout.index("y")] = 1.0
        return np.broadcast_to(H, np.shape(x)[:-1] + H.shape).copy()

    def measurement_noise(self, z) -> np.ndarray:
        """The converted covariance at the measured (ρ, θ) recovered from z."""
        return self.converted_covariance(self.to_polar(z))

    def simulate(self, x, layout, rng):
        """Polar measurement with noise, converted to Cartesian."""
        return self.to_cartesian(self.simulate_polar(x, layout, rng))


@attrs.frozen
class PolarRadarSensor(_RadarBase):
    """Radar as the nonlinear sensor h(x) = (ρ, θ) (for extended filters); ν_θ wrapped to (−π, π]."""

    registry_name: ClassVar[str] = "radar_polar"
    linear: ClassVar[bool] = False

    def measure(self, x, layout):
        return self.polar(x, layout)

    def jacobian(self, x, layout):
        """∂(ρ, θ)/∂(x, y) = [[Δx/ρ, Δy/ρ], [−Δy/ρ², Δx/ρ²]], zero elsewhere."""
        layout = tuple(layout)
        px, py = _positions(x, layout)
        dx, dy = px - self.site[0], py - self.site[1]
        r2 = dx * dx + dy * dy
        r = np.sqrt(r2)
        J = np.zeros(np.shape(px) + (2, len(layout)))
        ix, iy = layout.index("x"), layout.index("y")
        J[..., 0, ix], J[..., 0, iy] = dx / r, dy / r
        J[..., 1, ix], J[..., 1, iy] = -dy / r2, dx / r2
        return J

    def residual(self, z, z_pred):
        nu = np.asarray(z, dtype=float) - z_pred
        nu[..., 1] = wrap_angle(nu[..., 1])
        return nu

    def simulate(self, x, layout, rng):
        return self.simulate_polar(x, layout, rng)


@hookimpl
def register_sensors(registry):
    for sensor in (RadarSensor, PolarRadarSensor):
        registry.add(sensor.registry_name, sensor)
