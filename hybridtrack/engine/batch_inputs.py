"""The inputs of R runs done together: per-sensor measurements, times, priors and recorders checked and stacked.

What every batched algorithm (:mod:`hybridtrack.algorithms.known_switch`,
:mod:`hybridtrack.algorithms.unknown_change`, :mod:`hybridtrack.algorithms.known_modes`)
takes: measurements (R, K+1, m) per sensor, times (K+1,) shared or (R, K+1) per run,
one prior or one per run, recorders by run index.  A single run is R = 1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hybridtrack.core.interfaces import Estimator
from hybridtrack.core.types import Gaussian
from hybridtrack.core.validation import as_float_array
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_intervals


def batch_measurements(network: SensorNetwork, measurements: Mapping[str, np.ndarray]) -> np.ndarray:
    """Stack per-sensor arrays (runs, K+1, m_i) into z (runs, K+1, Σm), checking names and shapes."""
    if not isinstance(measurements, Mapping):
        raise TypeError(f"measurements: expected a mapping sensor name → (runs, K+1, m) array, got {type(measurements).__name__}")
    arrays = {name: np.asarray(value, dtype=float) for name, value in measurements.items()}
    for name, value in arrays.items():
        if value.ndim != 3:
            raise ValueError(f"measurements[{name!r}]: expected shape (runs, K+1, m), got {value.shape}")
    runs = {value.shape[0] for value in arrays.values()}
    if len(runs) != 1 or 0 in runs:
        raise ValueError(f"measurements: every sensor needs the same positive number of runs, got {sorted(runs)}")
    R = runs.pop()
    return np.stack([network.stack({name: value[r] for name, value in arrays.items()}) for r in range(R)])


def batch_times(times, tau: float | None, runs: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(t (runs, K+1), Δt (runs, K)) from ``times`` (K+1,) shared, (runs, K+1) per run, or None (τ)."""
    if times is None or np.ndim(times) == 1:
        t, dt = step_intervals(None if times is None else np.asarray(times, dtype=float), tau, steps)
        return np.broadcast_to(t, (runs, steps)), np.broadcast_to(dt, (runs, max(steps - 1, 0)))
    times = np.asarray(times, dtype=float)
    if times.shape != (runs, steps):
        raise ValueError(f"times: expected shape ({steps},) shared or ({runs}, {steps}) per run, got {times.shape}")
    pairs = [step_intervals(times[r], tau, steps) for r in range(runs)]
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def batch_prior(prior, runs: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-run prior means (runs, n) and covariances (runs, n, n) from one Gaussian (or (mean, cov)),
    or per-run means (runs, n) with a shared (n, n) or per-run (runs, n, n) covariance."""
    if isinstance(prior, Gaussian):
        mean, cov = prior.mean, prior.cov
    elif isinstance(prior, Sequence) and len(prior) == 2:
        mean, cov = prior
    else:
        raise TypeError(f"prior: expected a Gaussian or (means, covs), got {type(prior).__name__}")
    mean, cov = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
    if mean.ndim == 1:
        mean = np.broadcast_to(mean, (runs,) + mean.shape)
    if cov.ndim == 2:
        cov = np.broadcast_to(cov, (runs,) + cov.shape)
    mean = as_float_array(mean, "prior mean", (runs, n))
    cov = as_float_array(cov, "prior cov", (runs, n, n))
    return mean, cov


def per_run(value, runs: int, name: str) -> list:
    """``value`` split into one item per run: None → [None] * runs; otherwise a sequence of length ``runs``."""
    if value is None:
        return [None] * runs
    items = list(value)
    if len(items) != runs:
        raise ValueError(f"{name}: expected one entry per run ({runs}), got {len(items)}")
    return items


def check_recorders(recorders, runs: int) -> dict[int, Any]:
    """``recorders`` as a dict run index → Recorder (indices in 0 … runs − 1)."""
    if recorders is None:
        return {}
    if not isinstance(recorders, Mapping):
        raise TypeError(f"recorders: expected a mapping run index → Recorder, got {type(recorders).__name__}")
    out = {}
    for key, recorder in recorders.items():
        if isinstance(key, bool) or not isinstance(key, (int, np.integer)) or not 0 <= key < runs:
            raise ValueError(f"recorders: expected run indices in 0 … {runs - 1}, got {key!r}")
        out[int(key)] = recorder
    return out


def batchable(estimator: Estimator) -> bool:
    """True when runs of ``estimator`` can share one bank: a centralized, non-sampling estimator
    (a decentralized one's node copies and a particle filter's streams stay per run)."""
    return not getattr(estimator, "sampling", False) and type(estimator).node_scores is Estimator.node_scores


def run_groups(estimator: Estimator, runs: int) -> list[np.ndarray]:
    """The runs that share one bank: all of them for a :func:`batchable` estimator, else each run alone
    (the same batched code, on a batch of one)."""
    return [np.arange(runs)] if batchable(estimator) else [np.array([r]) for r in range(runs)]
