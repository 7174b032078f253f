"""The modes for recorded motion (plugins/motion/real_motion.py): the coordinated turn with ω in the state against
the fixed-radius turn of the seeds (two independent exact circles), its bound on ω, the speed change against the
hand-derived straight-line acceleration, the noise per second, the contract, and an EKF with the coordinated turn
estimating a real turn rate from 10 s reports."""

import numpy as np
import pytest
from filterpy.common import Q_continuous_white_noise

from hybridtrack.core.plugins import resolve
from hybridtrack.testing import check_motion_model
from hybridtrack_plugins.motion.linear_modes import LeftTurn, RightTurn
from hybridtrack_plugins.motion.real_motion import CoordinatedTurn, SpeedChange


@pytest.mark.parametrize("omega", [0.03, -0.03, 1e-9, 0.0])
@pytest.mark.parametrize("dt", [1.0, 10.0])
def test_coordinated_turn_equals_the_fixed_radius_turn(omega, dt):
    """Same speed and rate: the seeds' turn of radius |v|/|ω| (turn centre from the switch state, B ≠ 0) and the
    coordinated turn (ω in the state) trace one circle, step for step."""
    x4 = np.array([1.0e5, 6.0, -2.0e6, 8.0])  # map-grid coordinates
    model = CoordinatedTurn(max_rate=0.2)
    x5 = np.append(x4, omega)
    if omega == 0.0:
        expected = x4 + dt * np.array([x4[1], 0.0, x4[3], 0.0])
    else:
        turn = (LeftTurn if omega > 0 else RightTurn)(radius=10.0 / abs(omega))
        expected = turn.transition(dt, x4).apply(x4)
    got = model.propagate(x5, dt)
    np.testing.assert_allclose(got[:4], expected, rtol=1e-13, atol=1e-9)
    assert got[4] == omega


def test_turn_rate_is_bounded():
    model = CoordinatedTurn(max_rate=0.05)
    x = np.array([0.0, 10.0, 0.0, 0.0, 0.5])  # ten times the limit
    out = model.propagate(x, 10.0)
    assert out[4] == 0.05
    np.testing.assert_allclose(out[:4], model.propagate(np.append(x[:4], 0.05), 10.0)[:4], rtol=1e-15)
    J = model.transition(10.0, x).F
    assert np.all(J[:, 4] == 0.0)  # no derivative where the limit holds
    inside = model.transition(10.0, np.append(x[:4], 0.01)).F
    assert inside[4, 4] == 1.0 and np.all(inside[:4, 4] != 0.0)


def test_speed_change_is_straight_line_acceleration():
    """p⁺ = p + v Δt + a u Δt²/2, v⁺ = v + a u Δt along u = v/|v|; no heading (and no NaN) at zero speed."""
    model = SpeedChange()
    x = np.array([3.0e5, 3.0, 4.0e6, 4.0, -0.5])
    got = model.propagate(x, 4.0)
    # u = (0.6, 0.8), a Δt = −2, a Δt²/2 = −4
    np.testing.assert_allclose(
        got, [3.0e5 + 12.0 - 0.5 * 8.0 * 0.6, 3.0 - 2.0 * 0.6, 4.0e6 + 16.0 - 0.5 * 8.0 * 0.8, 4.0 - 2.0 * 0.8, -0.5], rtol=1e-15
    )
    with np.errstate(all="raise"):
        still = model.propagate(np.array([1.0, 0.0, 2.0, 0.0, 1.0]), 4.0)
        J = model.transition(4.0, np.array([1.0, 0.0, 2.0, 0.0, 1.0])).F
    np.testing.assert_array_equal(still, [1.0, 0.0, 2.0, 0.0, 1.0])
    assert np.all(np.isfinite(J))


@pytest.mark.parametrize(
    "model", [CoordinatedTurn(noise_density=0.3, rate_density=1e-5), SpeedChange(noise_density=0.3, jerk_density=2e-3)]
)
@pytest.mark.parametrize("dt", [0.5, 10.0, 200.0])
def test_noise_per_second(model, dt):
    """Q(Δt): white acceleration per axis (FilterPy's Q_continuous_white_noise to 1e-12) and a random walk of ω or
    a_along, q Δt."""
    Q = model.transition(dt, np.array([0.0, 5.0, 0.0, 5.0, 0.01])).process_noise
    block = Q_continuous_white_noise(2, dt, 0.3)
    for axis in (slice(0, 2), slice(2, 4)):
        np.testing.assert_allclose(Q[axis, axis], block, rtol=1e-12)
    extra = model.rate_density if isinstance(model, CoordinatedTurn) else model.jerk_density
    assert Q[4, 4] == pytest.approx(extra * dt, rel=1e-12)
    assert np.count_nonzero(Q[:4, 4]) == 0 and np.count_nonzero(Q[0:2, 2:4]) == 0
    bank = model.linearize(dt, np.array([[0.0, 5.0, 0.0, 5.0, 0.01]] * 3))
    np.testing.assert_allclose(bank.Q[2], Q, rtol=1e-12)
    np.testing.assert_allclose(bank.noise_root[1] @ bank.noise_root[1].T, Q, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("model", [CoordinatedTurn(), SpeedChange()])
def test_contract_and_registry(model):
    check_motion_model(model)
    assert resolve("motion_model", (model.name, {})) == model


@pytest.mark.parametrize(
    ("factory", "kwargs", "match"),
    [
        (CoordinatedTurn, {"max_rate": 0.0}, "max_rate"),
        (CoordinatedTurn, {"rate_density": -1.0}, r"rate_density: expected a noise density in rad²/s³"),
        (SpeedChange, {"noise_density": float("nan")}, "noise_density"),
        (SpeedChange, {"jerk_density": "x"}, "jerk_density"),
    ],
)
def test_bad_parameters_are_named(factory, kwargs, match):
    with pytest.raises(ValueError, match=match):
        factory(**kwargs)


def test_ekf_estimates_the_turn_rate_from_ten_second_reports():
    """A ship at 8 m/s turning at 0.01 rad/s (0.57°/s, radius 800 m) seen every 10 s with σ = 10 m: the EKF with the
    coordinated turn, started at ω = 0, finds ω within 3σ of its own covariance and the truth within 0.002 rad/s
    after 30 reports, and never leaves the bound."""
    rng = np.random.default_rng(5)
    model = CoordinatedTurn(noise_density=1e-4, rate_density=1e-8, max_rate=0.1)
    truth = np.array([2.0e5, 8.0, 5.5e6, 0.0, 0.01])
    ekf = resolve("estimator", ("ekf", {}))
    sensor = resolve("sensor", ("position", {"noise_cov": 100.0 * np.eye(2)}))
    layout = model.layout
    z0 = truth[[0, 2]] + 10.0 * rng.standard_normal(2)
    state = ekf.initialize(np.array([[z0[0], 8.0, z0[1], 0.0, 0.0]]), np.diag([100.0, 4.0, 100.0, 4.0, 0.02**2])[None])
    for _ in range(30):
        truth = model.propagate(truth, 10.0)
        state = ekf.predict(state, model.linearizer(10.0))
        assert abs(ekf.mean(state)[0, 4]) <= 0.1  # an update may step out of the bound; the prediction comes back
        z = truth[[0, 2]] + 10.0 * rng.standard_normal(2)
        state, _ = ekf.update(state, z, [sensor], layout)
    omega, var = ekf.mean(state)[0, 4], ekf.covariance(state)[0, 4, 4]
    assert abs(omega - 0.01) < 3 * np.sqrt(var) and abs(omega - 0.01) < 2e-3, (omega, np.sqrt(var))
