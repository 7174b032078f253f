"""The forward–backward mode smoother (hybridtrack.algorithms.mode_smoothing) against brute-force enumeration of
every mode sequence of a small hidden Markov chain, its fixed-lag limits, and the multiple-model run it smooths."""

import itertools

import attrs
import numpy as np
import pytest

from hybridtrack.algorithms.mode_smoothing import smooth_log_mode_probabilities
from hybridtrack.algorithms.multiple_model import MultipleModelEstimator
from hybridtrack.core.plugins import resolve


def _chain(rng, N=6, r=3):
    """Emissions Λ (N+1, r), transitions Π_k (N+1, r, r) (row 0 unused), the initial μ_0 and the forward filter."""
    lik = rng.uniform(0.05, 1.0, (N + 1, r))
    P = rng.uniform(0.1, 1.0, (N + 1, r, r))
    P /= P.sum(axis=2, keepdims=True)
    mu0 = rng.dirichlet(np.ones(r))
    filtered = np.empty((N + 1, r))
    alpha = mu0 * lik[0]
    filtered[0] = alpha / alpha.sum()
    for k in range(1, N + 1):
        alpha = (filtered[k - 1] @ P[k]) * lik[k]
        filtered[k] = alpha / alpha.sum()
    return lik, P, mu0, filtered


def _brute_force(lik, P, mu0, last):
    """P(mode at k | z_0 … z_last) by summing over every mode sequence 0 … last."""
    r = lik.shape[1]
    out = np.zeros((last + 1, r))
    for seq in itertools.product(range(r), repeat=last + 1):
        w = mu0[seq[0]] * lik[0, seq[0]]
        for k in range(1, last + 1):
            w *= P[k, seq[k - 1], seq[k]] * lik[k, seq[k]]
        for k, s in enumerate(seq):
            out[k, s] += w
    return out / out.sum(axis=1, keepdims=True)


def test_fixed_interval_equals_enumeration():
    lik, P, mu0, filtered = _chain(np.random.default_rng(1))
    got = np.exp(smooth_log_mode_probabilities(np.log(filtered), np.log(lik), np.log(P)))
    np.testing.assert_allclose(got, _brute_force(lik, P, mu0, len(lik) - 1), rtol=1e-12)


def test_fixed_lag_equals_enumeration_up_to_the_lag():
    """Step k with lag L uses the reports up to t_k + L: its probability is the enumeration over 0 … last(k)."""
    lik, P, mu0, filtered = _chain(np.random.default_rng(2))
    times = np.array([0.0, 1.0, 2.5, 3.0, 6.0, 6.5, 9.0])
    got = np.exp(smooth_log_mode_probabilities(np.log(filtered), np.log(lik), np.log(P), times, lag=2.0))
    for k in range(len(times)):
        last = int(np.searchsorted(times, times[k] + 2.0, side="right") - 1)
        np.testing.assert_allclose(got[k], _brute_force(lik, P, mu0, last)[k], rtol=1e-12)
    zero = smooth_log_mode_probabilities(np.log(filtered), np.log(lik), np.log(P), times, lag=0.0)
    np.testing.assert_allclose(np.exp(zero), filtered, rtol=1e-12)  # no lag: the filter


def test_bad_inputs_are_named():
    lik, P, _, filtered = _chain(np.random.default_rng(3))
    with pytest.raises(ValueError, match="model_loglik, log_transitions"):
        smooth_log_mode_probabilities(np.log(filtered), np.log(lik)[:-1], np.log(P))
    with pytest.raises(ValueError, match="lag"):
        smooth_log_mode_probabilities(np.log(filtered), np.log(lik), np.log(P), np.arange(7.0), lag=-1.0)
    with pytest.raises(ValueError, match="times"):
        smooth_log_mode_probabilities(np.log(filtered), np.log(lik), np.log(P), np.zeros(7), lag=1.0)


def straight_then_turn(n1=40, n2=40):
    """(IMM, its run): a straight leg then a 200 m turn at 10 m/s, fixes 2 s apart with σ = 5 m."""
    rng = np.random.default_rng(4)
    dt, speed, radius = 2.0, 10.0, 200.0
    t = np.arange(n1 + n2 + 1) * dt
    pos = np.zeros((t.size, 2))
    pos[: n1 + 1, 1] = speed * t[: n1 + 1]
    angle = speed / radius * (t[n1:] - t[n1])
    pos[n1:] = pos[n1] + np.array([-radius, 0.0]) + radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    z = pos + rng.normal(0.0, 5.0, pos.shape)
    sensor = resolve("sensor", ("position", {"name": "p", "noise_cov": 25.0 * np.eye(2)}))
    imm = MultipleModelEstimator(
        models=[("straight", {"noise_density": 0.01}), ("left_turn", {"radius": 200.0, "noise_density": 0.01})],
        sensors=[sensor],
        sojourn=60.0,
    )
    prior = (np.array([z[0, 0], 0.0, z[0, 1], speed]), np.diag([25.0, 4.0, 25.0, 4.0]))
    return imm, imm.run({"p": z}, prior, times=t)


def test_smoothing_a_run_finds_the_turn_earlier():
    """The smoothed run of the IMM calls the turn from its onset, before the filter does, and is right at least as
    often."""
    n1, n2 = 40, 40
    imm, run = straight_then_turn(n1, n2)
    smoothed = imm.smooth(run)
    truth = np.r_[np.zeros(n1, dtype=int), np.ones(n2 + 1, dtype=int)]
    first = {label: int(np.flatnonzero(r.mode[n1 - 5 :] == 1)[0]) + n1 - 5 for label, r in (("filtered", run), ("smoothed", smoothed))}
    assert first["smoothed"] < first["filtered"], first
    assert abs(first["smoothed"] - n1) <= 2, first
    assert np.mean(smoothed.mode == truth) >= np.mean(run.mode == truth)
    np.testing.assert_allclose(np.exp(smoothed.log_mode_probabilities).sum(axis=1), 1.0, rtol=1e-12)
    assert np.allclose(imm.smooth(run, lag=0.0).means, run.means)


def test_fixed_lag_states_are_the_interval_smoother_of_the_run_cut_at_the_lag():
    """With a lag L each model's estimate at step k is the fixed-interval smoother's of the run cut at the last
    report within t_k + L (the reference: the run truncated there, smoothed whole); between the filter and the
    fixed-interval smoother."""
    imm, run = straight_then_turn()
    lag = 9.0  # s: four or five reports ahead
    lagged = imm.smooth(run, lag=lag)
    for k in (0, 20, 38, 41, 45, 60, run.times.size - 3):
        end = int(np.searchsorted(run.times, run.times[k] + lag, side="right"))
        cut = attrs.evolve(
            run,
            times=run.times[:end],
            means=run.means[:end],
            covs=run.covs[:end],
            mode=run.mode[:end],
            log_mode_probabilities=run.log_mode_probabilities[:end],
            model_means=run.model_means[:end],
            model_covs=run.model_covs[:end],
            model_loglik=run.model_loglik[:end],
            loglik=run.loglik[:end],
        )
        reference = imm.smooth(cut)
        np.testing.assert_allclose(lagged.model_means[k], reference.model_means[k], rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(lagged.model_covs[k], reference.model_covs[k], rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(lagged.log_mode_probabilities[k], reference.log_mode_probabilities[k], atol=1e-9)
    whole = imm.smooth(run)
    assert not np.allclose(lagged.model_means, run.model_means) and not np.allclose(lagged.model_means, whole.model_means)
