"""The weave (serpentine) manoeuvre: heading oscillating sinusoidally about a mean course.

Heading ψ(t) = ψ̄ + A sin θ(t) with phase θ advancing at 2π/T, so the turn rate
is ω = A (2π/T) cos θ.  State ``(x, vx, y, vy, phase)``; over one step of τ
the phase advances by κ = 2πτ/T and the heading by

    Δ = A (sin(θ + κ) − sin θ),

the velocity is rotated by exactly Δ and the position follows the arc of a
coordinated turn at the mean rate Δ/τ (exact for the velocity, second order in
κ for the position):

    x⁺ = x + τ (vx s(Δ) − vy c(Δ)),    vx⁺ = vx cos Δ − vy sin Δ,
    y⁺ = y + τ (vx c(Δ) + vy s(Δ)),    vy⁺ = vx sin Δ + vy cos Δ,
    θ⁺ = θ + κ,

with s(Δ) = sin Δ / Δ and c(Δ) = (1 − cos Δ) / Δ (→ 1 and 0 as Δ → 0, taken
from their Taylor series near 0).  The speed is constant without noise.
Process noise: white acceleration on (vx, vy) through G = [τ²/2, τ] per axis
as in the straight mode, plus (3×3 ``noise_cov``) a random walk of the phase.
"""

from __future__ import annotations

import numpy as np

from hybridtrack import LinearTransition, MotionModel
from hybridtrack.core.validation import check_covariance

_SMALL = 1e-3  # below |Δ| the Taylor series of s, c and their derivatives are exact to rounding


def _arc_factors(delta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """s(Δ), c(Δ) and their derivatives s'(Δ), c'(Δ), elementwise."""
    delta = np.asarray(delta, dtype=float)
    small = np.abs(delta) < _SMALL
    d = np.where(small, 1.0, delta)  # a safe divisor where the series is used
    d2 = delta**2
    s = np.where(small, 1 - d2 / 6 + d2**2 / 120, np.sin(d) / d)
    c = np.where(small, delta / 2 - delta * d2 / 24, (1 - np.cos(d)) / d)
    ds = np.where(small, -delta / 3 + delta * d2 / 30, (d * np.cos(d) - np.sin(d)) / d**2)
    dc = np.where(small, 0.5 - d2 / 8 + d2**2 / 144, (d * np.sin(d) - (1 - np.cos(d))) / d**2)
    return s, c, ds, dc


class Weave(MotionModel):
    """Weave: heading ψ̄ + A sin θ, phase θ advancing at 2π/T (nonlinear, 5-state; hybridtrack-zigzag).

    ``amplitude`` A (rad, heading swing each side of the mean course),
    ``period`` T (s), ``noise_cov``: 2×2 (accelerations on vx, vy) or 3×3
    (plus the phase random walk, rad²/s²), default diag(0.01, 0.01, 1e-6).
    """

    name = "weave"
    layout = ("x", "vx", "y", "vy", "phase")
    linear = False

    def __init__(self, amplitude: float = 0.5, period: float = 20.0, noise_cov=None):
        for label, value in (("amplitude", amplitude), ("period", period)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{label}: expected a positive finite number, got {value!r}")
        self.amplitude = float(amplitude)
        self.period = float(period)
        noise_cov = np.diag([0.01, 0.01, 1e-6]) if noise_cov is None else noise_cov
        self.noise_cov = check_covariance(noise_cov, "noise_cov", readonly=True)
        if self.noise_cov.shape not in ((2, 2), (3, 3)):
            raise ValueError(f"noise_cov: expected shape (2, 2) or (3, 3), got {self.noise_cov.shape}")

    def _heading_change(self, phase, tau):
        kappa = 2 * np.pi * tau / self.period
        delta = self.amplitude * (np.sin(phase + kappa) - np.sin(phase))
        d_delta = self.amplitude * (np.cos(phase + kappa) - np.cos(phase))
        return kappa, delta, d_delta

    def propagate(self, x, tau, switch_state):
        """f(x) of the module docstring for x of shape (..., 5)."""
        x = np.asarray(x, dtype=float)
        px, vx, py, vy, phase = np.moveaxis(x, -1, 0)
        kappa, delta, _ = self._heading_change(phase, tau)
        s, c, _, _ = _arc_factors(delta)
        cos, sin = np.cos(delta), np.sin(delta)
        return np.stack(
            [px + tau * (vx * s - vy * c), vx * cos - vy * sin, py + tau * (vx * c + vy * s), vx * sin + vy * cos, phase + kappa],
            axis=-1,
        )

    def jacobian(self, x, tau) -> np.ndarray:
        """∂f/∂x at one state x (5,)."""
        px, vx, py, vy, phase = np.asarray(x, dtype=float)
        _, delta, d_delta = self._heading_change(phase, tau)
        s, c, ds, dc = _arc_factors(delta)
        cos, sin = np.cos(delta), np.sin(delta)
        vx_next, vy_next = vx * cos - vy * sin, vx * sin + vy * cos
        return np.array(
            [
                [1, tau * s, 0, -tau * c, tau * (vx * ds - vy * dc) * d_delta],
                [0, cos, 0, -sin, -vy_next * d_delta],
                [0, tau * c, 1, tau * s, tau * (vx * dc + vy * ds) * d_delta],
                [0, sin, 0, cos, vx_next * d_delta],
                [0, 0, 0, 0, 1],
            ],
            dtype=float,
        )

    def transition(self, tau, switch_state):
        """Linearization at the switching state: F = ∂f/∂x, B = f(x_s) − F x_s (interface contract)."""
        x_s = np.asarray(switch_state, dtype=float)
        F = self.jacobian(x_s, tau)
        B = self.propagate(x_s, tau, x_s) - F @ x_s
        axis = [tau**2 / 2, tau]
        G = np.zeros((5, self.noise_cov.shape[0]))
        G[0:2, 0] = axis
        G[2:4, 1] = axis
        if G.shape[1] == 3:
            G[4, 2] = tau
        return LinearTransition(F, B, G, self.noise_cov)
