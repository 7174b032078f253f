"""The χ², normal and F quantiles and tails of hybridtrack.sdk.distributions equal scipy.stats' over grids (1e-12 relative),
edges included: the ends of the support, probabilities 0 and 1, dof ≤ 0, NaN."""

import math

import numpy as np
import pytest
from scipy import stats

from hybridtrack.sdk import distributions as dist
from hybridtrack.sdk import thresholds as th

RTOL = 1e-12
#: probabilities from deep tails to the middle, both sides
P = np.concatenate([np.geomspace(1e-300, 1e-3, 40), np.linspace(0.001, 0.999, 60), 1.0 - np.geomspace(1e-3, 1e-15, 20)])
DOF = np.array([1, 2, 3, 4, 5, 6, 9, 17, 50, 300])
#: statistics over many magnitudes, below the support and at its ends
X = np.concatenate([[-5.0, -1e-300, 0.0], np.geomspace(1e-8, 2e3, 70), [np.inf]])


def same(ours, reference):
    ours, reference = np.asarray(ours, dtype=float), np.asarray(reference, dtype=float)
    assert ours.shape == reference.shape
    np.testing.assert_allclose(ours, reference, rtol=RTOL, atol=0.0, equal_nan=True)
    assert np.array_equal(np.isnan(ours), np.isnan(reference))


@pytest.mark.parametrize(
    ("ours", "reference", "points"),
    [
        (dist.chi2_quantile, stats.chi2.ppf, P),
        (dist.chi2_upper_quantile, stats.chi2.isf, P),
        (dist.chi2_cdf, stats.chi2.cdf, X),
        (dist.chi2_tail, stats.chi2.sf, X),
    ],
    ids=["chi2.ppf", "chi2.isf", "chi2.cdf", "chi2.sf"],
)
def test_chi2_functions_equal_scipy_stats_over_the_grid(ours, reference, points):
    grid, dof = np.meshgrid(points, DOF, indexing="ij")
    same(ours(grid, dof), reference(grid, dof))


def test_chi2_edges_equal_scipy_stats():
    edges = np.array([0.0, 1.0, -0.1, 1.1, np.nan])
    for dof in (0, -1, 0.5, 3, np.nan):
        same(dist.chi2_quantile(edges, dof), stats.chi2.ppf(edges, dof))
        same(dist.chi2_upper_quantile(edges, dof), stats.chi2.isf(edges, dof))
        same(dist.chi2_cdf(X, dof), stats.chi2.cdf(X, dof))
        same(dist.chi2_tail(X, dof), stats.chi2.sf(X, dof))
    assert dist.chi2_quantile(0.0, 2) == 0.0 and dist.chi2_quantile(1.0, 2) == math.inf
    assert dist.chi2_tail(-1.0, 2) == 1.0 and dist.chi2_cdf(-1.0, 2) == 0.0


def test_chi2_by_hand():
    """m = 2 is the exponential with mean 2: F(x) = 1 − e^{−x/2}, F⁻¹(p) = −2 ln(1 − p)."""
    x = np.array([0.1, 1.0, 5.0, 40.0])
    np.testing.assert_allclose(dist.chi2_tail(x, 2), np.exp(-x / 2), rtol=1e-14)
    np.testing.assert_allclose(dist.chi2_cdf(x, 2), -np.expm1(-x / 2), rtol=1e-14)
    p = np.array([1e-10, 0.3, 0.95])
    np.testing.assert_allclose(dist.chi2_quantile(p, 2), -2 * np.log1p(-p), rtol=1e-13)
    np.testing.assert_allclose(dist.chi2_upper_quantile(p, 2), -2 * np.log(p), rtol=1e-13)


def test_normal_functions_equal_scipy_stats():
    same(dist.normal_upper_quantile(P), stats.norm.isf(P))
    same(dist.normal_upper_quantile(np.array([0.0, 1.0, -0.1, 1.1, np.nan])), stats.norm.isf(np.array([0.0, 1.0, -0.1, 1.1, np.nan])))
    z = np.concatenate([-np.geomspace(30, 1e-8, 40), [0.0], np.geomspace(1e-8, 37, 60), [-np.inf, np.inf, np.nan]])
    same(dist.normal_tail(z), stats.norm.sf(z))
    assert th.THREE_SIGMA_ALPHA == float(2.0 * stats.norm.sf(3.0))
    assert th.two_sided_normal_bound(th.THREE_SIGMA_ALPHA) == pytest.approx(3.0, rel=1e-14)


def test_f_tail_equals_scipy_stats():
    grid, dfn, dfd = np.meshgrid(X, np.array([1, 3, 7]), np.array([1, 2, 5, 30, 400]), indexing="ij")
    same(dist.f_tail(grid, dfn, dfd), stats.f.sf(grid, dfn, dfd))
    for dfn, dfd in ((3, 0), (0, 5), (-1, 5), (3, np.nan)):
        same(dist.f_tail(X, dfn, dfd), stats.f.sf(X, dfn, dfd))


def test_scalars_in_scalars_out():
    for value in (dist.chi2_quantile(0.5, 3), dist.chi2_upper_quantile(0.5, 3), dist.chi2_cdf(1.0, 3), dist.chi2_tail(1.0, 3)):
        assert np.ndim(value) == 0 and isinstance(float(value), float)
    assert np.ndim(dist.normal_tail(1.0)) == 0 and np.ndim(dist.f_tail(1.0, 3, 4)) == 0
    assert np.isnan(dist.chi2_quantile(0.5, 0))
