"""Common plumbing of the built-in detectors: an Innovation is reduced to per-filter scores.

Every detector here reads only the scores of the bank it watches — the
log-likelihoods ℓ (M,), the NIS (M,) and the measurement dimension m — so the
same maths runs on the centralized :class:`~hybridtrack.interfaces.Innovation`
and on the quantities a node of the decentralized filter computes locally
from its own filter and the broadcast ΔI_j, Δs_j, z_jᵀR_j⁻¹z_j (seed 000
eq. 22; SPEC §4 "Decentralized detection").  ``observe(step, loglik, nis, m)``
is that entry point; ``step(step, innovation)`` calls it.
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from hybridtrack.interfaces import Detector, DetectorStep, Innovation


def check_positive_int(value, name: str, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}: expected an integer ≥ {minimum}, got {value!r}")
    return int(value)


def check_positive(value, name: str) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a positive number, got {value!r}") from None
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name}: expected a positive finite number, got {value!r}")
    return value


class ScoreDetector(Detector):
    """A detector fed per-filter scores; subclasses implement :meth:`observe`."""

    def step(self, step: int, innovation: Innovation) -> DetectorStep:
        return self.observe(step, np.asarray(innovation.loglik, float), np.asarray(innovation.nis, float), innovation.measurement_dim)

    @abstractmethod
    def observe(self, step: int, loglik: np.ndarray, nis: np.ndarray, m: int) -> DetectorStep:
        """Consume one step's scores: ℓ (M,), NIS (M,), m (0 = no measurement this step)."""
