"""KalmanFilter.restart_step (the compiled restart lane) against initialize → predict → update per missing pattern."""

from __future__ import annotations

import numpy as np
import pytest
from _filters_support import random_spd

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters.ekf import ExtendedKalmanFilter
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.filters.ukf import UnscentedKalmanFilter
from hybridtrack_plugins.sensors.position import PositionSensor
from hybridtrack_plugins.sensors.velocity import VelocitySensor

needs_numba = pytest.mark.skipif(not cov_form.NUMBA_AVAILABLE, reason="numba not installed: no compiled lane")
LAYOUT = ("x", "vx", "y", "vy", "omega")
# a time-stamp jitter and a course error: two sensors whose R depends on the state, side by side
SENSORS = [PositionSensor(noise_cov=np.diag([4.0, 9.0]), time_jitter=0.2), VelocitySensor(speed_sigma=0.3, course_sigma=0.05)]


def system(seed, M=31):
    rng = np.random.default_rng(seed)
    n = len(LAYOUT)
    scale = np.array([10.0, 1.0, 10.0, 1.0, 0.01])
    x = rng.normal(size=(M, n)) * scale
    P = np.stack([random_spd(rng, n, 1.0) for _ in range(M)]) * scale[:, None] * scale[None, :]
    F = np.eye(n) + 0.1 * rng.normal(size=(M, n, n))
    B = rng.normal(size=(M, n))
    Q = np.stack([random_spd(rng, n, 1e-2) for _ in range(M)]) * scale[:, None] * scale[None, :]
    z = x[:, [0, 2, 1, 3]] + rng.normal(size=(M, 4))
    z[1::3, 2:] = np.nan
    z[2::4, 1] = np.nan
    z[5::6] = np.nan
    return x, P, TransitionBank(F, B, Q), z


def reference(kf, x, P, bank, z, sensors=SENSORS):
    """initialize, predict, then one update per missing pattern (as the engine's bank groups them)."""
    state = kf.predict(kf.initialize(x, P), bank)
    M, n = x.shape
    out_x, out_P, loglik, nis = np.empty((M, n)), np.empty((M, n, n)), np.empty(M), np.empty(M)
    patterns = np.isnan(z)
    for pattern in np.unique(patterns, axis=0):
        rows = np.flatnonzero((patterns == pattern).all(axis=1))
        part, innovation = kf.update(kf.take(state, rows), z[rows], sensors, LAYOUT)
        out_x[rows], out_P[rows], loglik[rows], nis[rows] = part.x, part.P, innovation.loglik, innovation.nis
    return out_x, out_P, loglik, nis, state


@needs_numba
@pytest.mark.parametrize("form", ["joseph", "symmetric"])
@pytest.mark.parametrize("estimator", [KalmanFilter, ExtendedKalmanFilter])
def test_restart_step_equals_initialize_predict_update(form, estimator):
    x, P, bank, z = system(7)
    kf = estimator(form=form)
    state, loglik, nis, m = kf.restart_step(x, P, bank, z, SENSORS, LAYOUT)
    ref_x, ref_P, ref_loglik, ref_nis, predicted = reference(estimator(form=form), x, P, bank, z)
    assert np.max(np.abs(state.x - ref_x) / (np.abs(ref_x) + 1.0)) < 1e-12
    d = np.sqrt(np.diagonal(ref_P, axis1=1, axis2=2))
    assert np.max(np.abs(state.P - ref_P) / (d[:, :, None] * d[:, None, :])) < 1e-11
    assert np.max(np.abs(loglik - ref_loglik)) < 1e-9 and np.max(np.abs(nis - ref_nis)) < 1e-9
    np.testing.assert_array_equal(m, (~np.isnan(z)).sum(axis=1))
    np.testing.assert_array_equal(state.P, np.swapaxes(state.P, 1, 2))
    assert np.max(np.abs(state.x_predicted - predicted.x)) < 1e-9
    unmeasured = np.isnan(z).all(axis=1)
    assert (loglik[unmeasured] == 0).all() and (state.x[unmeasured] == state.x_predicted[unmeasured]).all()


@needs_numba
def test_a_linearizing_callable_is_taken_at_the_means_by_an_extended_filter_only():
    x, P, bank, z = system(8)
    calls = []

    def linearize(points):
        calls.append(points.copy())
        return bank

    state, *_ = ExtendedKalmanFilter().restart_step(x, P, linearize, z, SENSORS, LAYOUT)
    np.testing.assert_array_equal(calls[0], x)
    assert np.max(np.abs(state.x - KalmanFilter().restart_step(x, P, bank, z, SENSORS, LAYOUT)[0].x)) == 0.0
    assert KalmanFilter().restart_step(x, P, linearize, z, SENSORS, LAYOUT) is None
    assert UnscentedKalmanFilter().restart_step(x, P, linearize, z, SENSORS, LAYOUT) is None  # its own prediction


@needs_numba
def test_the_lane_declines_steps_the_reference_must_take():
    x, P, bank, z = system(9)
    kf = KalmanFilter()
    bad = P.copy()
    bad[4] = np.diag([1.0, 1.0, -1.0, 1.0, 1.0])
    assert kf.restart_step(x, bad, bank, z, SENSORS, LAYOUT) is None  # not positive definite
    nan_F = TransitionBank(bank.F.copy(), bank.B, bank.Q)
    nan_F.F[0, 0, 0] = np.nan
    assert kf.restart_step(x, P, nan_F, z, SENSORS, LAYOUT) is None
    inf_z = z.copy()
    inf_z[0, 0] = np.inf
    assert kf.restart_step(x, P, bank, inf_z, SENSORS, LAYOUT) is None
    assert KalmanFilter(form="conventional").restart_step(x, P, bank, z, SENSORS, LAYOUT) is None
    assert KalmanFilter(engine="numpy").restart_step(x, P, bank, z, SENSORS, LAYOUT) is None
