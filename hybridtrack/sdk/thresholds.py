"""Error probabilities and the thresholds derived from them (shared by the detector plugins).

Wald's thresholds in the log domain (seed 001 §3, seed 000 Algorithm 4 step 2;
SPEC §4):  A = ln((1 − β)/α),  B = ln(β/(1 − α)).  In code A is ``upper``
and B is ``lower`` (B is the control matrix elsewhere).  A > 0 > B holds
exactly when α + β < 1, which every SPRT here requires.
"""

from __future__ import annotations

import math

from scipy import special


def check_probability(value, name: str) -> float:
    """A probability strictly inside (0, 1), else ``ValueError`` naming ``name``."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a probability in (0, 1), got {value!r}") from None
    if not (0.0 < value < 1.0):
        raise ValueError(f"{name}: expected a probability in (0, 1), got {value!r}")
    return value


def check_error_probabilities(alpha, beta) -> tuple[float, float]:
    """α, β in (0, 1) with α + β < 1 (otherwise A ≤ 0 ≤ B and the test decides before any data)."""
    alpha = check_probability(alpha, "alpha")
    beta = check_probability(beta, "beta")
    if alpha + beta >= 1.0:
        raise ValueError(
            f"alpha + beta: expected alpha + beta < 1 so that the thresholds satisfy A > 0 > B, got {alpha} + {beta} = {alpha + beta}"
        )
    return alpha, beta


def sprt_thresholds(alpha, beta) -> tuple[float, float]:
    """(upper, lower) = (A, B) = (ln((1 − β)/α), ln(β/(1 − α))) (seed 001 §3; seed 000 Algorithm 4 step 2)."""
    alpha, beta = check_error_probabilities(alpha, beta)
    return math.log((1.0 - beta) / alpha), math.log(beta / (1.0 - alpha))


class WaldThresholds:
    """Mixin: error probabilities α, β and the thresholds ``upper`` = A, ``lower`` = B they give; setting ``alpha``
    or ``beta`` moves A and B (the dynamic-threshold wrapper relies on it)."""

    def set_error_probabilities(self, alpha, beta) -> None:
        self._alpha, self._beta = check_error_probabilities(alpha, beta)
        self.upper, self.lower = sprt_thresholds(self._alpha, self._beta)

    @property
    def alpha(self) -> float:
        """False-alarm probability α; setting it moves A and B (dynamic thresholds)."""
        return self._alpha

    @alpha.setter
    def alpha(self, value) -> None:
        self.set_error_probabilities(value, self._beta)

    @property
    def beta(self) -> float:
        """Missed-detection probability β; setting it moves A and B."""
        return self._beta

    @beta.setter
    def beta(self, value) -> None:
        self.set_error_probabilities(self._alpha, value)


def two_sided_normal_bound(alpha) -> float:
    """c with P(|N(0,1)| > c) = α: the 3σ rule is α = 2(1 − Φ(3)) ≈ 0.0027."""
    alpha = check_probability(alpha, "alpha")
    return float(-special.ndtri(alpha / 2.0))  # Φ⁻¹(1 − α/2) = −Φ⁻¹(α/2)


#: the false-alarm probability of the two-sided 3σ rule, 2(1 − Φ(3))
THREE_SIGMA_ALPHA = float(2.0 * special.ndtr(-3.0))
