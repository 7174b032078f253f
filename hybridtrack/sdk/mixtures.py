"""Log-sum-exp, normalized weights from log weights and the moment-matched Gaussian: the one implementation that
IMM/GPB, the adaptive banks' mixture estimate, Gaussian sums, PDA and the particle weights use."""

from __future__ import annotations

import numpy as np


def logsumexp(a: np.ndarray, axis: int = -1) -> np.ndarray:
    """ln Σ_i exp(a_i) along ``axis``: t + ln Σ_i exp(a_i − t), t = max_i a_i (−∞ for an all −∞ or empty slice).
    scipy.special.logsumexp's formula; scipy's array-API dispatch costs ≈ 57 µs a call on the small arrays the
    filters pass at every step, ≈ 2 µs here."""
    a = np.asarray(a, dtype=float)
    top = np.max(a, axis=axis, keepdims=True, initial=-np.inf)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return np.log(np.sum(np.exp(a - top), axis=axis)) + np.squeeze(top, axis=axis)


def normalized_weights(log_weights: np.ndarray, axis: int = -1) -> np.ndarray:
    """w_i = exp(ln w_i − ln Σ_j exp(ln w_j)) along ``axis``; an all −∞ slice gets equal weights.

    The equal weights only fill a slice whose result carries probability zero
    (e.g. the mixed estimate of a mode no mode can switch into), so any finite
    choice is exact.
    """
    log_weights = np.asarray(log_weights, dtype=float)
    top = np.max(log_weights, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    w = np.exp(log_weights - top)
    total = np.sum(w, axis=axis, keepdims=True)
    return np.where(total > 0, w / np.where(total > 0, total, 1.0), 1.0 / log_weights.shape[axis])


def moment_match(weights: np.ndarray, means: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Gaussian with the mixture's first two moments, over the component axis i:

        x̄ = Σ_i w_i x_i,   P̄ = Σ_i w_i (P_i + (x_i − x̄)(x_i − x̄)ᵀ)

    (Bar-Shalom, Li & Kirubarajan 2001, eqs. 11.6.6-9 and 11.6.6-10).  Shapes:
    weights (..., I) summing to one, means (..., I, n), covs (..., I, n, n) →
    (..., n), (..., n, n); the leading axes broadcast.
    """
    mean = np.einsum("...i,...in->...n", weights, means)
    d = means - mean[..., None, :]
    cov = np.einsum("...i,...inm->...nm", weights, covs) + np.einsum("...i,...in,...im->...nm", weights, d, d)
    return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2))


def mixture(log_weights: np.ndarray, means: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`moment_match` with w ∝ exp(``log_weights``) (..., I), normalized without overflow; −∞ drops a component."""
    return moment_match(normalized_weights(log_weights, -1), means, covs)
