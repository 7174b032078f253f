"""MSDA (plugins/filters/msda.py): a one-scan window is nearest neighbour, the Haar fusion by hand (the mean of the
window's residuals), missing entries, the contract checks, bad parameters, reproducibility (SPEC §6; seed 004)."""

import numpy as np
import pytest
from _filters_support import LAYOUT, position_sensor, straight

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import get_registry
from hybridtrack.engine.clutter import ClutterModel, region_around, simulate_scans
from hybridtrack.engine.schedule import Schedule
from hybridtrack.engine.simulate import simulate_trajectory
from hybridtrack.sdk.scans import Scan
from hybridtrack.testing import build_example, check_component, check_estimator
from hybridtrack_plugins.filters.msda import MSDAFilter
from hybridtrack_plugins.filters.nearest_neighbour import NearestNeighbourFilter
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])


def _turning_scans(seed, density, detection_probability=0.9, steps=(60, 30, 60)):
    sensor = PositionSensor("pos", ("x", "y"), np.eye(2) * 0.1)
    schedule = Schedule.from_rows([("left_turn", steps[0], 3.0), ("straight", steps[1]), ("right_turn", steps[2], 5.0)])
    truth = simulate_trajectory(schedule, X0, 0.1, seed=seed, noise_cov=np.eye(2) * 0.001)
    model = ClutterModel(density, detection_probability, region_around(truth.positions, 3.0))
    scans = simulate_scans(truth, [sensor], model, seed=seed)["pos"]
    bank = TransitionBank.stack([get_registry().create("motion_model", "straight", noise_cov=np.eye(2) * 0.1).transition(0.1, X0)])
    return truth, scans, sensor, bank


def _run(estimator, scans, sensor, bank, M=1):
    state = estimator.initialize(np.repeat(X0[None], M, 0), np.repeat(np.eye(4)[None] * 0.1, M, 0))
    means, covs, innovations = [], [], []
    for k in range(scans.steps):
        if k:
            state = estimator.predict(state, bank)
        state, innovation = estimator.update(state, scans.scan(k), [sensor], LAYOUT)
        means.append(estimator.mean(state).copy())
        covs.append(estimator.covariance(state).copy())
        innovations.append(innovation)
    return np.array(means), np.array(covs), innovations


def test_a_one_scan_window_is_nearest_neighbour_in_clutter():
    truth, scans, sensor, bank = _turning_scans(seed=3, density=0.1)
    nn, msda = NearestNeighbourFilter(0.99), MSDAFilter(0.99, window=1)
    assert msda.level == 0
    nn_means, nn_covs, nn_innovations = _run(nn, scans, sensor, bank)
    means, covs, innovations = _run(msda, scans, sensor, bank)
    np.testing.assert_allclose(means, nn_means, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(covs, nn_covs, rtol=1e-12, atol=1e-12)
    for a, b in zip(nn_innovations, innovations):
        np.testing.assert_allclose(b.nu, a.nu, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(b.loglik, a.loglik, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(b.associations[0].selected, a.associations[0].selected)
    assert sum(len(s) > 1 for s in scans.points) > 100  # clutter was there to choose from


def test_haar_fusion_is_the_mean_of_the_window_residuals_by_hand():
    # window 4, Haar, level 2: ν_p = the mean of the four chosen residuals, each against its own prediction;
    # the update is the Kalman update with ν_p, S = H P⁻ Hᵀ + R
    sensor = position_sensor(R=np.eye(2) * 0.05)
    t = straight(q=0.01)
    bank = TransitionBank.stack([t])
    scans = [np.array([[0.1, 0.0], [3.0, 3.0]]), np.array([[0.25, 0.05]]), np.array([[0.3, -0.1], [-2.0, 1.0]]), np.array([[0.4, 0.0]])]
    msda = MSDAFilter(None, window=4)
    assert msda.level == 2
    state = msda.initialize(np.zeros((1, 4)), np.eye(4)[None])
    x, P = np.zeros(4), np.eye(4)
    residuals = []
    H, R = sensor.H, sensor.noise_cov
    for z in scans:
        state = msda.predict(state, bank)
        state, innovation = msda.update(state, Scan(sensor.name, z), [sensor], LAYOUT)
        x, P = t.F @ x, t.F @ P @ t.F.T + t.process_noise
        S = H @ P @ H.T + R
        nus = z - H @ x
        d2 = np.einsum("li,ij,lj->l", nus, np.linalg.inv(S), nus)
        residuals.append(nus[np.argmin(d2)])
        # before the window fills, the missing entries are the newest residual
        window = [residuals[-1]] * (4 - len(residuals)) + residuals
        fused = np.mean(window, axis=0)
        K = P @ H.T @ np.linalg.inv(S)
        x = x + K @ fused
        P = (np.eye(4) - K @ H) @ P @ (np.eye(4) - K @ H).T + K @ R @ K.T
        np.testing.assert_allclose(innovation.nu[0], fused, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(state.x[0], x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(state.P[0], P, rtol=1e-12, atol=1e-12)


def test_an_empty_newest_scan_is_prediction_only_and_leaves_a_gap():
    sensor = position_sensor()
    bank = TransitionBank.stack([straight()])
    msda = MSDAFilter(0.99, window=2)
    state = msda.initialize(np.zeros((1, 4)), np.eye(4)[None] * 0.1)
    state = msda.predict(state, bank)
    predicted = state.x.copy()
    state, innovation = msda.update(state, Scan(sensor.name, [[50.0, 50.0]]), [sensor], LAYOUT)  # outside the gate
    np.testing.assert_array_equal(state.x, predicted)
    assert innovation.associations[0].selected[0] == -1
    assert state.dims[0, -1] == 0
    # the next scan: the gap takes the newest residual, so ν_p is that residual (NN's update)
    state = msda.predict(state, bank)
    state, innovation = msda.update(state, Scan(sensor.name, [[0.05, 0.0]]), [sensor], LAYOUT)
    np.testing.assert_allclose(innovation.nu[0], [0.05, 0.0] - sensor.H @ state.x_predicted[0], rtol=1e-12, atol=1e-12)


def test_reproducible_and_tracks_in_clutter():
    truth, scans, sensor, bank = _turning_scans(seed=4, density=0.05, steps=(30, 20, 10))
    msda = get_registry().create("estimator", "msda", window=4)
    a, _, _ = _run(msda, scans, sensor, bank)
    b, _, _ = _run(msda, scans, sensor, bank)
    np.testing.assert_array_equal(a, b)
    error = np.linalg.norm(a[:, 0, [0, 2]] - truth.states[: scans.steps, [0, 2]], axis=1)
    assert error[-10:].max() < 1.0


def test_contract_checks():
    check_component("estimator", build_example(get_registry().entry("estimator", "msda").factory))
    check_estimator(MSDAFilter(None, window=1, form="symmetric"))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"gate_probability": 0.0}, "gate_probability"),
        ({"window": 0}, "window"),
        ({"window": True}, "window"),
        ({"wavelet": "morl"}, "wavelet"),
        ({"wavelet": "nope"}, "wavelet"),
        ({"window": 4, "level": 3}, "level"),
        ({"window": 4, "level": -1}, "level"),
        ({"form": "nope"}, "form"),
    ],
)
def test_bad_parameters_raise_naming_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        MSDAFilter(**kwargs)
