"""PMHT (plugins/filters/pmht.py): without clutter the window is the RTS smoother (filterpy), the E-step weights
and the EM fixed point by hand, monotone log posterior, the contract checks, bad parameters, reproducibility (SPEC §6)."""

import numpy as np
import pytest
from _filters_support import LAYOUT, position_sensor, straight
from filterpy.kalman import KalmanFilter as FilterpyKF

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import get_registry
from hybridtrack.engine.clutter import ClutterModel, region_around, simulate_scans
from hybridtrack.engine.schedule import Schedule
from hybridtrack.engine.simulate import simulate_trajectory
from hybridtrack.sdk.scans import Scan
from hybridtrack.testing import build_example, check_component, check_estimator
from hybridtrack_plugins.filters.pmht import PMHTFilter
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 1.0, 0.0, 0.5])
P0 = np.diag([0.5, 0.2, 0.5, 0.2])


def _clean_run(steps, seed=0):
    rng = np.random.default_rng(seed)
    sensor = position_sensor(R=np.array([[0.04, 0.01], [0.01, 0.09]]))
    t = straight(q=0.01)
    x = X0.copy()
    zs = []
    for _ in range(steps):
        x = t.apply(x) + t.G @ rng.multivariate_normal(np.zeros(2), t.Q)
        zs.append(sensor.H @ x + rng.multivariate_normal(np.zeros(2), sensor.noise_cov))
    return sensor, t, np.array(zs)


def _filterpy_rts(sensor, t, zs):
    kf = FilterpyKF(dim_x=4, dim_z=2)
    kf.x, kf.P = X0.copy(), P0.copy()
    kf.F, kf.Q, kf.H, kf.R = t.F, t.process_noise, sensor.H, sensor.noise_cov
    means, covs, _, _ = kf.batch_filter(zs)
    xs, Ps, _, _ = kf.rts_smoother(means, covs)
    return means, covs, xs, Ps


@pytest.mark.parametrize("steps", [3, 12])
@pytest.mark.parametrize("as_scan", [True, False])
def test_without_clutter_the_window_is_the_rts_smoother(steps, as_scan):
    # λ = 0, P_D = 1, one candidate per scan: w = 1, z̃ = z, R̃ = R; the window (5 scans) holds the RTS smoother's
    # estimates of its scans and the output is the Kalman filter's (filterpy's batch_filter + rts_smoother)
    window = 5
    sensor, t, zs = _clean_run(steps)
    means, covs, xs, Ps = _filterpy_rts(sensor, t, zs)
    pmht = PMHTFilter(1.0, 0.0, None, window=window)
    bank = TransitionBank.stack([t])
    state = pmht.initialize(X0[None], P0[None])
    for k, z in enumerate(zs):
        state = pmht.predict(state, bank)
        state, innovation = pmht.update(state, Scan(sensor.name, z) if as_scan else z, [sensor], LAYOUT)
        np.testing.assert_allclose(pmht.mean(state)[0], means[k], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(pmht.covariance(state)[0], covs[k], rtol=1e-9, atol=1e-9)
    # the whole window against filterpy's RTS smoother over the whole run: the last min(steps, W) scans
    # (smoothing with the filtered estimate before the window as prior is the same recursion)
    w = min(steps, window)
    np.testing.assert_allclose(state.smoothed_mean[0, -w:], xs[-w:], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(state.smoothed_covariance[0, -w:], Ps[-w:], rtol=1e-9, atol=1e-9)
    assert state.valid[0].sum() == w
    np.testing.assert_array_equal(state.weights[0, -w:, 0], 1.0)


def _hand_rts(prior_x, prior_P, F, Q, H, R, zs):
    """A hand-written KF + RTS over a window (the M-step on synthetic measurements with R / W)."""
    x, P = prior_x, prior_P
    xp, Pp, xf, Pf = [], [], [], []
    for z, Rt in zip(zs, R):
        x, P = F @ x, F @ P @ F.T + Q
        xp.append(x)
        Pp.append(P)
        if Rt is not None:
            S = H @ P @ H.T + Rt
            K = P @ H.T @ np.linalg.inv(S)
            x = x + K @ (z - H @ x)
            P = (np.eye(len(x)) - K @ H) @ P
        xf.append(x)
        Pf.append(P)
    xs, Ps = list(xf), list(Pf)
    for k in range(len(zs) - 2, -1, -1):
        C = Pf[k] @ F.T @ np.linalg.inv(Pp[k + 1])
        xs[k] = xf[k] + C @ (xs[k + 1] - xp[k + 1])
        Ps[k] = Pf[k] + C @ (Ps[k + 1] - Pp[k + 1]) @ C.T
    return np.array(xs), np.array(Ps)


def test_em_fixed_point_against_hand_computed_weights_and_smoother():
    # two scans of two candidates each, λ = 0.05, P_D = 0.8: at convergence the weights are the E-step's
    # P_D N(z; H x̂, R) / (λ + P_D N(z; H x̂, R)) at the smoothed means, and the smoothed means are the hand
    # RTS on the synthetic measurements z̃ = Σ w z / Σ w with R / Σ w (to the EM tolerance)
    sensor = position_sensor(R=np.eye(2) * 0.05)
    t = straight(q=0.01)
    scans = [np.array([[0.12, 0.04], [0.6, -0.3]]), np.array([[0.2, 0.12], [-0.25, 0.3]])]
    pmht = PMHTFilter(0.8, 0.05, None, window=2, max_iterations=200, tolerance=1e-13)
    bank = TransitionBank.stack([t])
    state = pmht.initialize(X0[None] * 0, P0[None])
    for z in scans:
        state = pmht.predict(state, bank)
        state, innovation = pmht.update(state, Scan(sensor.name, z), [sensor], LAYOUT)
    xs = state.smoothed_mean[0]
    R = sensor.noise_cov
    weights = []
    for k, z in enumerate(scans):
        nu = z - sensor.H @ xs[k]
        N = np.exp(-0.5 * np.einsum("li,ij,lj->l", nu, np.linalg.inv(R), nu)) / (2 * np.pi * np.sqrt(np.linalg.det(R)))
        weights.append(0.8 * N / (0.05 + 0.8 * N))
    weights = np.array(weights)
    np.testing.assert_allclose(state.weights[0, :, :2], weights, rtol=1e-6, atol=1e-8)
    zsyn = [(w[:, None] * z).sum(0) / w.sum() for w, z in zip(weights, scans)]
    hand_xs, hand_Ps = _hand_rts(np.zeros(4), P0, t.F, t.process_noise, sensor.H, [R / w.sum() for w in weights], zsyn)
    np.testing.assert_allclose(xs, hand_xs, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(state.smoothed_covariance[0], hand_Ps, rtol=1e-6, atol=1e-8)
    # the newest scan's association record and the synthetic innovation
    a = innovation.associations[0]
    np.testing.assert_allclose(a.weights[0], weights[-1], rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(a.missed[0], np.prod(1 - weights[-1]), rtol=1e-6)
    used = state.weights[0, -1, :2]  # the weights of the last M-step
    expected = (used[:, None] * scans[-1]).sum(0) / used.sum() - sensor.H @ state.x_predicted[0]
    np.testing.assert_allclose(innovation.nu[0], expected, rtol=1e-12, atol=1e-12)
    assert 2 <= state.iterations[0] < 200


def _turning_scans(seed, density, detection_probability=0.9):
    sensor = PositionSensor("pos", ("x", "y"), np.eye(2) * 0.1)
    schedule = Schedule.from_rows([("left_turn", 30, 3.0), ("straight", 20)])
    x0 = np.array([0.0, 0.0, 0.0, 2.0])
    truth = simulate_trajectory(schedule, x0, 0.1, seed=seed, noise_cov=np.eye(2) * 0.001)
    model = ClutterModel(density, detection_probability, region_around(truth.positions, 3.0))
    scans = simulate_scans(truth, [sensor], model, seed=seed)["pos"]
    bank = TransitionBank.stack([get_registry().create("motion_model", "straight", noise_cov=np.eye(2) * 0.1).transition(0.1, x0)])
    return truth, scans, sensor, bank, x0


def _run(estimator, scans, sensor, bank, x0, M=1):
    state = estimator.initialize(np.repeat(x0[None], M, 0), np.repeat(np.eye(4)[None] * 0.1, M, 0))
    means, innovations = [], []
    for k in range(scans.steps):
        if k:
            state = estimator.predict(state, bank)
        state, innovation = estimator.update(state, scans.scan(k), [sensor], LAYOUT)
        means.append(estimator.mean(state).copy())
        innovations.append(innovation)
    return np.array(means), state, innovations


def test_in_clutter_tracks_and_is_seeded_reproducible():
    truth, scans, sensor, bank, x0 = _turning_scans(seed=4, density=0.1)
    pmht = get_registry().create("estimator", "pmht", detection_probability=0.9, clutter_density=0.1, window=3)
    a, state, innovations = _run(pmht, scans, sensor, bank, x0)
    b, _, _ = _run(pmht, scans, sensor, bank, x0)
    np.testing.assert_array_equal(a, b)
    error = np.linalg.norm(a[:, 0, [0, 2]] - truth.states[: scans.steps, [0, 2]], axis=1)
    assert error[-10:].max() < 1.0
    assert all(np.isfinite(i.loglik).all() for i in innovations)
    assert state.iterations.max() <= pmht.max_iterations


def test_bank_rows_are_independent_of_each_other():
    # a filter's EM stops on its own criterion: the same filter in a bank of 3 with other priors steps identically
    truth, scans, sensor, bank, x0 = _turning_scans(seed=5, density=0.1)
    pmht = PMHTFilter(0.9, 0.1, 0.99, window=3)
    bank3 = TransitionBank.stack(
        [
            bank_t
            for bank_t in [
                get_registry().create("motion_model", "straight", noise_cov=np.eye(2) * q).transition(0.1, x0) for q in (0.1, 1.0, 0.01)
            ]
        ]
    )
    single, _, _ = _run(pmht, scans, sensor, bank, x0)
    state = pmht.initialize(np.repeat(x0[None], 3, 0), np.repeat(np.eye(4)[None] * 0.1, 3, 0))
    for k in range(scans.steps):
        if k:
            state = pmht.predict(state, bank3)
        state, _ = pmht.update(state, scans.scan(k), [sensor], LAYOUT)
    np.testing.assert_allclose(state.x[0], single[-1, 0], rtol=1e-12, atol=1e-12)


def test_contract_checks():
    check_component("estimator", build_example(get_registry().entry("estimator", "pmht").factory))
    # λ = 0 and no gate with a longer window: exact Kalman filter, compared by the checks with the covariance KF
    estimator = PMHTFilter(1.0, 0.0, None, window=4)
    assert estimator.exact_kalman
    check_estimator(estimator)
    check_estimator(PMHTFilter(0.7, 0.05, 0.95, window=1, form="symmetric"))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"detection_probability": 0.0}, "detection_probability"),
        ({"detection_probability": 1.5}, "detection_probability"),
        ({"clutter_density": -1.0}, "clutter_density"),
        ({"clutter_density": float("nan")}, "clutter_density"),
        ({"gate_probability": 1.0}, "gate_probability"),
        ({"window": 0}, "window"),
        ({"window": 2.5}, "window"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"tolerance": 0.0}, "tolerance"),
        ({"tolerance": "x"}, "tolerance"),
        ({"form": "nope"}, "form"),
    ],
)
def test_bad_parameters_raise_naming_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        PMHTFilter(**kwargs)


def test_a_sensor_with_measurement_dependent_noise_is_refused_for_scans():
    from hybridtrack.testing import example_parameters

    radar = get_registry().create("sensor", "radar", **example_parameters(get_registry().entry("sensor", "radar").factory))
    pmht = PMHTFilter()
    state = pmht.initialize(np.array([[100.0, 0, 100.0, 0]]), np.eye(4)[None])
    z = np.array([[100.0, 100.0]])
    with pytest.raises(ValueError, match="sensors"):
        pmht.update(state, Scan(radar.name, z), [radar], LAYOUT)


@pytest.mark.parametrize(("name", "parameters"), [("pmht", {"clutter_density": 0.5, "window": 3}), ("msda", {"window": 2})])
def test_pipeline_runs_the_bank_on_candidates_and_records_the_weights(tmp_path, name, parameters, clutter_scenario, clutter_pipeline):
    from hybridtrack.recording import RerunRecorder
    from hybridtrack.recording.inspection import RecordingFile

    truth, sensor, scans = clutter_scenario()
    path = tmp_path / f"{name}.rrd"
    with RerunRecorder(path, {"seed": 2}) as recorder:
        pipeline = clutter_pipeline((name, parameters), sensor, scans, recorder=recorder, truth=truth)
        result = pipeline.run()
    assert result.means.shape == (31, 2, 4)
    assert np.abs(result.means[:15, 0, [0, 2]] - truth.positions[:15]).max() < 0.5  # straight filter on the straight leg
    steps, beta = RecordingFile(path).series("estimator/straight/beta")
    expected = np.array(
        [[r.innovation.associations[0].missed[0], r.innovation.associations[0].weights[0].max(initial=0.0)] for r in pipeline.results]
    )
    np.testing.assert_array_equal(beta, expected)


def test_em_never_lowers_the_log_posterior():
    # the same state and scan with max_iterations = 1, 2, …: J after each EM iteration is nondecreasing
    truth, scans, sensor, bank, x0 = _turning_scans(seed=6, density=0.3)
    pmht = PMHTFilter(0.9, 0.3, 0.99, window=4)
    state = pmht.initialize(x0[None], np.eye(4)[None] * 0.1)
    for k in range(12):
        if k:
            state = pmht.predict(state, bank)
        state, _ = pmht.update(state, scans.scan(k), [sensor], LAYOUT)
    state = pmht.predict(state, bank)
    values = []
    for iterations in range(1, 8):
        after, _ = PMHTFilter(0.9, 0.3, 0.99, window=4, max_iterations=iterations, tolerance=1e-300).update(
            state, scans.scan(12), [sensor], LAYOUT
        )
        assert after.iterations[0] == iterations
        values.append(after.log_posterior[0])
    assert np.all(np.diff(values) >= -1e-9), values
    assert values[-1] > values[0]


def test_an_empty_scan_is_prediction_only_with_a_record():
    sensor = position_sensor()
    pmht = PMHTFilter(0.9, 0.1, 0.99, window=3)
    state = pmht.predict(pmht.initialize(X0[None], P0[None]), TransitionBank.stack([straight()]))
    after, innovation = pmht.update(state, Scan(sensor.name, np.zeros((0, 2))), [sensor], LAYOUT)
    np.testing.assert_array_equal(after.x, state.x)
    np.testing.assert_array_equal(after.valid, state.valid)
    assert innovation.measurement_dim == 0
    (record,) = innovation.associations
    assert record.selected[0] == -1 and record.missed[0] == 1.0 and record.weights.shape == (1, 0)
