"""The mixing and merging steps of the interacting multiple model estimator over R runs, compiled by numba.

Over R runs of r model-matched estimates x̂_i, P_i (union layout, n) with ln μ_i (Bar-Shalom, Li & Kirubarajan
2001, §11.6.6, eqs. 11.6.6-6 to 11.6.6-10 and 11.6.6-13 to -17), in logarithms as
:mod:`hybridtrack.algorithms.multiple_model` keeps them:

* :func:`mix`: ln c̄_j = ln Σ_i π_ij μ_i and the start of model j's filter, the moment-matched mixture with
  μ_{i|j} ∝ π_ij μ_i: x̂_0j = Σ_i μ_{i|j} x̂_i, P_0j = ½(C + Cᵀ), C = Σ_i μ_{i|j} (P_i + (x̂_i − x̂_0j)(x̂_i − x̂_0j)ᵀ);
* :func:`merge`: ln μ_j = a_j − ln Σ_l exp(a_l) of a_j = ln Λ_j c̄_j, the total ln Σ_l exp(a_l) and the output
  x̂ = Σ_j μ_j x̂_j, P = ½(C + Cᵀ), C = Σ_j μ_j (P_j + (x̂_j − x̂)(x̂_j − x̂)ᵀ).

The arithmetic of :func:`~hybridtrack.sdk.mixtures.logsumexp`, ``normalized_weights`` and ``moment_match``
(t = max, ln Σ exp(a − t) + t; an all −∞ slice: ln c̄ = −∞ and equal weights), one run at a time in compiled
loops (equal to them to rounding: tests/engine/test_mixing.py); without numba those functions themselves.  The
kernels are compiled on first use and cached (``cache=True``).
"""

from __future__ import annotations

import functools
import importlib.util

import numpy as np

from hybridtrack.sdk.mixtures import logsumexp, mixture

#: numba is installed: the compiled kernels run (else the numpy functions of :mod:`hybridtrack.sdk.mixtures`)
NUMBA_AVAILABLE = importlib.util.find_spec("numba") is not None


@functools.cache
def _kernels():
    """The compiled (mix, merge) of :mod:`._mixing_kernels`, imported (and numba with it) on first use."""
    from hybridtrack.engine import _mixing_kernels

    return _mixing_kernels.mix, _mixing_kernels.merge


def mix(log_pi: np.ndarray, log_mu: np.ndarray, means: np.ndarray, covs: np.ndarray):
    """(ln c̄ (R, r), x̂_0 (R, r, n), P_0 (R, r, n, n)) of ln Π (1 or R, r, r), ln μ (R, r) and the models' x̂ (R, r, n),
    P (R, r, n, n) (module docstring)."""
    if not NUMBA_AVAILABLE:
        joint = log_pi + log_mu[:, :, None]
        x0, P0 = mixture(np.swapaxes(joint, 1, 2), means[:, None], covs[:, None])
        return logsumexp(joint, axis=1), x0, P0
    R, r, n = means.shape
    if np.shape(log_pi) not in ((1, r, r), (R, r, r)) or np.shape(log_mu) != (R, r) or np.shape(covs) != (R, r, n, n):
        raise ValueError(
            f"log_pi, log_mu, covs: expected shapes (1 or {R}, {r}, {r}), ({R}, {r}), ({R}, {r}, {n}, {n}) for means of shape"
            f" {means.shape}, got {np.shape(log_pi)}, {np.shape(log_mu)}, {np.shape(covs)}"
        )
    log_cbar, x0, P0 = np.empty((R, r)), np.empty((R, r, n)), np.empty((R, r, n, n))
    args = (np.ascontiguousarray(log_pi, dtype=float), np.ascontiguousarray(log_mu, dtype=float))
    _kernels()[0](*args, np.ascontiguousarray(means, dtype=float), np.ascontiguousarray(covs, dtype=float), log_cbar, x0, P0)
    return log_cbar, x0, P0


def merge(joint: np.ndarray, means: np.ndarray, covs: np.ndarray):
    """(ln μ (R, r), ln Σ_l exp(a_l) (R,), x̂ (R, n), P (R, n, n)) of a = ln Λ c̄ (R, r) and the models' x̂ (R, r, n),
    P (R, r, n, n) (module docstring)."""
    if not NUMBA_AVAILABLE:
        total = logsumexp(joint, axis=-1)
        log_mu = joint - total[:, None]
        return (log_mu, total, *mixture(log_mu, means, covs))
    R, r, n = means.shape
    if np.shape(joint) != (R, r) or np.shape(covs) != (R, r, n, n):
        raise ValueError(f"joint, covs: expected shapes ({R}, {r}), ({R}, {r}, {n}, {n}), got {np.shape(joint)}, {np.shape(covs)}")
    log_mu, total, mean, cov = np.empty((R, r)), np.empty(R), np.empty((R, n)), np.empty((R, n, n))
    joint = np.ascontiguousarray(joint, dtype=float)
    _kernels()[1](joint, np.ascontiguousarray(means, dtype=float), np.ascontiguousarray(covs, dtype=float), log_mu, total, mean, cov)
    return log_mu, total, mean, cov
