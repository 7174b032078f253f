"""The position sensor's time-stamp jitter (R(x) = R + σ_t² v vᵀ, Sensor.state_noise): its noise, the contract, every
linear estimator against a hand-written covariance KF with R at the predicted state, and NIS consistency on
along-track errors where the plain sensor is overconfident."""

import numpy as np
import pytest

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import resolve
from hybridtrack.testing import check_sensor
from hybridtrack_plugins.motion.linear_modes import Straight
from hybridtrack_plugins.sensors.position import PositionSensor

LAYOUT = ("x", "vx", "y", "vy")


def test_state_noise_is_along_the_velocity():
    sensor = PositionSensor(noise_cov=25.0 * np.eye(2), time_jitter=0.1)
    x = np.array([[1.0e6, 200.0, 5.0e6, 0.0], [0.0, 30.0, 0.0, 40.0]])
    extra = sensor.state_noise(x, LAYOUT)
    np.testing.assert_allclose(extra[0], [[400.0, 0.0], [0.0, 0.0]], rtol=1e-15)  # 20 m along, nothing across
    np.testing.assert_allclose(extra[1], 0.01 * np.outer([30.0, 40.0], [30.0, 40.0]), rtol=1e-15)
    assert sensor.noise_depends_on_state and not PositionSensor().noise_depends_on_state
    check_sensor(sensor)  # the simulated noise has covariance R + σ_t² v vᵀ


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"time_jitter": -0.1}, "time_jitter: expected"), ({"time_jitter": float("nan")}, "time_jitter")],
)
def test_bad_jitter_is_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PositionSensor(**kwargs)


def test_a_layout_without_velocities_is_named():
    with pytest.raises(ValueError, match=r"time_jitter needs the velocities \['vx', 'vy'\]"):
        PositionSensor(time_jitter=0.1).state_noise(np.zeros((1, 2)), ("x", "y"))


def _reference(x0, P0, F, Q, Z, R0, jitter):
    """Covariance KF, R_k = R0 + σ_t² v⁻ v⁻ᵀ at the predicted velocity (Joseph form)."""
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    x, P, out = x0.copy(), P0.copy(), []
    for z in Z:
        x, P = F @ x, F @ P @ F.T + Q
        v = x[[1, 3]]
        R = R0 + jitter**2 * np.outer(v, v)
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        x = x + K @ (z - H @ x)
        A = np.eye(4) - K @ H
        P = A @ P @ A.T + K @ R @ K.T
        out.append((x.copy(), P.copy()))
    return out


@pytest.mark.parametrize("name", ["kalman", "ekf", "potter", "bierman", "information", "srif"])
def test_estimators_equal_the_reference_kf(name):
    rng = np.random.default_rng(3)
    sensor = PositionSensor(noise_cov=np.array([[25.0, 3.0], [3.0, 16.0]]), time_jitter=0.2)
    T = Straight(noise_density=0.5).transition(2.0)
    F, Q = T.F, T.process_noise
    x0 = np.array([3.0e5, 150.0, 6.0e6, -80.0])
    P0 = np.diag([100.0, 25.0, 100.0, 25.0])
    Z = x0[[0, 2]] + np.arange(1, 31)[:, None] * 2.0 * x0[[1, 3]] + 10.0 * rng.standard_normal((30, 2))
    ref = _reference(x0, P0, F, Q, Z, sensor.noise_cov, 0.2)
    estimator = resolve("estimator", (name, {}))  # its own state form, read back in covariance form
    transitions = TransitionBank.stack([T])
    state = estimator.initialize(x0[None], P0[None])
    for k, z in enumerate(Z):
        state = estimator.predict(state, transitions)
        state, _ = estimator.update(state, z, [sensor], LAYOUT)
        x, P = ref[k]
        np.testing.assert_allclose(estimator.mean(state)[0], x, rtol=1e-10, atol=1e-6)
        np.testing.assert_allclose(estimator.covariance(state)[0], P, rtol=1e-8, atol=1e-9 * np.abs(P).max())


def test_nis_is_consistent_only_with_the_jitter_modelled():
    """Straight flight at 200 m/s, fixes 2 s apart, σ = 5 m across and δt ~ N(0, (0.1 s)²) along (20 m): the mean
    NIS is ≈ m = 2 with the jitter in R, far above with the plain sensor."""
    rng = np.random.default_rng(11)
    truth_sensor = PositionSensor(noise_cov=25.0 * np.eye(2), time_jitter=0.1)
    T = Straight(noise_density=0.01).transition(2.0)
    transitions = TransitionBank.stack([T])
    x = np.array([0.0, 200.0, 0.0, 0.0])
    truth = [x := T.F @ x for _ in range(400)]
    Z = np.stack([truth_sensor.simulate(t, LAYOUT, rng) for t in truth])
    means = {}
    for label, sensor in (("jitter", truth_sensor), ("plain", PositionSensor(noise_cov=25.0 * np.eye(2)))):
        kf = resolve("estimator", ("kalman", {}))
        state = kf.initialize(np.array([[0.0, 200.0, 0.0, 0.0]]), np.diag([100.0, 100.0, 100.0, 100.0])[None])
        nis = []
        for z in Z:
            state = kf.predict(state, transitions)
            state, innovation = kf.update(state, z, [sensor], LAYOUT)
            nis.append(innovation.nis[0])
        means[label] = float(np.mean(nis[50:]))
    assert 1.7 < means["jitter"] < 2.3 and means["plain"] > 5.0, means
