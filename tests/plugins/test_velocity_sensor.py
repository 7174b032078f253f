"""The velocity sensor of a reported course and speed (R(x) = σ_s² I + σ_χ² (|v|² I − v vᵀ)): its noise, every linear
estimator with position and velocity against a hand-written covariance KF with R at the predicted state, NIS
consistency on simulated course/speed reports, and the tracker's configuration of it."""

import numpy as np
import pytest

from hybridtrack.apps.tracking import ConfigError, load_config, measurements_of
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import resolve
from hybridtrack.io.track_files import Track
from hybridtrack.testing import check_sensor
from hybridtrack_plugins.motion.linear_modes import Straight
from hybridtrack_plugins.sensors.position import PositionSensor
from hybridtrack_plugins.sensors.velocity import VelocitySensor

LAYOUT = ("x", "vx", "y", "vy")


def test_noise_is_the_speed_error_and_the_course_error_across():
    sensor = VelocitySensor(speed_sigma=0.2, course_sigma=np.radians(2.0))
    x = np.array([[1.0e6, 3.0, 5.0e6, 4.0], [0.0, 0.0, 0.0, 0.0]])
    R = sensor.noise_cov + sensor.state_noise(x, LAYOUT)
    u, normal = np.array([3.0, 4.0]) / 5.0, np.array([-4.0, 3.0]) / 5.0
    assert u @ R[0] @ u == pytest.approx(0.04, rel=1e-12)  # along: σ_s²
    assert normal @ R[0] @ normal == pytest.approx(0.04 + (np.radians(2.0) * 5.0) ** 2, rel=1e-12)  # across: + (σ_χ |v|)²
    np.testing.assert_allclose(R[1], 0.04 * np.eye(2), rtol=1e-15)  # at rest the course says nothing
    assert sensor.noise_depends_on_state and not VelocitySensor(speed_sigma=0.2).noise_depends_on_state
    check_sensor(sensor)  # simulated noise of covariance R(x)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"speed_sigma": 0.0}, "speed_sigma: expected a finite number of m/s > 0"),
        ({"speed_sigma": "x"}, "speed_sigma: expected"),
        ({"course_sigma": -0.1}, "course_sigma: expected a finite number of radians ≥ 0"),
        ({"course_sigma": float("nan")}, "course_sigma"),
    ],
)
def test_bad_sigmas_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        VelocitySensor(**kwargs)


def _reference(x0, P0, F, Q, Z, R_position, speed_sigma, course_sigma):
    """Covariance KF of (x, y, vx, vy) measurements, the velocity block of R at the predicted velocity (Joseph form)."""
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])
    x, P, out = x0.copy(), P0.copy(), []
    for z in Z:
        x, P = F @ x, F @ P @ F.T + Q
        v = x[[1, 3]]
        R = np.zeros((4, 4))
        R[:2, :2] = R_position
        R[2:, 2:] = speed_sigma**2 * np.eye(2) + course_sigma**2 * (v @ v * np.eye(2) - np.outer(v, v))
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        x = x + K @ (z - H @ x)
        A = np.eye(4) - K @ H
        P = A @ P @ A.T + K @ R @ K.T
        out.append((x.copy(), P.copy()))
    return out


@pytest.mark.parametrize("name", ["kalman", "ekf", "ukf", "information", "srif"])
def test_estimators_equal_the_reference_kf(name):
    rng = np.random.default_rng(5)
    position = PositionSensor(noise_cov=100.0 * np.eye(2))
    velocity = VelocitySensor(speed_sigma=0.3, course_sigma=np.radians(3.0))
    T = Straight(noise_density=0.01).transition(10.0)
    F, Q = T.F, T.process_noise
    x0 = np.array([4.0e5, 5.0, 5.6e6, -2.0])
    P0 = np.diag([400.0, 4.0, 400.0, 4.0])
    steps = np.arange(1, 21)[:, None]
    Z = np.hstack(
        [x0[[0, 2]] + steps * 10.0 * x0[[1, 3]] + 10.0 * rng.standard_normal((20, 2)), x0[[1, 3]] + 0.3 * rng.standard_normal((20, 2))]
    )
    ref = _reference(x0, P0, F, Q, Z, position.noise_cov, 0.3, np.radians(3.0))
    estimator = resolve("estimator", (name, {}))
    transitions = TransitionBank.stack([T])
    state = estimator.initialize(x0[None], P0[None])
    for k, z in enumerate(Z):
        state = estimator.predict(state, transitions)
        state, _ = estimator.update(state, z, [position, velocity], LAYOUT)
        x, P = ref[k]
        np.testing.assert_allclose(estimator.mean(state)[0], x, rtol=1e-10, atol=1e-6)
        np.testing.assert_allclose(estimator.covariance(state)[0], P, rtol=1e-8, atol=1e-9 * np.abs(P).max())


def test_nis_is_consistent_on_simulated_course_and_speed():
    """A ship at 6 m/s, reports 10 s apart, course error 3° (0.31 m/s across), speed error 0.1 m/s: the mean NIS of
    the velocity alone is ≈ 2 with the course error in R, far above with the speed error alone."""
    rng = np.random.default_rng(2)
    truth_sensor = VelocitySensor(speed_sigma=0.1, course_sigma=np.radians(3.0))
    T = Straight(noise_density=1e-4).transition(10.0)
    x = np.array([0.0, 6.0, 0.0, 0.0])
    truth = [x := T.F @ x for _ in range(400)]
    Z = np.stack([truth_sensor.simulate(t, LAYOUT, rng) for t in truth])
    means = {}
    for label, sensor in (("course", truth_sensor), ("speed only", VelocitySensor(speed_sigma=0.1))):
        kf = resolve("estimator", ("kalman", {}))
        state = kf.initialize(np.array([[0.0, 6.0, 0.0, 0.0]]), np.diag([100.0, 1.0, 100.0, 1.0])[None])
        nis = []
        for z in Z:
            state = kf.predict(state, TransitionBank.stack([T]))
            state, innovation = kf.update(state, z, [sensor], LAYOUT)
            nis.append(innovation.nis[0])
        means[label] = float(np.mean(nis[50:]))
    assert 1.6 < means["course"] < 2.4 and means["speed only"] > 4.0, means


def _config(**measurement):
    return {
        "reader": {"course": "cog", "speed": "sog"},
        "measurement": {"sigma": 10.0, **measurement},
        "estimator": {"algorithm": "imm", "modes": ["straight", {"name": "coordinated_turn"}], "noise_density": 0.001},
    }


def test_the_tracker_measures_course_and_speed_as_velocity():
    cfg = load_config(_config(speed_sigma=0.2, course_sigma=2.0))
    track = Track("a", times=[0.0, 10.0], positions=[[0.0, 0.0], [50.0, 0.0]], lines=[2, 3], course=[90.0, np.nan], speed=[5.0, 5.0])
    z = measurements_of(track, cfg)
    np.testing.assert_allclose(z["velocity"][0], [5.0, 0.0], atol=1e-12)  # 90° = east
    assert np.isnan(z["velocity"][1]).all()  # no course: the position alone
    with pytest.raises(ConfigError, match="speed_sigma .m/s. and course_sigma .degrees.: give both"):
        load_config(_config(speed_sigma=0.2))
    missing = _config(speed_sigma=0.2, course_sigma=2.0)
    missing["reader"] = {}
    with pytest.raises(ConfigError, match=r"\[reader\] needs the course and speed columns"):
        load_config(missing)


@pytest.mark.parametrize(
    ("segments", "match"),
    [
        ({"by": "course"}, "by = 'course'; expected 'model'"),
        ({"turn_rate_on": 1.0}, r"need by = 'motion'"),
        ({"by": "motion", "turn_rate_on": 0.2, "turn_rate_off": 0.3}, "turn_rate_off ≤ turn_rate_on"),
        ({"by": "motion", "stop_speed": -1.0}, "stop_speed"),
    ],
)
def test_bad_segment_rules_are_config_errors(segments, match):
    with pytest.raises(ConfigError, match=match):
        load_config(_config() | {"segments": segments})
