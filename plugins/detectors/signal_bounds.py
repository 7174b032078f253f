"""The standardized χ² statistic of the NIS (seed 000 eqs. 22–23, Semoushin's signal function; SPEC §4).

Under the correct model NIS_k = ν_kᵀS_k⁻¹ν_k ~ χ²(m_k), independent over k
(the innovations of the optimal filter are white), so over a set of steps
with D = Σ m_k degrees of freedom

    S = (Σ NIS_k − D) / √(2 D)

has mean 0 and variance 1, and is ≈ N(0, 1) for large D.  Seed 000 eq. 23
prints √(m/2k)(Σ/m − 1), which is this only for k = 1 (SPEC §4 correction).
The sum runs over the steps since the last reset (``window=None``) or over
the last ``window`` measured steps.

Bounds for a two-sided false-alarm probability α per step:

* ``"normal"``: ±Φ⁻¹(1 − α/2) on S (the 3σ rule for α = 2(1 − Φ(3)));
  exact only as D → ∞ — χ²(D) is skewed, so for small D the upper tail is
  heavier and the lower bound cannot be reached when D < c²·2;
* ``"chi2"``: the exact χ²(D) quantiles at α/2 and 1 − α/2, standardized the
  same way, so the per-step false-alarm probability is α for every D.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

CALIBRATIONS = ("normal", "chi2")


def standardize(nis_sum, dof):
    """S = (Σ NIS − D)/√(2D); 0 where D = 0 (nothing observed yet)."""
    nis_sum = np.asarray(nis_sum, dtype=float)
    dof = np.asarray(dof, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = (nis_sum - dof) / np.sqrt(2.0 * dof)
    return np.where(dof > 0, s, 0.0)


def bounds(alpha: float, dof: float, calibration: str = "normal") -> tuple[float, float]:
    """(lower, upper) bounds on S for a two-sided per-step false-alarm probability α."""
    if calibration == "normal" or dof <= 0:
        c = float(-special.ndtri(alpha / 2.0))  # Φ⁻¹(1 − α/2)
        return -c, c
    if calibration == "chi2":
        scale = math.sqrt(2.0 * dof)
        low = 2.0 * special.gammaincinv(dof / 2.0, alpha / 2.0)  # the χ²(D) quantiles α/2 and 1 − α/2 (the upper by its tail)
        high = special.chdtri(dof, alpha / 2.0)
        return float((low - dof) / scale), float((high - dof) / scale)
    raise ValueError(f"calibration: expected one of {CALIBRATIONS}, got {calibration!r}")


def false_alarm_probability(dof: float, lower: float, upper: float) -> float:
    """Exact P(S < lower or S > upper) when Σ NIS ~ χ²(D) (the correct-model distribution)."""
    scale = math.sqrt(2.0 * dof)
    return float(special.chdtr(dof, max(dof + lower * scale, 0.0)) + special.chdtrc(dof, max(dof + upper * scale, 0.0)))
