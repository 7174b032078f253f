"""Normalization through an empirical CDF and thresholds from simulated H0 quantiles (seed 003; SPEC §4 "GLR").

* ỹ = Φ⁻¹(F̂(y)): F̂ is the empirical CDF of a reference sample of the raw
  signal under H_0 (e.g. angular-rate estimates of a ship going straight), so
  ỹ ~ N(0, 1) under H_0.  F̂(y) = (#{y_i ≤ y} + ½)/(n + 1) keeps Φ⁻¹ finite.
* λ(α): the (1 − α) quantile of a detector statistic under H_0, estimated from
  ``runs`` seeded simulated N(0, 1) sequences of ``length`` steps after a
  ``burn_in`` (the per-step stationary distribution).  The sorted sample is
  cached per (statistic, parameters, seed, size), so λ(α) for any α — e.g. a
  dynamic threshold's α₁ — costs a lookup.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.special import ndtri

from hybridtrack.sdk.thresholds import check_probability


def sorted_sample(values, name: str, what: str) -> np.ndarray:
    """``values`` flattened, sorted and read-only; at least 10 finite values of ``what`` under H0, else
    ``ValueError`` naming ``name``."""
    sample = np.sort(np.asarray(values, dtype=float).reshape(-1))
    if sample.size < 10 or not np.all(np.isfinite(sample)):
        raise ValueError(f"{name}: expected at least 10 finite values of {what} under H0, got {sample.size}")
    sample.setflags(write=False)
    return sample


class EmpiricalNormalizer:
    """ỹ = Φ⁻¹(F̂(y)) with F̂ the empirical CDF of ``reference`` (1-D, at least 10 finite values)."""

    def __init__(self, reference):
        self.sorted = sorted_sample(reference, "reference", "the signal")

    def __call__(self, y):
        y = np.asarray(y, dtype=float)
        count = np.searchsorted(self.sorted, y, side="right")
        # Φ⁻¹ by scipy.special.ndtri (what norm.ppf computes, without its per-call overhead on scalars)
        return ndtri((count + 0.5) / (self.sorted.size + 1))


def glr_statistics(y: np.ndarray, window: int) -> np.ndarray:
    """g_n = max_{n−W<k≤n} (y_k + … + y_n)² / (2(n − k + 1)) for every n, y of shape (runs, steps) (seed 003 eq. 5)."""
    runs, steps = y.shape
    c = np.concatenate([np.zeros((runs, 1)), np.cumsum(y, axis=1)], axis=1)
    g = np.zeros((runs, steps))
    for length in range(1, window + 1):
        sums = c[:, length:] - c[:, :-length]  # window sums ending at n = length−1 … steps−1
        g[:, length - 1 :] = np.maximum(g[:, length - 1 :], sums * sums / (2.0 * length))
    return g


def cusum_statistics(y: np.ndarray, drift: float) -> np.ndarray:
    """Two-sided Page CUSUM g_n = max(g⁺_n, g⁻_n), g⁺ = max(0, g⁺ + y − κ), g⁻ = max(0, g⁻ − y − κ)."""
    runs, steps = y.shape
    up = down = np.zeros(runs)
    g = np.zeros((runs, steps))
    for n in range(steps):
        up = np.maximum(0.0, up + y[:, n] - drift)
        down = np.maximum(0.0, down - y[:, n] - drift)
        g[:, n] = np.maximum(up, down)
    return g


@lru_cache(maxsize=32)
def h0_sample(
    statistic: str, parameter: float, seed: int = 20240601, runs: int = 2000, length: int = 200, burn_in: int = 100
) -> np.ndarray:
    """Sorted per-step values of ``statistic`` ("glr" with window, "cusum" with drift) on N(0,1) input (cached)."""
    if statistic not in ("glr", "cusum"):
        raise ValueError(f"statistic: expected 'glr' or 'cusum', got {statistic!r}")
    y = np.random.default_rng(seed).standard_normal((runs, length))
    g = glr_statistics(y, int(parameter)) if statistic == "glr" else cusum_statistics(y, float(parameter))
    return sorted_sample(g[:, burn_in:], "runs", "the statistic")


def h0_quantile(sample: np.ndarray, alpha) -> float:
    """λ(α): the (1 − α) quantile of the H0 sample."""
    alpha = check_probability(alpha, "alpha")
    if alpha * sample.size < 10:
        raise ValueError(f"alpha: {alpha} is too small for an H0 sample of {sample.size} values (fewer than 10 exceedances); simulate more")
    return float(np.quantile(sample, 1.0 - alpha))
