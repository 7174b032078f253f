"""The mixing and merging steps of the interacting multiple model estimator over R runs, compiled by numba.

Over R runs of r model-matched estimates x̂_i, P_i (union layout, n) with ln μ_i (Bar-Shalom, Li & Kirubarajan
2001, §11.6.6, eqs. 11.6.6-6 to 11.6.6-10 and 11.6.6-13 to -17), in logarithms as
:mod:`hybridtrack.algorithms.multiple_model` keeps them:

* :func:`mix`: ln c̄_j = ln Σ_i π_ij μ_i and the start of model j's filter, the moment-matched mixture with
  μ_{i|j} ∝ π_ij μ_i: x̂_0j = Σ_i μ_{i|j} x̂_i, P_0j = ½(C + Cᵀ), C = Σ_i μ_{i|j} (P_i + (x̂_i − x̂_0j)(x̂_i − x̂_0j)ᵀ);
* :func:`merge`: ln μ_j = a_j − ln Σ_l exp(a_l) of a_j = ln Λ_j c̄_j, the total ln Σ_l exp(a_l) and the output
  x̂ = Σ_j μ_j x̂_j, P = ½(C + Cᵀ), C = Σ_j μ_j (P_j + (x̂_j − x̂)(x̂_j − x̂)ᵀ);
* :func:`merge_groups`: G groups of hypotheses h (each a multiple-model estimate with weight w_h ∝ exp(ln w_h),
  Σ_h w_h = 1 per group) merged into one multiple-model estimate each: per mode j, w_hj ∝ w_h μ_j^h normalized over
  h, μ_j ∝ Σ_h w_h μ_j^h, x̂_j = x̂_j^1 + Σ_h w_hj d_hj and P_j = ½(C + Cᵀ), C = Σ_h w_hj (P_j^h + d_hj d_hjᵀ) −
  δ_j δ_jᵀ about the group's first hypothesis (d_hj = x̂_j^h − x̂_j^1, δ_j = Σ_h w_hj d_hj: map-grid coordinates
  lose no digits), Λ_j = Σ_h w_hj Λ_j^h, ℓ = Σ_h w_h ℓ^h and the output the mixture over j as in ``merge``.

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
    """The compiled (mix, merge, merge_groups) of :mod:`._mixing_kernels`, imported (and numba with it) on first use."""
    from hybridtrack.engine import _mixing_kernels

    return _mixing_kernels.mix, _mixing_kernels.merge, _mixing_kernels.merge_groups


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


def merge_groups(group: np.ndarray, groups: int, log_weights, log_mode_probabilities, model_means, model_covs, model_loglik, loglik):
    """(ln μ (G, r), x̂_j (G, r, n), P_j (G, r, n, n), x̂ (G, n), P (G, n, n), Λ_j (G, r), ℓ (G,)) of H hypotheses in
    ``groups`` groups (``group`` (H,) the group of each, every group non-empty) with ln w (H,) and their ln μ (H, r),
    x̂_j (H, r, n), P_j (H, r, n, n), Λ_j (H, r), ℓ (H,) (module docstring)."""
    counts = np.bincount(group, minlength=groups)
    if counts.size != groups or (groups and counts.min() == 0):
        raise ValueError(f"group: expected every group in [0, {groups}) to hold at least one hypothesis, got counts {counts.tolist()}")
    H, r, n = np.shape(model_means)
    shapes = {"group": (H,), "log_weights": (H,), "log_mode_probabilities": (H, r), "model_covs": (H, r, n, n)}
    shapes |= {"model_loglik": (H, r), "loglik": (H,)}
    given = (group, log_weights, log_mode_probabilities, model_covs, model_loglik, loglik)
    wrong = [f"{name} {np.shape(a)} (expected {shape})" for (name, shape), a in zip(shapes.items(), given) if np.shape(a) != shape]
    if wrong:
        raise ValueError(f"merge_groups: for model_means of shape {(H, r, n)}, got " + ", ".join(wrong))
    order = np.argsort(group, kind="stable")
    starts = np.zeros(groups, dtype=np.intp)
    np.cumsum(counts[:-1], out=starts[1:])
    if not NUMBA_AVAILABLE:
        return _merge_groups_numpy(group, order, starts, log_weights, log_mode_probabilities, model_means, model_covs, model_loglik, loglik)
    log_mu, x, P = np.empty((groups, r)), np.empty((groups, r, n)), np.empty((groups, r, n, n))
    mean, cov, model_ll, ll = np.empty((groups, n)), np.empty((groups, n, n)), np.empty((groups, r)), np.empty(groups)
    inputs = (log_weights, log_mode_probabilities, model_means, model_covs, model_loglik, loglik)
    _kernels()[2](order, starts, counts, *(np.ascontiguousarray(a, dtype=float) for a in inputs), log_mu, x, P, mean, cov, model_ll, ll)
    return log_mu, x, P, mean, cov, model_ll, ll


def _merge_groups_numpy(group, order, starts, log_weights, log_p, model_means, model_covs, model_loglik, loglik):
    """:func:`merge_groups` in numpy (without numba)."""

    def per_group(values: np.ndarray) -> np.ndarray:  # Σ over each group's hypotheses (contiguous once sorted)
        return np.add.reduceat(values[order], starts, axis=0)

    log_w = log_weights[:, None] + log_p  # (H, r)
    top = np.maximum.reduceat(log_w[order], starts, axis=0)
    top = np.where(np.isfinite(top), top, 0.0)
    w = np.exp(log_w - top[group])  # scaled per group and mode
    total = per_group(w)
    first = order[starts]
    w = np.where((total > 0)[group], w / np.where(total > 0, total, 1.0)[group], 0.0)
    w[first] = np.where(total > 0, w[first], 1.0)  # a mode of probability zero: the first hypothesis' estimate
    with np.errstate(divide="ignore"):
        log_mu = top + np.log(total)
    log_mu = log_mu - logsumexp(log_mu, axis=1)[:, None]
    ref = model_means[first]  # (G, r, n)
    d = model_means - ref[group]
    shift = per_group(w[..., None] * d)
    second = per_group(w[..., None, None] * (model_covs + d[..., :, None] * d[..., None, :]))
    covs = second - shift[..., :, None] * shift[..., None, :]
    covs = 0.5 * (covs + np.swapaxes(covs, -1, -2))
    means = ref + shift
    mean, cov = mixture(log_mu, means, covs)
    return log_mu, means, covs, mean, cov, per_group(w * model_loglik), per_group(np.exp(log_weights) * loglik)
