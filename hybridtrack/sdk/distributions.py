"""The χ², normal and F quantiles and tails that gates, bounds and tests take their thresholds from.

They are the ``scipy.special`` functions that ``scipy.stats`` evaluates for them (the same numbers:
tests/sdk/test_quantiles.py), without importing ``scipy.stats`` (about 0.5 s and 40 MB at start-up).  Like
``scipy.stats`` they vectorize over their arguments, give NaN outside the parameters' domain (dof ≤ 0, a
probability outside [0, 1]) and treat x below the support as its lower end.  (Plugins call ``scipy.special``
themselves, as a third party would.)
"""

from __future__ import annotations

import numpy as np
from scipy import special


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
