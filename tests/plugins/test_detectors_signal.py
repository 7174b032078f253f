"""Signal function (SPEC §4; seed 000 eqs. 22–23): hand values, false-alarm rate under the correct model,
decentralized = centralized."""

import numpy as np
import pytest
from scipy.stats import binom, chi2

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.sdk.thresholds import THREE_SIGMA_ALPHA
from hybridtrack_plugins.detectors import signal_bounds
from hybridtrack_plugins.detectors.signal_function import SignalFunction
from hybridtrack_plugins.filters.decentralized import DecentralizedFilter
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.motion.linear_modes import LeftTurn, Straight
from hybridtrack_plugins.sensors.position import PositionSensor

LAYOUT = ("x", "vx", "y", "vy")
X0 = np.array([0.0, 0.0, 0.0, 2.0])


def test_standardized_statistic_by_hand():
    d = SignalFunction(reset_on_alarm=False)
    out = [d.observe(k, np.zeros(1), np.array([v]), 2) for k, v in enumerate([1.0, 5.0, 0.5])]
    # S_k = (Σ NIS − 2k)/√(4k)
    assert out[0].statistics["signal"][0] == pytest.approx((1 - 2) / 2)
    assert out[1].statistics["signal"][0] == pytest.approx((6 - 4) / np.sqrt(8))
    assert out[2].statistics["signal"][0] == pytest.approx((6.5 - 6) / np.sqrt(12))
    assert out[2].thresholds == {"upper": pytest.approx(3.0), "lower": pytest.approx(-3.0)}


def test_window_keeps_the_last_w_measured_steps_and_skips_missing_ones():
    d = SignalFunction(window=2, reset_on_alarm=False)
    d.observe(0, np.zeros(1), np.array([10.0]), 2)
    d.observe(1, np.zeros(1), np.array([0.0]), 0)  # no measurement
    d.observe(2, np.zeros(1), np.array([1.0]), 2)
    out = d.observe(3, np.zeros(1), np.array([3.0]), 2)
    assert out.statistics["signal"][0] == pytest.approx((4.0 - 4) / np.sqrt(8))


def test_alarm_outside_the_bounds_then_restart():
    d = SignalFunction()
    out = d.observe(0, np.zeros(1), np.array([40.0]), 2)
    assert out.decision is not None and out.decision.mode == "change"
    assert d.observe(1, np.zeros(1), np.array([2.0]), 2).statistics["signal"][0] == pytest.approx(0.0)


def correct_model_nis(runs, steps, seed, R=0.01):
    """NIS of a KF run on data of its own model, the runs stacked as a bank; x(0) ~ N(x̂0, P0)."""
    rng = np.random.default_rng(seed)
    model, sensor = Straight(), PositionSensor(noise_cov=np.eye(2) * R)
    t = model.transition(0.1, X0)
    P0 = np.eye(4)
    x = X0 + rng.standard_normal((runs, 4))
    kf = KalmanFilter()
    state = kf.initialize(np.tile(X0, (runs, 1)), np.tile(P0, (runs, 1, 1)))
    bank = TransitionBank(np.tile(t.F, (runs, 1, 1)), np.tile(t.B, (runs, 1)), np.tile(t.process_noise, (runs, 1, 1)))
    Lq = np.linalg.cholesky(model.noise_cov)
    nis = []
    for k in range(steps):
        if k:
            x = t.apply(x) + (rng.standard_normal((runs, 2)) @ Lq.T) @ t.G.T
            state = kf.predict(state, bank)
        z = x[:, [0, 2]] + np.sqrt(R) * rng.standard_normal((runs, 2))
        state, innovation = kf.update(state, z, [sensor], LAYOUT)
        nis.append(innovation.nis)
    return np.array(nis)  # (steps, runs)


def alarm_rate(detector, nis, check_steps):
    alarms = 0
    for k, values in enumerate(nis):
        out = detector.observe(k, np.zeros_like(values), values, 2)
        if k in check_steps:
            s = out.statistics["signal"]
            alarms += int(np.sum((s > out.thresholds["upper"]) | (s < out.thresholds["lower"])))
    return alarms


def binomial_interval(n, p, level=0.999):
    return binom.ppf((1 - level) / 2, n, p), binom.ppf(1 - (1 - level) / 2, n, p)


@pytest.fixture(scope="module")
def nis_sample():
    return correct_model_nis(runs=4000, steps=50, seed=7)


def test_nis_is_chi2_under_the_correct_model(nis_sample):
    assert nis_sample.mean() == pytest.approx(2.0, rel=0.01)


def test_false_alarm_rate_of_the_3sigma_rule_on_windows_of_10(nis_sample):
    """Disjoint windows of 10 steps (D = 20): the ±3 rule's rate equals the exact χ²(20) tail (≈ 0.0068, not 0.0027)."""
    check = {9, 19, 29, 39, 49}
    alarms = alarm_rate(SignalFunction(window=10, reset_on_alarm=False), nis_sample, check)
    n = 4000 * len(check)
    exact = signal_bounds.false_alarm_probability(20, -3.0, 3.0)
    assert exact == pytest.approx(chi2.sf(20 + 3 * np.sqrt(40), 20), rel=1e-6)  # lower tail ≈ 2e-10
    low, high = binomial_interval(n, exact)
    assert low <= alarms <= high, (alarms, n * exact)
    assert alarms > binomial_interval(n, THREE_SIGMA_ALPHA)[1]  # the normal approximation understates it at D = 20


def test_chi2_calibrated_bounds_give_the_nominal_0027(nis_sample):
    check = {9, 19, 29, 39, 49}
    alarms = alarm_rate(SignalFunction(window=10, calibration="chi2", reset_on_alarm=False), nis_sample, check)
    low, high = binomial_interval(4000 * len(check), THREE_SIGMA_ALPHA)
    assert low <= alarms <= high


def test_cumulative_statistic_at_step_50_matches_the_chi2_100_tail(nis_sample):
    alarms = alarm_rate(SignalFunction(reset_on_alarm=False), nis_sample, {49})
    low, high = binomial_interval(4000, signal_bounds.false_alarm_probability(100, -3.0, 3.0))
    assert low <= alarms <= high


def test_signal_function_alarms_after_a_mode_change():
    """Data from a left turn r = 3 seen by the straight filter: the signal function leaves ±3."""
    from hybridtrack.core.types import Gaussian
    from hybridtrack.engine.pipeline import Pipeline
    from hybridtrack.engine.schedule import Schedule
    from hybridtrack.engine.simulate import simulate

    schedule = Schedule.from_rows([("straight", 20), ("left_turn", 40, 3.0)])
    sensors = [PositionSensor()]
    _, z = simulate(schedule, X0, 0.1, sensors, seed=3, noise_cov=np.diag([1e-3, 1e-3]))
    run = Pipeline(
        models=[Straight(noise_cov=np.diag([1e-3, 1e-3]))],
        estimator="kalman",
        sensors=sensors,
        measurements=z,
        prior=Gaussian(X0, np.eye(4)),
        tau=0.1,
        detectors=[SignalFunction(window=10)],
    ).run()
    assert run.decisions and all(d.step > 20 for d in run.decisions)


def test_decentralized_signal_function_equals_the_centralized_one():
    """Each node's NIS from its own information filter + the broadcast terms (seed 000 eq. 22) → same S_k."""
    rng = np.random.default_rng(11)
    sensors = [
        PositionSensor(name="a"),
        PositionSensor(name="b", components="x", noise_cov=[[0.04]]),
        PositionSensor(name="c", components="y", noise_cov=[[0.02]]),
    ]
    models = [Straight(), LeftTurn(radius=5.0)]
    transitions = TransitionBank.stack([m.transition(0.1, X0) for m in models])
    central, decentral = KalmanFilter(), DecentralizedFilter()
    prior = (np.tile(X0, (2, 1)), np.tile(np.eye(4), (2, 1, 1)))
    sc, sd = central.initialize(*prior), decentral.initialize(*prior)
    det_c = SignalFunction(window=5, reset_on_alarm=False)
    det_nodes = [SignalFunction(window=5, reset_on_alarm=False) for _ in sensors]
    x = X0.copy()
    worst = 0.0
    for k in range(30):
        if k:
            x = models[0].transition(0.1, X0).apply(x) + np.array([0, 0.1, 0, 0.1]) * rng.standard_normal(4)
            sc, sd = central.predict(sc, transitions), decentral.predict(sd, transitions)
        z = np.concatenate(
            [x[[0, 2]] + 0.1 * rng.standard_normal(2), [x[0] + 0.2 * rng.standard_normal()], [x[2] + 0.14 * rng.standard_normal()]]
        )
        sc, inn = central.update(sc, z, sensors, LAYOUT)
        sd, _ = decentral.update(sd, z, sensors, LAYOUT)
        ref = det_c.step(k, inn).statistics["signal"]
        for i, d in enumerate(det_nodes):
            local = d.observe(k, sd.node_loglik[i], sd.node_nis[i], inn.measurement_dim).statistics["signal"]
            worst = max(worst, float(np.max(np.abs(local - ref))))
    assert worst <= 1e-9
