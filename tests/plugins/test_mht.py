"""Track-oriented MHT (plugins/filters/mht.py): equal to NN with one hypothesis and a one-scan window, to the
KF without clutter, probabilities, the N-scan rule and cap, recovery where NN loses the track (SPEC §6)."""

import numpy as np
import pytest
from _filters_support import LAYOUT, position_sensor, straight

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import get_registry
from hybridtrack.engine.clutter import ClutterModel, region_around, simulate_scans
from hybridtrack.engine.schedule import Schedule
from hybridtrack.engine.simulate import simulate_trajectory
from hybridtrack.sdk.scans import Scan
from hybridtrack.testing import check_estimator
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.filters.mht import MHTFilter
from hybridtrack_plugins.filters.nearest_neighbour import NearestNeighbourFilter
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])


def _turning_scans(seed, density, detection_probability=0.9):
    """The turning run of test_nearest_neighbour's clutter test: 151 steps, R = 0.1 I, scans over the track ± 3 m."""
    sensor = PositionSensor("pos", ("x", "y"), np.eye(2) * 0.1)
    schedule = Schedule.from_rows([("left_turn", 60, 3.0), ("straight", 30), ("right_turn", 60, 5.0)])
    truth = simulate_trajectory(schedule, X0, 0.1, seed=seed, noise_cov=np.eye(2) * 0.001)
    model = ClutterModel(density, detection_probability, region_around(truth.positions, 3.0))
    scans = simulate_scans(truth, [sensor], model, seed=seed)["pos"]
    bank = TransitionBank.stack([get_registry().create("motion_model", "straight", noise_cov=np.eye(2) * 0.1).transition(0.1, X0)])
    return truth, scans, sensor, bank


def _run(estimator, scans, sensor, bank, each=None):
    state = estimator.initialize(X0[None], np.eye(4)[None] * 0.1)
    means = []
    for k in range(scans.steps):
        if k:
            state = estimator.predict(state, bank)
        state, innovation = estimator.update(state, scans.scan(k), [sensor], LAYOUT)
        if each is not None:
            each(k, state, innovation)
        means.append(estimator.mean(state)[0].copy())
    return np.array(means), state


def test_one_hypothesis_and_a_one_scan_window_is_nearest_neighbour_in_clutter():
    # λ = 1e-3 in the score: the missed branch never beats a gated candidate
    # (d² threshold 2[ln(P_D/λ) − ln√|2πS| − ln(1 − P_D P_G)] > γ), so the best child is NN's choice
    truth, scans, sensor, bank = _turning_scans(seed=3, density=0.1)
    nn, mht = NearestNeighbourFilter(0.99), MHTFilter(0.9, 1e-3, 0.99, window=1, max_hypotheses=1)
    records = {"nn": [], "mht": []}
    nn_means, nn_state = _run(nn, scans, sensor, bank, lambda k, s, i: records["nn"].append((s.P.copy(), i)))
    mht_means, mht_state = _run(mht, scans, sensor, bank, lambda k, s, i: records["mht"].append((mht.covariance(s).copy(), i)))
    np.testing.assert_allclose(mht_means, nn_means, rtol=1e-12, atol=1e-12)
    chosen = 0
    for (P_nn, i_nn), (P_mht, i_mht) in zip(records["nn"], records["mht"]):
        np.testing.assert_allclose(P_mht, P_nn, rtol=1e-12, atol=1e-12)
        a, b = i_nn.associations[0], i_mht.associations[0]
        np.testing.assert_array_equal(b.selected, a.selected)
        np.testing.assert_array_equal(b.weights, a.weights)
        np.testing.assert_array_equal(b.missed, a.missed)
        np.testing.assert_allclose(b.distances, a.distances, rtol=1e-12)
        np.testing.assert_allclose(i_mht.nu, i_nn.nu, rtol=1e-12, atol=1e-12)
        chosen += int(a.selected[0] >= 0)
    assert chosen > 100 and scans.counts.mean() > 20  # a cluttered run with real choices


@pytest.mark.parametrize("through", ["scan", "stacked z"])
def test_without_clutter_and_with_certain_detection_it_is_the_kalman_filter(through):
    mht, kf = MHTFilter(1.0, 0.05, None, window=3, max_hypotheses=5), KalmanFilter()
    rng = np.random.default_rng(4)
    sensor, bank = position_sensor(), TransitionBank.stack([straight(), straight()])
    prior = (np.array([[0.0, 0, 0, 2], [1.0, 0, 0, 1]]), np.stack([np.eye(4), 2 * np.eye(4)]))
    s_mht, s_kf = mht.initialize(*prior), kf.initialize(*prior)
    for k in range(30):
        z = np.array([0.0, 0.2 * k]) + rng.normal(0, 0.1, 2)
        s_mht, i_mht = mht.update(mht.predict(s_mht, bank), Scan("pos", z) if through == "scan" else z, [sensor], LAYOUT)
        s_kf, i_kf = kf.update(kf.predict(s_kf, bank), z, [sensor], LAYOUT)
        np.testing.assert_allclose(mht.mean(s_mht), s_kf.x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(mht.covariance(s_mht), s_kf.P, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(i_mht.loglik, i_kf.loglik, rtol=1e-12)
        np.testing.assert_array_equal(s_mht.count, [1, 1])  # the missed branch has score −∞
        np.testing.assert_array_equal(i_mht.probabilities[:, 0], [1.0, 1.0])


def test_scores_are_the_log_likelihood_ratio_and_probabilities_their_softmax():
    # hand-derived: prior P = I, R = I → S = 2 I, two candidates, P_D = 0.9, λ = 0.1, P_G = 0.99
    sensor = position_sensor(R=np.eye(2))
    mht = MHTFilter(0.9, 0.1, 0.99, window=2, max_hypotheses=10)
    state, innovation = mht.update(
        mht.initialize(np.zeros((1, 4)), np.eye(4)[None]), Scan("pos", [[1.0, 0.0], [0.0, 2.0]]), [sensor], LAYOUT
    )
    half = np.log(2 * np.pi * 2.0)  # ln √|2π S| for S = 2 I
    expected = sorted([np.log(1 - 0.9 * 0.99), np.log(0.9 / 0.1) - 0.5 * 0.5 - half, np.log(0.9 / 0.1) - 0.5 * 2.0 - half], reverse=True)
    np.testing.assert_allclose(state.scores[0, :3], expected, rtol=1e-12)
    assert np.all(np.isneginf(state.scores[0, 3:])) and state.count[0] == 3
    p = np.exp(np.array(expected) - np.logaddexp.reduce(expected))
    np.testing.assert_allclose(state.probabilities[0, :3], p, rtol=1e-12)
    np.testing.assert_allclose(innovation.probabilities, state.probabilities)
    a = innovation.associations[0]
    assert a.selected[0] == 0  # the best hypothesis took the nearer candidate
    np.testing.assert_allclose(a.weights[0].sum() + a.missed[0], 1.0, rtol=1e-12)
    # the best hypothesis is a Kalman update with candidate 0
    kf = KalmanFilter()
    ref, _ = kf.update(kf.initialize(np.zeros((1, 4)), np.eye(4)[None]), np.array([1.0, 0.0]), [sensor], LAYOUT)
    np.testing.assert_allclose(mht.mean(state), ref.x, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("window, cap", [(1, 50), (2, 50), (3, 4)])
def test_the_n_scan_rule_and_the_cap_bound_the_hypotheses_and_probabilities_sum_to_one(window, cap):
    truth, scans, sensor, bank = _turning_scans(seed=1, density=0.1)
    mht = MHTFilter(0.9, 0.1, 0.99, window=window, max_hypotheses=cap)
    gated = []

    def check(k, state, innovation):
        count = int(state.count[0])
        assert 1 <= count <= cap
        np.testing.assert_allclose(state.probabilities.sum(axis=1), 1.0, rtol=1e-12)
        assert np.all(np.diff(state.scores[0, :count]) <= 0)  # sorted, best first
        live = state.history[0, :count]
        assert len({tuple(h) for h in live}) == count  # no two live hypotheses share their last N decisions
        gated.append(int(innovation.associations[0].gated[0].sum()))
        if window == 1:  # one hypothesis per decision of this scan: missed or a candidate gated by some parent
            assert count <= 1 + scans.counts[k]

    _run(mht, scans, sensor, bank, check)
    assert max(gated) >= 2  # candidates did compete


@pytest.mark.slow
def test_mht_recovers_where_nearest_neighbour_loses_the_track():
    """Seeded: 20 turning runs, P_D = 0.9, λ = 0.1 /m² (≈ 32 candidates per scan, ≈ 1.4 false per gate).

    Lost: position error > 2 m over the last 10 steps.  Measured: NN 6/20, MHT (N = 2, cap 5) 0/20.
    """
    lost = {"nn": 0, "mht": 0}
    for seed in range(20):
        truth, scans, sensor, bank = _turning_scans(seed, density=0.1)
        for name, estimator in (("nn", NearestNeighbourFilter(0.99)), ("mht", MHTFilter(0.9, 0.1, 0.99, window=2, max_hypotheses=5))):
            means, _ = _run(estimator, scans, sensor, bank)
            errors = np.hypot(*(means[:, [0, 2]] - truth.positions).T)
            lost[name] += bool(np.all(errors[-10:] > 2.0))
    assert lost["mht"] <= 1 and lost["nn"] >= lost["mht"] + 3, lost


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"detection_probability": 0.0}, "detection_probability"),
        ({"detection_probability": 1.2}, "detection_probability"),
        ({"clutter_density": 0.0}, "clutter_density"),
        ({"clutter_density": -1.0}, "clutter_density"),
        ({"clutter_density": np.inf}, "clutter_density"),
        ({"window": 0}, "window"),
        ({"window": 1.5}, "window"),
        ({"max_hypotheses": 0}, "max_hypotheses"),
        ({"max_hypotheses": True}, "max_hypotheses"),
        ({"gate_probability": 1.0}, "gate_probability"),
        ({"form": "nope"}, "form"),
    ],
)
def test_bad_parameters_raise_value_errors_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        MHTFilter(**kwargs)


def test_contract_and_bank_operations_keep_the_hypothesis_axis():
    mht = get_registry().create("estimator", "mht", **MHTFilter.example_parameters)
    assert not mht.exact_kalman and mht.accepts_scans
    check_estimator(mht)
    state = mht.initialize(np.zeros((3, 4)), np.tile(np.eye(4), (3, 1, 1)))
    sensor = position_sensor()
    state, _ = mht.update(state, Scan("pos", [[0.1, 0.0], [0.0, 0.3]]), [sensor], LAYOUT)
    taken = mht.take(state, [2, 0])
    assert taken.x.shape == (2, mht.max_hypotheses, 4) and taken.scores.shape == (2, mht.max_hypotheses)
    joined = mht.concatenate([mht.take(state, [0]), mht.take(state, [1, 2])])
    np.testing.assert_array_equal(joined.scores, state.scores)
    np.testing.assert_array_equal(joined.history, state.history)
