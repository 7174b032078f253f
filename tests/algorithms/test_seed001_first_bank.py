"""Seed 001's first bank is built from the given initial state x0 (Algorithm 1: x̂ := x0), as the optimal KF does.

The defect this guards against: updating the prior N(x0, I) with z_0 first and
building the first bank's turn centres and ω from that updated estimate moves
the switch state by about 0.5 m per axis at R = 1 (the truth starts exactly at
x0, and P0 = I overstates its uncertainty), so the first turn orbits a wrong
centre and every later bank inherits the bias.
"""

import numpy as np

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.known_modes import run_known_modes
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.simulate import simulate
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.motion.linear_modes import LeftTurn
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
Q = 0.001 * np.eye(2)
LAYOUT = ("x", "vx", "y", "vy")
SCHEDULE = Schedule.from_rows([("left_turn", 40, 3.0)])


def _case(seed: int):
    sensors = [PositionSensor(noise_cov=np.eye(2))]  # R = 1
    truth, z = simulate(SCHEDULE, X0, 0.1, sensors, seed=seed, noise_cov=Q)
    return sensors, truth, z


def _filter_with_transition_from(switch_state, sensors, z) -> np.ndarray:
    """A left-turn r = 3 filter from N(x0, I), its transition fixed at ``switch_state``: position errors per step."""
    bank = FilterBank(KalmanFilter(), LAYOUT, sensors)
    bank.start(X0, np.eye(4), [LeftTurn(radius=3.0, noise_cov=Q)], switch_state)
    bank.step(None, next(iter(z.values()))[:1])
    means = [bank.means[0]]
    for k in range(1, SCHEDULE.total_steps + 1):
        bank.step(0.1, next(iter(z.values()))[k : k + 1])
        means.append(bank.means[0])
    return np.array(means)


def test_a_step_zero_update_moves_the_first_turn_centre():
    shift = []
    for seed in range(40):
        sensors, _, z = _case(seed)
        start = FilterBank(KalmanFilter(), LAYOUT, sensors)
        start.start(X0, np.eye(4), [LeftTurn(radius=3.0, noise_cov=Q)], X0)
        start.step(None, next(iter(z.values()))[:1])
        shift.append(np.abs(LeftTurn(radius=3.0).turn_centre(start.means[0]) - LeftTurn(radius=3.0).turn_centre(X0)))
    assert 0.3 < np.mean(shift) < 0.8  # the reported ≈ 0.5 m per axis


def test_the_adaptive_estimators_first_bank_equals_the_filter_told_the_mode():
    for seed in range(3):
        sensors, _, z = _case(seed)
        adaptive = KnownSwitchAdaptive(modes=[("left_turn", {"radius": 3.0, "noise_cov": Q})], sensors=sensors, tau=0.1)
        run = adaptive.run(z, Gaussian(X0, np.eye(4)), SCHEDULE)
        optimal = run_known_modes(
            SCHEDULE, estimator="kalman", sensors=sensors, measurements=z, prior=Gaussian(X0, np.eye(4)), tau=0.1, noise_cov=Q
        )
        np.testing.assert_allclose(run.means, optimal.means, rtol=0, atol=1e-12)
        # the defect's construction (transition fixed at x0 updated with z_0) is a different filter
        start = FilterBank(KalmanFilter(), LAYOUT, sensors)
        start.start(X0, np.eye(4), [LeftTurn(radius=3.0, noise_cov=Q)], X0)
        start.step(None, next(iter(z.values()))[:1])
        defect = _filter_with_transition_from(start.means[0], sensors, z)
        assert np.abs(defect - optimal.means).max() > 0.05
