"""Nearest-neighbour filter bank (plugins/filters/nearest_neighbour.py): Mahalanobis choice, gate,
equality with the Kalman update on the chosen candidate, per-filter gating in a bank (SPEC §6)."""

import numpy as np
import pytest
from _filters_support import LAYOUT, position_sensor, straight
from scipy.stats import chi2

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.sdk.scans import Scan
from hybridtrack.testing import check_estimator
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.filters.nearest_neighbour import NearestNeighbourFilter


def test_the_nearest_in_mahalanobis_distance_wins_not_the_nearest_in_metres():
    # S is elongated along x: a candidate 2 m away in x is nearer than one 1 m away in y
    sensor = position_sensor(R=np.diag([4.0, 0.01]))
    nn = NearestNeighbourFilter(gate_probability=None)
    prior = nn.initialize(np.zeros((1, 4)), np.eye(4)[None] * 1e-3)
    z = np.array([[0.0, 1.0], [2.0, 0.0]])
    state, innovation = nn.update(prior, Scan("pos", z), [sensor], LAYOUT)
    a = innovation.associations[0]
    assert a.selected[0] == 1
    np.testing.assert_array_equal(a.weights[0], [0.0, 1.0])
    kf = KalmanFilter()
    expected, kf_innovation = kf.update(kf.initialize(np.zeros((1, 4)), np.eye(4)[None] * 1e-3), z[1], [sensor], LAYOUT)
    np.testing.assert_allclose(state.x, expected.x, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(state.P, expected.P, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(innovation.nu, kf_innovation.nu, rtol=1e-12)
    np.testing.assert_allclose(a.loglik, kf_innovation.loglik, rtol=1e-12)


def test_the_gate_is_the_chi_square_quantile_and_rejects_what_lies_outside():
    sensor = position_sensor(R=np.eye(2))
    nn = NearestNeighbourFilter(gate_probability=0.95)
    prior = nn.initialize(np.zeros((1, 4)), np.eye(4)[None])  # S = 2 I
    gamma = chi2.ppf(0.95, 2)
    just_in, just_out = np.sqrt(2 * gamma) * 0.999, np.sqrt(2 * gamma) * 1.001
    state, innovation = nn.update(prior, Scan("pos", [[just_out, 0.0], [0.0, just_in]]), [sensor], LAYOUT)
    a = innovation.associations[0]
    assert a.gate == pytest.approx(gamma)
    np.testing.assert_array_equal(a.gated[0], [False, True])
    assert a.selected[0] == 1
    state, innovation = nn.update(prior, Scan("pos", [[just_out, 0.0]]), [sensor], LAYOUT)
    np.testing.assert_array_equal(state.x, prior.x)  # nothing gated: prediction only
    np.testing.assert_array_equal(state.P, prior.P)
    assert innovation.associations[0].selected[0] == -1 and innovation.associations[0].missed[0] == 1.0
    np.testing.assert_array_equal(innovation.nu, np.zeros((1, 2)))
    assert np.isnan(innovation.associations[0].loglik[0])


def test_each_filter_of_a_bank_chooses_and_gates_for_itself():
    sensor = position_sensor(R=np.eye(2) * 0.01)
    nn = NearestNeighbourFilter(gate_probability=0.99)
    mean = np.array([[0.0, 0, 0.0, 0], [5.0, 0, 0.0, 0], [50.0, 0, 50.0, 0]])
    prior = nn.initialize(mean, np.tile(np.eye(4) * 0.1, (3, 1, 1)))
    z = np.array([[0.1, 0.0], [5.2, 0.1]])
    state, innovation = nn.update(prior, Scan("pos", z), [sensor], LAYOUT)
    np.testing.assert_array_equal(innovation.associations[0].selected, [0, 1, -1])
    kf = KalmanFilter()
    for j, i in ((0, 0), (1, 1)):
        expected, _ = kf.update(kf.initialize(mean[j : j + 1], np.eye(4)[None] * 0.1), z[i], [sensor], LAYOUT)
        np.testing.assert_allclose(state.x[j], expected.x[0], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(state.P[j], expected.P[0], rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(state.x[2], mean[2])


def test_without_a_gate_and_one_candidate_nearest_neighbour_is_the_kalman_filter():
    nn = NearestNeighbourFilter(gate_probability=None)
    assert nn.exact_kalman and not NearestNeighbourFilter(0.99).exact_kalman
    check_estimator(nn)
    rng = np.random.default_rng(2)
    sensor, bank, kf = position_sensor(), TransitionBank.stack([straight()]), KalmanFilter()
    s_nn = nn.initialize(np.array([[0.0, 0, 0, 2]]), np.eye(4)[None])
    s_kf = kf.initialize(np.array([[0.0, 0, 0, 2]]), np.eye(4)[None])
    for k in range(20):
        z = np.array([0.0, 0.2 * k]) + rng.normal(0, 0.1, 2)
        s_nn, _ = nn.update(nn.predict(s_nn, bank), Scan("pos", z), [sensor], LAYOUT)
        s_kf, _ = kf.update(kf.predict(s_kf, bank), z, [sensor], LAYOUT)
        np.testing.assert_allclose(s_nn.x, s_kf.x, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(s_nn.P, s_kf.P, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("probability", [0.0, 1.0, -0.1, 2.0, float("nan")])
def test_gate_probability_outside_the_open_unit_interval_raises(probability):
    with pytest.raises(ValueError, match="gate_probability"):
        NearestNeighbourFilter(gate_probability=probability)


def test_a_nonlinear_or_measurement_dependent_sensor_is_refused():
    from hybridtrack.core.plugins import get_registry

    radar = get_registry().create("sensor", "radar", **_example(get_registry().get("sensor", "radar")))
    nn = NearestNeighbourFilter()
    state = nn.initialize(np.zeros((1, 4)) + [[100.0, 0, 100.0, 0]], np.eye(4)[None])
    with pytest.raises(ValueError, match="sensors"):
        nn.update(state, Scan(radar.name, [[100.0, 100.0]]), [radar], LAYOUT)


def _example(entry):
    from hybridtrack.testing import example_parameters

    return example_parameters(entry.factory if hasattr(entry, "factory") else entry)


def test_pda_keeps_tracks_that_nearest_neighbour_loses_in_clutter():
    """Seeded: 10 turning trajectories, P_D = 0.9, about 1.4 false measurements per gate (λ = 0.1 /m²).

    A track is lost when its position error exceeds 2 m over the last 10 steps.
    (experiments/clutter.py measures the same over densities; docs/clutter.md.)
    """
    from hybridtrack.core.plugins import get_registry
    from hybridtrack.engine.clutter import ClutterModel, region_around, simulate_scans
    from hybridtrack.engine.schedule import Schedule
    from hybridtrack.engine.simulate import simulate_trajectory
    from hybridtrack_plugins.filters.pda import PDAFilter
    from hybridtrack_plugins.sensors.position import PositionSensor

    x0 = np.array([0.0, 0.0, 0.0, 2.0])
    bank = TransitionBank.stack([get_registry().create("motion_model", "straight", noise_cov=np.eye(2) * 0.1).transition(0.1, x0)])
    sensor = PositionSensor("pos", ("x", "y"), np.eye(2) * 0.1)
    schedule = Schedule.from_rows([("left_turn", 60, 3.0), ("straight", 30), ("right_turn", 60, 5.0)])
    lost = {"nearest_neighbour": 0, "pda": 0}
    for seed in range(10):
        truth = simulate_trajectory(schedule, x0, 0.1, seed=seed, noise_cov=np.eye(2) * 0.001)
        scans = simulate_scans(truth, [sensor], ClutterModel(0.1, 0.9, region_around(truth.positions, 3.0)), seed=seed)["pos"]
        for name, estimator in (("nearest_neighbour", NearestNeighbourFilter(0.99)), ("pda", PDAFilter(0.9, 0.1, 0.99))):
            state = estimator.initialize(x0[None], np.eye(4)[None] * 0.1)
            errors = []
            for k in range(scans.steps):
                if k:
                    state = estimator.predict(state, bank)
                state, _ = estimator.update(state, scans.scan(k), [sensor], LAYOUT)
                errors.append(np.hypot(*(state.x[0, [0, 2]] - truth.positions[k])))
            lost[name] += bool(np.all(np.array(errors[-10:]) > 2.0))
    assert lost["pda"] <= 1 and lost["nearest_neighbour"] >= lost["pda"] + 2, lost
