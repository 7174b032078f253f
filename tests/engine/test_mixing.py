"""The compiled IMM mixing and merging (hybridtrack.engine.mixing) against the numpy mixtures they replace."""

from __future__ import annotations

import numpy as np
import pytest

from hybridtrack.engine import mixing
from hybridtrack.sdk.mixtures import logsumexp, mixture

needs_numba = pytest.mark.skipif(not mixing.NUMBA_AVAILABLE, reason="numba not installed: the numpy functions run")


def models(seed, R=13, r=3, n=5):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(R, r, n)) * 10.0
    A = rng.normal(size=(R, r, n, n))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(n)
    log_mu = np.log(rng.dirichlet(np.ones(r), size=R))
    log_mu[0] = [0.0, -np.inf, -np.inf]  # one model certain
    log_mu[1, 1] = -800.0  # below float64's exp range
    return x, P, log_mu


@needs_numba
@pytest.mark.parametrize("per_run", [False, True])
def test_mix_equals_the_numpy_mixture(per_run):
    x, P, log_mu = models(1)
    R, r = log_mu.shape
    rng = np.random.default_rng(2)
    pi = rng.dirichlet(np.ones(r), size=(R if per_run else 1, r))
    with np.errstate(divide="ignore"):
        log_pi = np.log(pi)
    log_pi[..., 0, 2] = -np.inf  # a forbidden switch
    log_cbar, x0, P0 = mixing.mix(log_pi, log_mu, x, P)
    joint = log_pi + log_mu[:, :, None]
    ref_x, ref_P = mixture(np.swapaxes(joint, 1, 2), x[:, None], P[:, None])
    np.testing.assert_allclose(log_cbar, logsumexp(joint, axis=1), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(x0, ref_x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(P0, ref_P, rtol=1e-12, atol=1e-11)
    np.testing.assert_array_equal(P0, np.swapaxes(P0, -1, -2))


@needs_numba
def test_merge_equals_the_numpy_mixture_and_an_all_impossible_run_gets_equal_weights():
    x, P, _ = models(3)
    rng = np.random.default_rng(4)
    joint = rng.normal(size=(x.shape[0], x.shape[1])) * 30.0
    joint[2] = -np.inf
    with np.errstate(invalid="ignore"):
        log_mu, total, mean, cov = mixing.merge(joint, x, P)
        ref_total = logsumexp(joint, axis=-1)
        ref_log_mu = joint - ref_total[:, None]
        ref_mean, ref_cov = mixture(ref_log_mu, x, P)
    np.testing.assert_allclose(total, ref_total, rtol=1e-13)
    np.testing.assert_allclose(log_mu, ref_log_mu, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-12, atol=1e-11)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(mean[2], x[2].mean(axis=0), rtol=1e-12)


def hypotheses(seed, H=11, r=3, n=5):
    """H multiple-model estimates far from the origin (map grid), in 4 groups, one mode impossible in one group."""
    rng = np.random.default_rng(seed)
    x, P, log_mu = models(seed, H, r, n)
    x = x + 4e6
    group = np.array([0, 1, 1, 2, 2, 2, 3, 3, 3, 3, 1])[:H]
    log_w = np.log(rng.uniform(0.1, 1.0, H))
    for g in range(4):
        log_w[group == g] -= logsumexp(log_w[group == g])
    log_mu[group == 0] = [0.0, -np.inf, -np.inf]  # group 0: modes 1 and 2 have probability zero
    log_mu -= logsumexp(log_mu, axis=1)[:, None]
    return group, log_w, log_mu, x, P, rng.normal(size=(H, r)), rng.normal(size=H)


@needs_numba
def test_merge_groups_equals_the_numpy_merge(monkeypatch):
    group, *inputs = hypotheses(3)
    compiled = mixing.merge_groups(group, 4, *inputs)
    monkeypatch.setattr(mixing, "NUMBA_AVAILABLE", False)
    reference = mixing.merge_groups(group, 4, *inputs)
    for got, expected in zip(compiled, reference):
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-7)


def test_merge_groups_is_the_moment_match_of_each_group():
    group, log_w, log_mu, x, P, model_ll, ll = hypotheses(4)
    log_mu_out, _, _, mean, cov, _, ll_out = mixing.merge_groups(group, 4, log_w, log_mu, x, P, model_ll, ll)
    for g in range(4):
        inside = group == g
        means, covs = mixture(log_mu[inside], x[inside], P[inside])  # each hypothesis' output estimate
        expected_mean, expected_cov = mixture(log_w[inside], means, covs)
        np.testing.assert_allclose(mean[g] - 4e6, expected_mean - 4e6, rtol=1e-9, atol=1e-8)
        np.testing.assert_allclose(cov[g], expected_cov, rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(ll_out[g], np.exp(log_w[inside]) @ ll[inside], rtol=1e-12)
        np.testing.assert_allclose(logsumexp(log_mu_out[g]), 0.0, atol=1e-12)
    assert np.isneginf(log_mu_out[0, 1:]).all()


def test_merge_groups_names_an_empty_group_and_a_wrong_shape():
    group, *inputs = hypotheses(5)
    with pytest.raises(ValueError, match="group: expected every group in \\[0, 5\\)"):
        mixing.merge_groups(group, 5, *inputs)
    inputs[4] = inputs[4][:, :2]
    with pytest.raises(ValueError, match="model_loglik"):
        mixing.merge_groups(group, 4, *inputs)
