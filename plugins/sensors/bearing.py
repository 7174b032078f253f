"""Bearing-only sensor: z = φ(x) + v, v ~ N(0, σ²), angles wrapped to (−π, π] (seed 002, §4.1).

The bearing of a target at (x, y) seen from an observer at (x̃, ỹ), with
Δx = x − x̃, Δy = y − ỹ, ρ² = Δx² + Δy²:

* ``convention="north"`` (default, the seed's definition: «пеленг – угол между
  севером и объектом», seed 002 §2): φ = atan2(Δx, Δy), measured clockwise from
  north (+y), x east, y north.  ∂φ/∂Δx = Δy/ρ², ∂φ/∂Δy = −Δx/ρ².
* ``convention="math"``: φ = atan2(Δy, Δx), counter-clockwise from +x; this is
  the seed's eq. (2) read with x as abscissa.  ∂φ/∂Δx = −Δy/ρ², ∂φ/∂Δy = Δx/ρ².

The two conventions are mirror images (swap x and y), so any result computed in
one holds in the other.  The functions below are the one place the bearing
maths lives; the bearings-only TMA solvers (``hybridtrack_plugins.solvers``)
import them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.validation import as_float_array, check_covariance
from hybridtrack.sdk.linalg import wrap_angle

CONVENTIONS = ("north", "math")


def check_convention(convention: str) -> str:
    if convention not in CONVENTIONS:
        raise ValueError(f"convention: expected one of {CONVENTIONS}, got {convention!r}")
    return convention


def angle_difference(a, b, out=None):
    """a − b wrapped to (−π, π] for a, b already in (−π, π] (two compares instead of a modulo)."""
    d = np.asarray(np.subtract(a, b, out=out, dtype=float))
    d[d > np.pi] -= 2.0 * np.pi
    d[d <= -np.pi] += 2.0 * np.pi
    return d


def bearing(dx, dy, convention: str = "north", out=None):
    """φ of the relative position (Δx, Δy) (arrays broadcast), in (−π, π]; ``out`` an optional buffer."""
    return np.arctan2(dx, dy, out=out) if convention == "north" else np.arctan2(dy, dx, out=out)


def bearing_gradient(dx, dy, convention: str = "north", out=None):
    """(∂φ/∂Δx, ∂φ/∂Δy) = (Δy, −Δx)/ρ² (north) or (−Δy, Δx)/ρ² (math).

    ``out`` optionally gives (p, q, work) buffers of the broadcast shape (hot loops reuse them).
    """
    if out is None:
        w = 1.0 / (dx * dx + dy * dy)
        return (dy * w, -dx * w) if convention == "north" else (-dy * w, dx * w)
    p, q, w = out
    np.multiply(dx, dx, out=w)
    np.multiply(dy, dy, out=p)
    w += p
    np.divide(-1.0, w, out=w)  # w = −1/ρ²
    if convention == "north":
        np.multiply(dx, w, out=q)
        np.multiply(dy, w, out=p)
        np.negative(p, out=p)
    else:
        np.multiply(dy, w, out=p)
        np.multiply(dx, w, out=q)
        np.negative(q, out=q)
    return p, q


def direction(phi, convention: str = "north"):
    """Unit vector (u_x, u_y) pointing along bearing φ: (sin φ, cos φ) north, (cos φ, sin φ) math."""
    phi = np.asarray(phi, dtype=float)
    if convention == "north":
        return np.sin(phi), np.cos(phi)
    return np.cos(phi), np.sin(phi)


@attrs.frozen
class BearingSensor(Sensor):
    """Bearing to the target from an observer at ``observer`` (shape (2,) or (..., 2), metres).

    ``sigma`` is the bearing noise standard deviation in radians (R = [[σ²]]).
    The observer moves: give its position per step, either by building one
    sensor per step with :meth:`at` or by passing an (..., 2) array that
    broadcasts with the state's leading shape (e.g. a whole trajectory (T, 2)
    against states (T, n)).  Any state layout naming ``"x"`` and ``"y"`` works.
    """

    registry_name: ClassVar[str] = "bearing"
    linear: ClassVar[bool] = False

    name: str = "bearing"
    sigma: float = attrs.field(default=np.deg2rad(0.5), converter=float)
    observer: np.ndarray = attrs.field(default=(0.0, 0.0), eq=attrs.cmp_using(eq=np.array_equal))
    convention: str = attrs.field(default="north", validator=lambda i, a, v: check_convention(v))
    noise_cov: np.ndarray = attrs.field(init=False, eq=False)

    def __attrs_post_init__(self):
        if not (np.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"sigma: expected a positive finite bearing noise (radians), got {self.sigma!r}")
        observer = as_float_array(self.observer, "observer", readonly=True)
        if observer.ndim < 1 or observer.shape[-1] != 2:
            raise ValueError(f"observer: expected shape (2,) or (..., 2), got {observer.shape}")
        object.__setattr__(self, "observer", observer)
        R = check_covariance([[self.sigma**2]], "noise_cov", 1, definite=True, readonly=True)
        object.__setattr__(self, "noise_cov", R)

    def at(self, observer) -> BearingSensor:
        """The same sensor with the observer at ``observer`` (one step of a moving observer)."""
        return attrs.evolve(self, observer=observer)

    @staticmethod
    def indices(layout: Sequence[str]) -> tuple[int, int]:
        layout = tuple(layout)
        if "x" not in layout or "y" not in layout:
            raise ValueError(f"bearing sensor needs 'x' and 'y' in the state layout, got {layout}")
        return layout.index("x"), layout.index("y")

    def _relative(self, x, layout):
        x = as_float_array(x, "x")
        ix, iy = self.indices(layout)
        return x, x[..., ix] - self.observer[..., 0], x[..., iy] - self.observer[..., 1]

    def measure(self, x, layout):
        """h(x) = φ(x − x̃, y − ỹ), shape (..., 1)."""
        _, dx, dy = self._relative(x, layout)
        return bearing(dx, dy, self.convention)[..., None]

    def jacobian(self, x, layout):
        """∂h/∂x, shape (..., 1, n): ∂φ/∂Δx in column "x", ∂φ/∂Δy in column "y", zeros elsewhere."""
        x, dx, dy = self._relative(x, layout)
        ix, iy = self.indices(layout)
        gx, gy = bearing_gradient(dx, dy, self.convention)
        H = np.zeros(np.broadcast_shapes(x.shape, dx.shape + (1,))[:-1] + (1, x.shape[-1]))
        H[..., 0, ix] = gx
        H[..., 0, iy] = gy
        return H

    def residual(self, z, z_pred):
        """ν = z − ẑ wrapped to (−π, π]."""
        return wrap_angle(np.asarray(z, dtype=float) - np.asarray(z_pred, dtype=float))

    def simulate(self, x, layout, rng):
        """z = φ(x) + v, v ~ N(0, σ²), wrapped to (−π, π]."""
        z = self.measure(x, layout)
        return wrap_angle(z + self.sigma * rng.standard_normal(z.shape))


@hookimpl
def register_sensors(registry):
    registry.add(BearingSensor.registry_name, BearingSensor)
