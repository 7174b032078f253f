"""Gaussian-sum filter: one component is the EKF; merging, pruning, weights; range-parameterised bearings-only TMA."""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.sdk.mixtures import logsumexp, mixture
from hybridtrack.testing.contracts import check_estimator
from hybridtrack_plugins.filters.gaussian_sum import GaussianSumFilter, merge, range_parameterised
from hybridtrack_plugins.motion.linear_modes import Straight
from hybridtrack_plugins.motion.ship import ShipTurn
from hybridtrack_plugins.sensors.bearing import BearingSensor
from hybridtrack_plugins.sensors.position import PositionSensor
from hybridtrack_plugins.solvers.observer import Seed002Scenario, simulate_bearings
from hybridtrack_plugins.solvers.tma_model import from_polar

LAYOUT = ("x", "vx", "y", "vy")


def _registry():
    return ht.load_plugins(strict=True).registry


def _close(a, b, rtol=1e-12, atol=1e-12):
    np.testing.assert_allclose(a, b, rtol=rtol, atol=atol)


def _compare_to_ekf(ekf, gsum, s_ekf, s_gs, steps):
    for predict, z, sensors, layout in steps:
        s_ekf, s_gs = ekf.predict(s_ekf, predict), gsum.predict(s_gs, predict)
        _close(gsum.mean(s_gs), ekf.mean(s_ekf))
        _close(gsum.covariance(s_gs), ekf.covariance(s_ekf), atol=1e-9)
        (s_ekf, i_ekf), (s_gs, i_gs) = ekf.update(s_ekf, z, sensors, layout), gsum.update(s_gs, z, sensors, layout)
        _close(gsum.mean(s_gs), ekf.mean(s_ekf))
        _close(gsum.covariance(s_gs), ekf.covariance(s_ekf), atol=1e-9)
        for field in ("nu", "S", "loglik", "nis"):
            _close(getattr(i_gs, field), getattr(i_ekf, field))
    return s_gs


def test_one_component_is_the_ekf_linear():
    rng = np.random.default_rng(1)
    bank = TransitionBank.stack([Straight(noise_cov=q * np.eye(2)).transition(1.0) for q in (0.01, 1.0)])
    sensor = PositionSensor(noise_cov=np.array([[4.0, 1.0], [1.0, 9.0]]))
    ekf = _registry().create("estimator", "ekf", structure=False, engine="numpy")
    gsum = GaussianSumFilter(engine="numpy")
    x0 = np.array([[100.0, 10.0, 50.0, -5.0], [110.0, 9.0, 40.0, -4.0]])
    P0 = np.stack([np.diag([25.0, 4.0, 25.0, 4.0])] * 2)
    truth, steps = x0[0].copy(), []
    F = bank.F[0]
    for k in range(40):
        truth = F @ truth
        z = sensor.simulate(truth, LAYOUT, rng)
        if k % 7 == 3:
            z[1] = np.nan  # a partial measurement
        steps.append((bank, z, [sensor], LAYOUT))
    state = _compare_to_ekf(ekf, gsum, ekf.initialize(x0, P0), gsum.initialize(x0, P0), steps)
    assert state.x.shape == (2, 1, 4) and np.all(state.log_weights == 0.0)


def test_one_component_is_the_ekf_bearings_and_ship_turn():
    """Nonlinear case: a bearing sensor on a moving observer and the ship-turn model's linearizing callable."""
    rng = np.random.default_rng(2)
    model = ShipTurn(sigma_velocity=0.05, sigma_rate=2e-4)
    layout = ShipTurn.layout
    ekf = _registry().create("estimator", "ekf", structure=False, engine="numpy")
    gsum = GaussianSumFilter(engine="numpy")
    x = np.array([3000.0, 4000.0, -3.0, 2.0, 0.005])
    x0 = np.array([[3100.0, 3900.0, -2.5, 2.5, 0.0], [2900.0, 4200.0, -3.5, 1.5, 0.01]])
    P0 = np.stack([np.diag([1e4, 1e4, 1.0, 1.0, 1e-4])] * 2)
    lin, steps = model.linearizer(5.0), []
    for k in range(60):
        x = model.f(x, 5.0)
        sensor = BearingSensor(sigma=np.deg2rad(0.5), observer=(20.0 * k, 300.0 * np.sin(k / 10.0)))
        steps.append((lin, sensor.simulate(x, layout, rng), [sensor], layout))
    _compare_to_ekf(ekf, gsum, ekf.initialize(x0, P0), gsum.initialize(x0, P0), steps)


def test_merging_identical_components_leaves_the_mixture_unchanged():
    x = np.array([[1.0, 2.0, 3.0, 4.0]] * 2)[None]
    A = np.array([[2.0, 0.3, 0.1, 0.0], [0.3, 1.0, 0.0, 0.2], [0.1, 0.0, 3.0, 0.4], [0.0, 0.2, 0.4, 1.5]])
    P = np.stack([A, A])[None]
    lw = np.log([[0.3, 0.7]])
    xm, Pm, lwm = merge(x, P, lw, threshold=4.0)
    assert xm.shape == (1, 1, 4)
    _close(xm[0, 0], x[0, 0])
    _close(Pm[0, 0], A)
    _close(lwm, [[0.0]], atol=1e-15)
    before, after = mixture(lw, x, P), mixture(lwm, xm, Pm)
    _close(after[0], before[0])
    _close(after[1], before[1])


def test_merging_is_moment_matched_and_respects_the_threshold():
    """Two components 1 σ apart merge into their moment-matched Gaussian; a third 10 σ away stays."""
    P = np.stack([np.eye(2), np.eye(2), np.eye(2)])[None]
    x = np.array([[[0.0, 0.0], [1.0, 0.0], [10.0, 0.0]]])
    lw = np.log([[0.5, 0.3, 0.2]])
    mean, cov = mixture(lw[:, :2], x[:, :2], P[:, :2])
    xm, Pm, lwm = merge(x, P, lw, threshold=4.0)
    assert xm.shape == (1, 2, 2)
    _close(np.exp(lwm), [[0.8, 0.2]])
    _close(xm[0, 0], mean[0])
    _close(Pm[0, 0], cov[0])
    _close(xm[0, 1], [10.0, 0.0])
    # hand-derived: x̄ = 0.3/0.8 = 0.375, P̄_xx = 1 + (0.5·0.375² + 0.3·0.625²)/0.8 = 1.234375
    _close(xm[0, 0], [0.375, 0.0])
    _close(Pm[0, 0], [[1.234375, 0.0], [0.0, 1.0]])
    xs, _, _ = merge(x, P, lw, threshold=0.5)  # 1 σ apart is beyond d² = 0.5: nothing merges
    assert xs.shape == (1, 3, 2)


def test_pruning_removes_small_weights_and_renormalises():
    gsum = GaussianSumFilter(prune_threshold=1e-3, merge_threshold=None, max_components=2)
    lw = np.log([[0.6, 0.3999, 1e-4], [0.2, 0.3, 0.5]])
    pruned = gsum.prune(lw)
    assert np.isneginf(pruned[0, 2]) and np.isfinite(pruned[1]).all()
    _close(np.exp(pruned[0, :2]), np.array([0.6, 0.3999]) / 0.9999)
    _close(logsumexp(pruned, axis=-1), [0.0, 0.0], atol=1e-15)
    x = np.zeros((2, 3, 1)) + np.arange(3.0)[None, :, None]
    P = np.ones((2, 3, 1, 1))
    xr, Pr, lwr = gsum.reduce(x, P, lw)  # then the cap of 2: the second filter keeps 0.5 and 0.3
    assert xr.shape == (2, 2, 1)
    _close(np.exp(lwr), [np.array([0.6, 0.3999]) / 0.9999, [0.5 / 0.8, 0.3 / 0.8]])
    _close(xr[1, :, 0], [2.0, 1.0])


def _bearings_run(components, steps_every=10.0, sigma_deg=0.5, seed=3, merge_threshold=4.0):
    scenario = Seed002Scenario(interval=steps_every)
    times, observer = scenario.times(), scenario.observer()
    theta = from_polar(0.0, 20_000.0, np.deg2rad(120.0), 8.0, observer[0])  # (x, y, vx, vy) at t = 0
    rng = np.random.default_rng(seed)
    sigma = np.deg2rad(sigma_deg)
    bearings = simulate_bearings(theta, times, observer, sigma, rng)
    means, covs, weights = range_parameterised(observer[0], bearings[0], sigma, 2_000.0, 60_000.0, components, speed_sigma=10.0)
    gsum = GaussianSumFilter(merge_threshold=merge_threshold)
    state = gsum.initialize_mixture(means, covs, weights)
    bank = TransitionBank.stack([Straight(noise_cov=1e-6 * np.eye(2)).transition(steps_every)])
    truth_range = 20_000.0
    initial = state
    history = []
    for k, z in enumerate(bearings):
        if k:
            state = gsum.predict(state, bank)
        state, innovation = gsum.update(state, np.array([z]), [BearingSensor(sigma=sigma, observer=observer[k])], LAYOUT)
        assert np.isfinite(innovation.loglik).all() and np.isfinite(innovation.nis).all()
        lw = state.log_weights[np.isfinite(state.log_weights)]
        assert np.isfinite(lw).all() and lw.size >= 1
        _close(logsumexp(state.log_weights, axis=-1), [0.0], atol=1e-12)
        truth = np.array([theta[0] + theta[2] * (times[k] - times[0]), theta[1] + theta[3] * (times[k] - times[0])])
        history.append(np.hypot(*(state.mean[0, [0, 2]] - truth)))
    return initial, state, np.array(history), truth_range, truth


def test_range_parameterised_mixture_geometry():
    means, covs, weights = range_parameterised((100.0, -50.0), np.deg2rad(30.0), 0.01, 1_000.0, 16_000.0, 4, speed_sigma=5.0)
    assert means.shape == (1, 4, 4) and covs.shape == (1, 4, 4, 4)
    _close(weights, np.full((1, 4), 0.25))
    ranges = np.hypot(means[0, :, 0] - 100.0, means[0, :, 2] + 50.0)
    _close(ranges, [1500.0, 3000.0, 6000.0, 12000.0])  # ρ = 2: midpoints of [1, 2], [2, 4], [4, 8], [8, 16] km
    u = np.array([np.sin(np.deg2rad(30.0)), np.cos(np.deg2rad(30.0))])
    pos = covs[0][:, [0, 2]][:, :, [0, 2]]
    sigma_r = np.sqrt(np.einsum("i,cij,j->c", u, pos, u))
    _close(sigma_r / ranges, np.full(4, 2 * (2 - 1) / (np.sqrt(12) * 3)))  # σ_r / r constant (Peach 1995)
    v = np.array([-u[1], u[0]])
    _close(np.sqrt(np.einsum("i,cij,j->c", v, pos, v)), 0.01 * ranges)
    _close(covs[0, :, 1, 1], 25.0)
    for c in range(4):
        np.linalg.cholesky(covs[0, c])


def test_range_parameterised_covers_the_truth_and_converges():
    initial, state, error, truth_range, truth_position = _bearings_run(8)
    # the initial mixture covers the true range: some component is within 2 σ_r of it
    observer0 = Seed002Scenario(interval=10.0).observer()[0]
    ranges = np.hypot(initial.x[0, :, 0] - observer0[0], initial.x[0, :, 2] - observer0[1])
    sigma_r = np.sqrt(np.diagonal(initial.P[0], axis1=-2, axis2=-1)[:, [0, 2]].sum(axis=1))
    assert np.min(np.abs(ranges - truth_range) / sigma_r) < 2.0
    assert error[0] > 2_000.0  # the mixture mean starts far off (range unobservable from one bearing)
    assert error[-1] < 0.02 * truth_range  # 182 m after the observer's two turns (20 min, 120 bearings)
    d = state.mean[0, [0, 2]] - truth_position
    nees = d @ np.linalg.solve(state.covariance[0][np.ix_([0, 2], [0, 2])], d)
    assert nees < 13.8  # χ²₂ 99.9 %: the mixture covariance is consistent with the error
    assert 1 <= state.x.shape[1] <= 8


def test_log_weights_stay_finite_over_a_long_run_without_merging():
    _, state, error, _, _ = _bearings_run(6, steps_every=2.0, merge_threshold=None)
    assert np.isfinite(error).all()
    assert state.component_count[0] >= 1


def test_bank_operations_pad_components():
    gsum = GaussianSumFilter()
    means, covs, weights = range_parameterised((0.0, 0.0), [0.1, 0.2], 0.01, 1_000.0, 8_000.0, 3, speed_sigma=5.0)
    mix = gsum.initialize_mixture(means, covs, weights)
    one = gsum.initialize(mix.mean[:1], mix.covariance[:1])
    joined = gsum.concatenate([one, mix])
    assert joined.x.shape == (3, 3, 4)
    assert np.isneginf(joined.log_weights[0, 1:]).all()
    _close(gsum.mean(joined), np.concatenate([mix.mean[:1], mix.mean]))
    _close(gsum.covariance(gsum.take(joined, [2])), mix.covariance[1:])


def test_bad_parameters():
    with pytest.raises(ValueError, match="merge_threshold"):
        GaussianSumFilter(merge_threshold=-1.0)
    with pytest.raises(ValueError, match="prune_threshold"):
        GaussianSumFilter(prune_threshold=1.0)
    with pytest.raises(ValueError, match="max_components"):
        GaussianSumFilter(max_components=0)
    with pytest.raises(ValueError, match="form"):
        GaussianSumFilter(form="nope")
    gsum = GaussianSumFilter()
    x, P = np.zeros((1, 2, 4)), np.stack([np.eye(4)] * 2)[None]
    with pytest.raises(ValueError, match="weights"):
        gsum.initialize_mixture(x, P, [[0.0, 0.0]])
    with pytest.raises(ValueError, match="weights"):
        gsum.initialize_mixture(x, P, [[-0.5, 1.5]])
    with pytest.raises(ValueError, match="covs"):
        gsum.initialize_mixture(x, P[:, :1], [[0.5, 0.5]])
    with pytest.raises(ValueError, match="r_min"):
        range_parameterised((0.0, 0.0), 0.0, 0.01, 5_000.0, 1_000.0, 4, speed_sigma=5.0)
    with pytest.raises(ValueError, match="components"):
        range_parameterised((0.0, 0.0), 0.0, 0.01, 1_000.0, 5_000.0, 0, speed_sigma=5.0)
    with pytest.raises(ValueError, match="sigma_bearing"):
        range_parameterised((0.0, 0.0), 0.0, 0.0, 1_000.0, 5_000.0, 4, speed_sigma=5.0)
    with pytest.raises(ValueError, match="layout"):
        range_parameterised((0.0, 0.0), 0.0, 0.01, 1_000.0, 5_000.0, 4, speed_sigma=5.0, layout=("x", "y"))


def test_contract():
    check_estimator(_registry().create("estimator", "gaussian_sum"))
