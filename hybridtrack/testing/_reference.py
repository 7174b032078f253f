"""Small reference objects the contract checks are built on (the straight mode of SPEC §1, a linear position
sensor, the Kalman oracle every exact estimator must match, example states and innovations).

They depend on the kernel and the sdk only (never on plugins), so a check of an estimator or a detector means
the same thing whichever plugins are installed.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg

from hybridtrack.core.interfaces import Innovation, LinearTransition, Sensor
from hybridtrack.core.validation import check_covariance
from hybridtrack.sdk import kalman_reference
from hybridtrack.sdk.estimation import empty_innovation
from hybridtrack.sdk.linalg import gaussian_scores

CV_LAYOUT = ("x", "vx", "y", "vy")

#: (centre, spread) of generated values, by the first letters of a component name
_SCALES = (
    (("omega", "w", "turn_rate"), (0.05, 0.02)),
    (("v",), (10.0, 3.0)),
    (("a",), (0.0, 1.0)),
    (("x", "y", "z"), (100.0, 30.0)),
)


def cv_transition(tau: float = 1.0, q: float = 0.1) -> LinearTransition:
    """Straight mode: F = blockdiag([[1, τ], [0, 1]] ×2), B = 0, G = [[τ²/2, 0], [τ, 0], [0, τ²/2], [0, τ]], Q = q I₂."""
    axis = np.array([[1.0, tau], [0.0, 1.0]])
    gain = np.array([[tau**2 / 2], [tau]])
    return LinearTransition(scipy.linalg.block_diag(axis, axis), np.zeros(4), scipy.linalg.block_diag(gain, gain), q * np.eye(2))


def example_state(layout: Sequence[str], rng: np.random.Generator, shape: tuple[int, ...] = ()) -> np.ndarray:
    """Random states of ``layout`` with magnitudes chosen by component name.

    Positions ≈ 100 ± 30 m (away from the origin, where bearings are singular),
    velocities 10 ± 3 m/s (a non-zero speed, which turns need), accelerations
    0 ± 1 m/s², turn rates 0.05 ± 0.02 rad/s, anything else 0 ± 1.
    """
    state = np.empty(shape + (len(layout),))
    for j, name in enumerate(layout):
        centre, spread = next((values for prefixes, values in _SCALES if name.startswith(prefixes)), (0.0, 1.0))
        state[..., j] = centre + spread * rng.uniform(-1.0, 1.0, size=shape)
    return state


class LinearPositionSensor(Sensor):
    """z = H x + v with H picking the named ``components`` of the state (a ``position``-like sensor).

    Used by the estimator checks so they need no sensor plugin; it is itself a
    valid :class:`~hybridtrack.core.interfaces.Sensor` (and passes ``check_sensor``).
    """

    registry_name = "contract_position"

    def __init__(self, name: str = "contract", components: Sequence[str] = ("x", "y"), noise_cov=None):
        self.name = name
        self.components = tuple(components)
        m = len(self.components)
        self.noise_cov = check_covariance(np.eye(m) if noise_cov is None else noise_cov, "noise_cov", m, definite=True)

    def matrix(self, layout: Sequence[str]) -> np.ndarray:
        """H of shape (m, n) for ``layout``."""
        layout = tuple(layout)
        H = np.zeros((len(self.components), len(layout)))
        for i, component in enumerate(self.components):
            if component not in layout:
                raise ValueError(f"layout: sensor {self.name!r} measures {component!r}, absent from {layout}")
            H[i, layout.index(component)] = 1.0
        return H

    def measure(self, x, layout):
        return np.asarray(x, dtype=float) @ self.matrix(layout).T

    def jacobian(self, x, layout):
        H = self.matrix(layout)
        return np.broadcast_to(H, np.shape(x)[:-1] + H.shape).copy()


def kalman_update(
    mean: np.ndarray, cov: np.ndarray, z: np.ndarray, sensors: Sequence[Sensor], layout: Sequence[str]
) -> tuple[np.ndarray, np.ndarray, Innovation]:
    """:func:`hybridtrack.sdk.kalman_reference.update` with the sensors whose rows of ``z`` hold no NaN."""
    parts = np.split(np.asarray(z, dtype=float), np.cumsum([sensor.measurement_dim for sensor in sensors]))
    used = [(part, sensor) for part, sensor in zip(parts, sensors) if not np.isnan(part).any()]
    if not used:
        return mean, cov, empty_innovation(mean.shape[0])
    H = np.concatenate([sensor.jacobian(mean, layout) for _, sensor in used], axis=-2)  # (M, m, n)
    R = scipy.linalg.block_diag(*(sensor.noise_cov for _, sensor in used))
    mean, cov, nu, S, loglik, nis = kalman_reference.update(mean, cov, np.concatenate([part for part, _ in used]), H, R)
    return mean, cov, Innovation(nu, S, loglik, nis)


def random_innovations(rng: np.random.Generator, steps: int = 20, bank_size: int = 3, measurement_dim: int = 2) -> list[Innovation]:
    """Innovations of a bank: filter 0 consistent (ν ~ N(0, S)), the others biased, as a detector would see."""
    out = []
    base = np.array([[4.0, 1.0], [1.0, 3.0]])[:measurement_dim, :measurement_dim] if measurement_dim <= 2 else np.eye(measurement_dim)
    S = np.stack([base * (1.0 + 0.5 * j) for j in range(bank_size)])
    L = np.linalg.cholesky(S)
    bias = np.linspace(0.0, 3.0, bank_size)[:, None] * np.ones(measurement_dim)
    for _ in range(steps):
        nu = np.einsum("mij,mj->mi", L, rng.standard_normal((bank_size, measurement_dim))) + bias
        loglik, nis = gaussian_scores(nu, L)
        out.append(Innovation(nu, S.copy(), loglik, nis))
    return out
