"""What the algorithms on a :class:`~hybridtrack.engine.bank.FilterBank` take for R runs, stacked for the bank.

The checks are :mod:`hybridtrack.engine.batch`'s (measurements sensor name →
(R, K+1, m_i), times, priors, values per run); here the measurements become one
array z (R, K+1, Σm) in the network's order, the priors arrays, and the runs are
grouped into the banks they can share (:func:`run_groups`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hybridtrack.core.interfaces import Estimator
from hybridtrack.core.types import Gaussian
from hybridtrack.engine.batch import batch_measurements, batch_priors
from hybridtrack.sdk.network import SensorNetwork


def stacked_measurements(network: SensorNetwork, measurements: Mapping[str, np.ndarray]) -> np.ndarray:
    """z (R, K+1, Σm): every sensor's (R, K+1, m_i) array side by side in the network's order (names and m checked)."""
    arrays, runs, steps = batch_measurements(measurements)
    flat = network.stack({name: value.reshape(runs * steps, *value.shape[2:]) for name, value in arrays.items()})
    return flat.reshape(runs, steps, -1)


def prior_arrays(prior, runs: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-run prior means (R, n) and covariances (R, n, n) from one Gaussian (or (mean, cov)), or per-run means
    (R, n) with a shared (n, n) or per-run (R, n, n) covariance."""
    if not isinstance(prior, Gaussian) and isinstance(prior, (tuple, list)) and len(prior) == 2:
        mean, cov = np.asarray(prior[0], dtype=float), np.asarray(prior[1], dtype=float)
        if mean.ndim == 2 and cov.ndim == 2:
            prior = (mean, np.broadcast_to(cov, (mean.shape[0],) + cov.shape))
    priors = batch_priors(prior, runs)
    if priors[0].mean.shape != (n,):
        raise ValueError(f"prior: expected a mean of the {n} state components, got shape {priors[0].mean.shape}")
    return np.stack([p.mean for p in priors]), np.stack([p.cov for p in priors])


def batchable(estimator: Estimator) -> bool:
    """True when runs of ``estimator`` can share one bank: a centralized, non-sampling estimator
    (a decentralized one's node copies and a particle filter's streams stay per run)."""
    return not getattr(estimator, "sampling", False) and type(estimator).node_scores is Estimator.node_scores


def run_groups(estimator: Estimator, runs: int) -> list[np.ndarray]:
    """The runs that share one bank: all of them for a :func:`batchable` estimator, else each run alone
    (the same batched code, on a batch of one)."""
    return [np.arange(runs)] if batchable(estimator) else [np.array([r]) for r in range(runs)]
