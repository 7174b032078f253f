"""Process noise in physical units per second: the discretized continuous white-noise models.

A state block (p, ṗ, …, p⁽ᵒ⁻¹⁾) of order o driven by white noise of power
spectral density q on its highest derivative has, over a step of Δt seconds,

    Q_ij(Δt) = q Δt^(2o−1−i−j) / ((o−1−i)! (o−1−j)! (2o−1−i−j)),   i, j = 0 … o−1

(Bar-Shalom, Li & Kirubarajan 2001, §6.2.2 eq. 6.2.2-12 for o = 2, §6.2.3 for
o = 3; FilterPy's ``Q_continuous_white_noise(dim=o, dt, spectral_density=q)``,
Stone Soup's ``ConstantVelocity(q)`` / ``ConstantAcceleration(q)``).  Order 1
is a random walk, Q = q Δt; order 2 the white-noise acceleration model,
Q = q [[Δt³/3, Δt²/2], [Δt²/2, Δt]], q in m²/s³; order 3 white-noise jerk, q in
m²/s⁵.  Q grows with Δt: a 200 s gap gets a hundred times the velocity
variance of a 2 s step, where a per-step Q gives both the same.

Mapping from the seeds' per-step noise (Q_p = σ² on the velocities of each
step of τ seconds, no position term): the same velocity variance per step is
q = σ²/τ; the continuous model adds the position terms q τ³/3 and q τ²/2 the
per-step model leaves out, so the seed experiments keep their per-step
``noise_cov`` and their numbers.
"""

from __future__ import annotations

import math

import numpy as np


def check_density(value, name: str, units: str) -> float:
    """A finite density ≥ 0 (0: no noise of that kind), else ``ValueError`` naming ``name`` and its units."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a noise density in {units} (a finite number ≥ 0), got {value!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name}: expected a noise density in {units} (a finite number ≥ 0), got {value!r}")
    return value


def white_noise_unit(dt, order: int = 2) -> np.ndarray:
    """Q(Δt) / q of one block of ``order`` (module docstring), shape (order, order), or (..., order, order) for an
    array of Δt."""
    if order not in (1, 2, 3):
        raise ValueError(f"order: expected 1 (random walk), 2 (white acceleration) or 3 (white jerk), got {order!r}")
    dt = np.asarray(dt, dtype=float)
    if not np.all(np.isfinite(dt) & (dt > 0)):
        raise ValueError(f"dt: expected step lengths in seconds, finite and > 0, got {dt!r}")
    i = np.arange(order)
    power = 2 * order - 1 - i[:, None] - i[None, :]
    factorial = np.array([math.factorial(k) for k in range(order)], dtype=float)[::-1]
    scale = 1.0 / (factorial[:, None] * factorial[None, :] * power)
    return dt[..., None, None] ** power * scale


def white_noise_covariance(dt, density: float, order: int = 2) -> np.ndarray:
    """Q(Δt) = q · :func:`white_noise_unit` (module docstring): one block of ``order`` driven by white noise of
    density q = ``density``."""
    return check_density(density, "density", "units²/s^(2·order−1)") * white_noise_unit(dt, order)


def white_noise_root(dt, order: int = 2) -> np.ndarray:
    """G(Δt) with G Gᵀ = Q(Δt)/q (the lower Cholesky factor of :func:`white_noise_unit`), so that a model gives
    G(Δt) and the constant noise covariance q I: its ``noise_cov`` stays what its transition's Q is."""
    unit = white_noise_unit(dt, order)
    try:
        return np.linalg.cholesky(unit)
    except np.linalg.LinAlgError:  # Q(Δt)/q underflowed: a step far too short for float64
        raise ValueError(_too_short(np.asarray(dt, dtype=float), order)) from None


def _too_short(dt: np.ndarray, order: int) -> str:
    """The message for a step whose Q(Δt)/q has no Cholesky factor in float64, with the shortest step that has one
    (bisection of log Δt between the step and 1 s; error path only)."""
    shortest = float(dt.min())

    def factors(t: float) -> bool:
        try:
            np.linalg.cholesky(white_noise_unit(t, order))
        except np.linalg.LinAlgError:
            return False
        return True

    low, high = math.log(shortest), 0.0
    for _ in range(60):
        middle = (low + high) / 2
        low, high = (low, middle) if factors(math.exp(middle)) else (middle, high)
    return (
        f"dt: a step Δt (tau) of {shortest!r} s is too short for white noise of order {order}: Q(Δt)/q (entries Δt … Δt^{2 * order - 1}) underflows"
        f" float64 and has no Cholesky factor; expected steps ≥ {math.exp(high):.3g} s"
    )
