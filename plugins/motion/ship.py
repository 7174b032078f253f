"""Nonlinear coordinated-turn ship model (SPEC §1, seed 003 eq. 1).

State s = (x, y, vx, vy, ω); with a = ωT:

    x⁺  = x + (vx sin a − vy (1 − cos a)) / ω      y⁺  = y + (vx (1 − cos a) + vy sin a) / ω
    vx⁺ = vx cos a − vy sin a                       vy⁺ = vx sin a + vy cos a          ω⁺ = ω

Written with s₁(a) = sin a / a and c₁(a) = (1 − cos a) / a = sin(a/2)·sinc(a/2):
x⁺ = x + T (vx s₁ − vy c₁), y⁺ = y + T (vx c₁ + vy s₁), which are smooth at
ω = 0 (the constant-velocity limit) and never divide by ω.  Their derivatives
use Taylor series for |a| < 10⁻² (where the closed forms cancel).

Process noise on the velocities (σ_v) and on ω (σ_ω) enters through the
Taylor-series gain Γ = [[T²/2,0,0],[0,T²/2,0],[T,0,0],[0,T,0],[0,0,T]], with
Q_w = diag(σ_v², σ_v², σ_ω²).
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import LinearTransition, MotionModel, TransitionBank
from hybridtrack.core.validation import as_float_array

SERIES_BELOW = 1e-2


def _s1(a):
    """sin a / a."""
    return np.sinc(a / np.pi)


def _c1(a):
    """(1 − cos a) / a = sin(a/2) · sin(a/2)/(a/2)."""
    return np.sin(a / 2.0) * np.sinc(a / (2.0 * np.pi))


def _ds1(a):
    """d/da (sin a / a) = (a cos a − sin a) / a²; series −a/3 + a³/30 − a⁵/840 near 0."""
    small = np.abs(a) < SERIES_BELOW
    safe = np.where(small, 1.0, a)
    a2 = a * a
    series = a * (-1.0 / 3.0 + a2 * (1.0 / 30.0 - a2 / 840.0))
    return np.where(small, series, (safe * np.cos(safe) - np.sin(safe)) / (safe * safe))


def _dc1(a):
    """d/da ((1 − cos a) / a) = (a sin a − 1 + cos a) / a²; series 1/2 − a²/8 + a⁴/144 near 0."""
    small = np.abs(a) < SERIES_BELOW
    safe = np.where(small, 1.0, a)
    a2 = a * a
    series = 0.5 + a2 * (-1.0 / 8.0 + a2 / 144.0)
    return np.where(small, series, (safe * np.sin(safe) - 1.0 + np.cos(safe)) / (safe * safe))


@attrs.frozen
class ShipTurn(MotionModel):
    """Nonlinear ship turn (x, y, vx, vy, ω) of seed 003; ``sigma_velocity`` σ_v (m/s²·s), ``sigma_rate`` σ_ω (rad/s²·s)."""

    name: ClassVar[str] = "ship_turn"
    layout: ClassVar[tuple[str, ...]] = ("x", "y", "vx", "vy", "omega")
    linear: ClassVar[bool] = False
    example_layout: ClassVar[tuple[str, ...]] = layout

    sigma_velocity: float = 0.1
    sigma_rate: float = 1e-3

    def __attrs_post_init__(self):
        for field in ("sigma_velocity", "sigma_rate"):
            value = getattr(self, field)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{field}: expected a finite number ≥ 0, got {value!r}")

    @property
    def noise_cov(self) -> np.ndarray:
        """Q_w = diag(σ_v², σ_v², σ_ω²)."""
        return np.diag([self.sigma_velocity**2, self.sigma_velocity**2, self.sigma_rate**2])

    @staticmethod
    def noise_gain(tau: float) -> np.ndarray:
        """Γ (5, 3) of SPEC §1."""
        T = float(tau)
        return np.array([[T * T / 2, 0, 0], [0, T * T / 2, 0], [T, 0, 0], [0, T, 0], [0, 0, T]], dtype=float)

    @staticmethod
    def f(x: np.ndarray, tau: float) -> np.ndarray:
        """The noise-free step f(x) for x of shape (..., 5)."""
        x = np.asarray(x, dtype=float)
        px, py, vx, vy, w = np.moveaxis(x, -1, 0)
        a = w * tau
        s1, c1, c, s = _s1(a), _c1(a), np.cos(a), np.sin(a)
        return np.stack([px + tau * (vx * s1 - vy * c1), py + tau * (vx * c1 + vy * s1), vx * c - vy * s, vx * s + vy * c, w], axis=-1)

    @staticmethod
    def jacobian(x: np.ndarray, tau: float) -> np.ndarray:
        """∂f/∂x at x (..., 5) → (..., 5, 5)."""
        x = np.asarray(x, dtype=float)
        _, _, vx, vy, w = np.moveaxis(x, -1, 0)
        T = tau
        a = w * T
        s1, c1, c, s, ds1, dc1 = _s1(a), _c1(a), np.cos(a), np.sin(a), _ds1(a), _dc1(a)
        J = np.zeros(x.shape[:-1] + (5, 5))
        J[..., 0, 0] = J[..., 1, 1] = J[..., 4, 4] = 1.0
        J[..., 0, 2], J[..., 0, 3] = T * s1, -T * c1
        J[..., 1, 2], J[..., 1, 3] = T * c1, T * s1
        J[..., 2, 2], J[..., 2, 3] = c, -s
        J[..., 3, 2], J[..., 3, 3] = s, c
        J[..., 0, 4] = T * T * (vx * ds1 - vy * dc1)
        J[..., 1, 4] = T * T * (vx * dc1 + vy * ds1)
        J[..., 2, 4] = T * (-vx * s - vy * c)
        J[..., 3, 4] = T * (vx * c - vy * s)
        return J

    def transition(self, tau: float, switch_state: np.ndarray) -> LinearTransition:
        """Linearization at switch_state: F = ∂f/∂x, B = f(x_s) − F x_s, G = Γ, Q = Q_w."""
        xs = as_float_array(switch_state, "switch_state", (5,))
        F = self.jacobian(xs, tau)
        return LinearTransition(F, self.f(xs, tau) - F @ xs, self.noise_gain(tau), self.noise_cov)

    def propagate(self, x: np.ndarray, tau: float, switch_state: np.ndarray | None = None) -> np.ndarray:
        """The exact nonlinear step f(x) (the switch state plays no role)."""
        return self.f(x, tau)

    def linearize(self, tau: float, x: np.ndarray) -> TransitionBank:
        """A bank linearized at every row of x (M, 5): F_m = ∂f/∂x(x_m), B_m = f(x_m) − F_m x_m (for the EKF)."""
        x = as_float_array(x, "x", (None, 5))
        F = self.jacobian(x, tau)
        B = self.f(x, tau) - np.einsum("mij,mj->mi", F, x)
        G = self.noise_gain(tau)
        M = x.shape[0]
        root = G @ np.diag([self.sigma_velocity, self.sigma_velocity, self.sigma_rate])
        Q = root @ root.T
        return TransitionBank(F, B, np.broadcast_to(Q, (M, 5, 5)), np.broadcast_to(root, (M, 5, 3)))

    def linearizer(self, tau: float):
        """``lambda x: self.linearize(tau, x)``: what ``ekf.predict`` takes to relinearize at each step."""
        return lambda x: self.linearize(tau, x)


@hookimpl
def register_motion_models(registry):
    registry.add(ShipTurn.name, ShipTurn)
