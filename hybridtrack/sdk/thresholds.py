"""Error probabilities and the thresholds derived from them (shared by the detector plugins), and the χ², normal and
F quantiles and tails that gates, bounds and tests take them from.

Wald's thresholds in the log domain (seed 001 §3, seed 000 Algorithm 4 step 2;
SPEC §4):  A = ln((1 − β)/α),  B = ln(β/(1 − α)).  In code A is ``upper``
and B is ``lower`` (B is the control matrix elsewhere).  A > 0 > B holds
exactly when α + β < 1, which every SPRT here requires.

The distribution functions (:func:`chi2_quantile`, :func:`chi2_upper_quantile`, :func:`chi2_cdf`,
:func:`chi2_tail`, :func:`normal_upper_quantile`, :func:`normal_tail`, :func:`f_tail`) are the
``scipy.special`` functions that ``scipy.stats`` evaluates for them (the same numbers:
tests/sdk/test_quantiles.py), without importing ``scipy.stats`` (about 0.5 s and 40 MB at start-up).  Like
``scipy.stats`` they vectorize over their arguments, give NaN outside the parameters' domain (dof ≤ 0, a
probability outside [0, 1]) and treat x below the support as its lower end.
"""

from __future__ import annotations

import math

import numpy as np
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
    return float(normal_upper_quantile(alpha / 2.0))


def _where_dof(value, *dofs):
    """``value`` where every degree-of-freedom argument is > 0, NaN elsewhere (as scipy.stats); a scalar for scalars."""
    valid = np.logical_and.reduce([np.asarray(d, dtype=np.float64) > 0 for d in dofs])
    return np.where(valid, value, np.nan)[()]


def chi2_quantile(p, dof):
    """The χ²(m) quantile F⁻¹(p; m) = 2 P⁻¹(m/2, p), P⁻¹ the inverse of the regularized lower incomplete gamma
    function (F(x; m) = P(m/2, x/2): Abramowitz & Stegun 1964, eq. 26.4.19); ``scipy.stats.chi2.ppf``."""
    dof = np.asarray(dof, dtype=np.float64)
    return _where_dof(2.0 * special.gammaincinv(dof / 2.0, p), dof)


def chi2_upper_quantile(q, dof):
    """x with P(χ²(m) > x) = q, the upper quantile Q⁻¹(m/2, q) of the regularized upper incomplete gamma function
    (Abramowitz & Stegun 1964, eq. 26.4.19): accurate for a small tail q, where F⁻¹(1 − q) loses digits to the
    rounding of 1 − q; ``scipy.stats.chi2.isf`` (``scipy.special.chdtri``)."""
    return _where_dof(special.chdtri(dof, q), dof)


def chi2_cdf(x, dof):
    """F(x; m) = P(χ²(m) ≤ x) = P(m/2, x/2) (Abramowitz & Stegun 1964, eq. 26.4.19), 0 for x ≤ 0;
    ``scipy.stats.chi2.cdf`` (``scipy.special.chdtr``)."""
    return _where_dof(special.chdtr(dof, np.maximum(x, 0.0)), dof)


def chi2_tail(x, dof):
    """1 − F(x; m) = P(χ²(m) > x) = Q(m/2, x/2), computed as the upper function (no cancellation in a small tail),
    1 for x ≤ 0; ``scipy.stats.chi2.sf`` (``scipy.special.chdtrc``)."""
    return _where_dof(special.chdtrc(dof, np.maximum(x, 0.0)), dof)


def normal_upper_quantile(q):
    """z with 1 − Φ(z) = q: −Φ⁻¹(q) (the normal is symmetric); ``scipy.stats.norm.isf``."""
    return -special.ndtri(q)


def normal_tail(x):
    """1 − Φ(x) = Φ(−x) = ½ erfc(x/√2) (Abramowitz & Stegun 1964, eq. 26.2.29); ``scipy.stats.norm.sf``."""
    return special.ndtr(-np.asarray(x, dtype=np.float64))[()]


def f_tail(x, dfn, dfd):
    """P(F(d₁, d₂) > x) = I_{d₂/(d₂ + d₁x)}(d₂/2, d₁/2), I the regularized incomplete beta function (Abramowitz &
    Stegun 1964, eq. 26.6.2), 1 for x ≤ 0; ``scipy.stats.f.sf`` (``scipy.special.fdtrc``)."""
    return _where_dof(special.fdtrc(dfn, dfd, np.maximum(x, 0.0)), dfn, dfd)


#: the false-alarm probability of the two-sided 3σ rule, 2(1 − Φ(3))
THREE_SIGMA_ALPHA = float(2.0 * normal_tail(3.0))
