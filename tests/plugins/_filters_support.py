"""Small inline models for the filter tests (independent of the motion/sensor plugins).

4-state layout ("x", "vx", "y", "vy"); SPEC §1 matrices written out here so the
filter tests do not depend on other plugins' code.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from hybridtrack.core.interfaces import LinearTransition, Sensor, TransitionBank

LAYOUT = ("x", "vx", "y", "vy")
G4 = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])


class MatrixSensor(Sensor):
    """z = H x + v with an explicit H (any H, not only a selection)."""

    kind: ClassVar[str] = "matrix_test"
    linear: ClassVar[bool] = True

    def __init__(self, H, R, name="s"):
        self.H = np.atleast_2d(np.asarray(H, dtype=float))
        self.noise_cov = np.atleast_2d(np.asarray(R, dtype=float))
        self.name = name

    def measure(self, x, layout):
        return np.asarray(x) @ self.H.T

    def jacobian(self, x, layout):
        x = np.asarray(x)
        return np.broadcast_to(self.H, x.shape[:-1] + self.H.shape).copy()


def position_sensor(R=None, components=("x", "y"), name="pos") -> MatrixSensor:
    idx = [LAYOUT.index(c) for c in components]
    H = np.zeros((len(idx), 4))
    H[np.arange(len(idx)), idx] = 1.0
    R = np.eye(len(idx)) * 0.01 if R is None else R
    return MatrixSensor(H, R, name)


def straight(tau=0.1, q=0.001) -> LinearTransition:
    A = np.array([[1.0, tau], [0.0, 1.0]])
    F = np.kron(np.eye(2), A)
    return LinearTransition(F, np.zeros(4), G4, np.eye(2) * q)


def turn(switch_state, radius, left=True, tau=0.1, q=0.001) -> LinearTransition:
    """SPEC §1 turn: per-axis harmonic oscillator about the turn centre fixed at the switch."""
    x, vx, y, vy = switch_state
    w = np.hypot(vx, vy) / radius
    c, s = np.cos(w * tau), np.sin(w * tau)
    A = np.array([[c, s / w], [-w * s, c]])
    F = np.kron(np.eye(2), A)
    sign = 1.0 if left else -1.0
    B = np.array(
        [
            (x - sign * vy / w) * (1 - c),
            (w * x - sign * vy) * s,
            (y + sign * vx / w) * (1 - c),
            (w * y + sign * vx) * s,
        ]
    )
    return LinearTransition(F, B, G4, np.eye(2) * q)


def radii_bank(switch_state, n_radii=10, tau=0.1, q=0.001, r_min=1.0, r_max=10.0) -> list[LinearTransition]:
    """Seed 001 bank: straight + n left + n right turns, radii r_min…r_max."""
    radii = np.linspace(r_min, r_max, n_radii)
    return [straight(tau, q)] + [turn(switch_state, r, True, tau, q) for r in radii] + [turn(switch_state, r, False, tau, q) for r in radii]


def simulate(transition: LinearTransition, sensors, x0, steps, rng, runs=1):
    """Truth (runs, steps+1, n) from x0 and stacked measurements (runs, steps, Σm) of the linear model."""
    n = x0.shape[-1]
    Lq = np.linalg.cholesky(transition.Q)
    X = np.empty((runs, steps + 1, n))
    X[:, 0] = x0
    Z = []
    for k in range(steps):
        w = rng.standard_normal((runs, transition.Q.shape[0])) @ Lq.T
        X[:, k + 1] = X[:, k] @ transition.F.T + transition.B + w @ transition.G.T
        Z.append(np.concatenate([s.simulate(X[:, k + 1], LAYOUT, rng) for s in sensors], axis=-1))
    return X, np.stack(Z, axis=1)


def bank_of(transitions) -> TransitionBank:
    return TransitionBank.stack(list(transitions))


def random_spd(rng, n, scale=1.0):
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T / n + np.eye(n))
