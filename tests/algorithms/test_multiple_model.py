"""IMM, GPB1 and GPB2 (hybridtrack.algorithms.multiple_model) against FilterPy, a loop reference and their exact limits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.multiple_model import MultipleModelEstimator, sojourn_matrix
from hybridtrack.engine.layouts import union_layout
from hybridtrack.engine.simulate import simulate
from hybridtrack_plugins.motion.linear_modes import LAYOUT_4, LAYOUT_6, ConstantAcceleration, LeftTurn, RightTurn, Straight
from hybridtrack_plugins.sensors.position import PositionSensor

H4 = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
METHODS = ("imm", "gpb1", "gpb2")


def two_cv_problem(K=60, seed=1, tau=1.0):
    """Two CV models with different Q, a position sensor; truth switches Q at steps 20–40."""
    rng = np.random.default_rng(seed)
    q1, q2 = 0.01, 4.0
    R = np.array([[0.5, 0.1], [0.1, 0.8]])
    models = [Straight(noise_cov=np.eye(2) * q1), Straight(noise_cov=np.eye(2) * q2)]
    x0, P0 = np.array([0.0, 1.0, 0.0, 0.5]), np.diag([1.0, 0.5, 1.0, 0.5])
    truth = [x0]
    for k in range(K):
        q = q2 if 20 <= k < 40 else q1
        truth.append(models[0].transition(tau, x0).apply(truth[-1]) + np.array([0, 1, 0, 1]) * rng.normal(0, np.sqrt(q), 4))
    z = np.array(truth)[:, [0, 2]] + rng.multivariate_normal([0, 0], R, K + 1)
    return models, PositionSensor(noise_cov=R), x0, P0, z


# --------------------------------------------------------------------------- references


def kf_update(x, P, z, H, R):
    """Covariance KF update (Joseph form) and the Gaussian likelihood N(ν; 0, S)."""
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    nu = z - H @ x
    A = np.eye(len(x)) - K @ H
    return x + K @ nu, A @ P @ A.T + K @ R @ K.T, multivariate_normal(np.zeros(len(z)), S).pdf(nu)


def kf_predict(model, tau, x, P):
    """Prediction with the model's transition built at the starting mean (the rule under test)."""
    t = model.transition(tau, x)
    return t.F @ x + t.B, t.F @ P @ t.F.T + t.process_noise


def merge(w, xs, Ps):
    x = sum(wi * xi for wi, xi in zip(w, xs))
    return x, sum(wi * (Pi + np.outer(xi - x, xi - x)) for wi, xi, Pi in zip(w, xs, Ps))


def reference(method, models, Pi, x0, P0, mu0, z, tau, R):
    """A plain loop in linear probability space, straight from BLK 2001 §11.6 (4-state models, position sensor)."""
    r = len(models)
    xs, Ps, lik = zip(*[kf_update(x0, P0, z[0], H4, R) for _ in models])
    mu = mu0 * np.array(lik)
    mu /= mu.sum()
    xs, Ps = list(xs), list(Ps)
    out = [(*merge(mu, xs, Ps), mu.copy())]
    for k in range(1, len(z)):
        cbar = mu @ Pi
        if method == "gpb2":
            new_x, new_P, new_mu = [], [], np.zeros(r)
            for j in range(r):
                pair = [kf_update(*kf_predict(models[j], tau, xs[i], Ps[i]), z[k], H4, R) for i in range(r)]
                weights = np.array([Pi[i, j] * mu[i] * pair[i][2] for i in range(r)])
                new_mu[j] = weights.sum()
                x, P = merge(weights / weights.sum(), [p[0] for p in pair], [p[1] for p in pair])
                new_x.append(x)
                new_P.append(P)
            xs, Ps, mu = new_x, new_P, new_mu / new_mu.sum()
        else:
            if method == "imm":
                starts = [merge(Pi[:, j] * mu / cbar[j], xs, Ps) for j in range(r)]
            else:
                starts = [merge(mu, xs, Ps)] * r
            result = [kf_update(*kf_predict(models[j], tau, *starts[j]), z[k], H4, R) for j in range(r)]
            xs, Ps = [p[0] for p in result], [p[1] for p in result]
            mu = cbar * np.array([p[2] for p in result])
            mu /= mu.sum()
        out.append((*merge(mu, xs, Ps), mu.copy()))
    return [np.array(a) for a in zip(*out)]


# --------------------------------------------------------------------------- FilterPy


def test_imm_equals_filterpy_imm_estimator():
    filterpy = pytest.importorskip("filterpy.kalman")
    models, sensor, x0, P0, z = two_cv_problem(K=80)
    Pi = np.array([[0.95, 0.05], [0.1, 0.9]])
    mu0 = np.array([0.6, 0.4])
    z[0] = np.nan  # FilterPy's loop starts with predict: no update at step 0
    run = MultipleModelEstimator(models, Pi, sensors=[sensor], tau=1.0).run({"position": z}, (x0, P0), mode_probabilities=mu0)
    filters = []
    for model in models:
        t = model.transition(1.0, x0)
        f = filterpy.KalmanFilter(dim_x=4, dim_z=2)
        f.F, f.Q, f.H, f.R, f.x, f.P = t.F.copy(), t.process_noise.copy(), H4.copy(), sensor.noise_cov.copy(), x0.copy(), P0.copy()
        filters.append(f)
    imm = filterpy.IMMEstimator(filters, mu0.copy(), Pi.copy())
    errors = np.zeros(3)
    for k in range(1, z.shape[0]):
        imm.predict()
        imm.update(z[k])
        errors = np.maximum(
            errors,
            [np.abs(imm.x - run.means[k]).max(), np.abs(imm.P - run.covs[k]).max(), np.abs(imm.mu - run.mode_probabilities[k]).max()],
        )
    assert np.all(errors < 1e-9), errors
    assert np.allclose(run.mode_probabilities.sum(axis=1), 1.0)
    # the data switch to the noisy model in steps 20–40 and back
    assert run.mode[35] == 1 and run.mode[70] == 0


@pytest.mark.parametrize("method", METHODS)
def test_every_method_equals_the_loop_reference_with_turn_models(method):
    """Straight and two turns of radius 5: each turn's ω and centre from the filter's starting (mixed) estimate."""
    noise = np.diag([0.01, 0.01])
    schedule = Schedule.from_rows([("straight", 15), ("left_turn", 25, 5.0)])
    R = np.diag([0.05, 0.05])
    _, measurements = simulate(schedule, [0.0, 0.0, 0.0, 2.0], 0.1, [PositionSensor(noise_cov=R)], seed=3, noise_cov=noise)
    models = [Straight(noise_cov=noise), LeftTurn(radius=5.0, noise_cov=noise), RightTurn(radius=5.0, noise_cov=noise)]
    Pi = np.array([[0.9, 0.05, 0.05], [0.1, 0.85, 0.05], [0.1, 0.05, 0.85]])
    mu0 = np.array([0.8, 0.1, 0.1])
    x0, P0 = np.array([0.0, 0.0, 0.0, 2.0]), np.eye(4) * 0.5
    run = MultipleModelEstimator(models, Pi, sensors=[PositionSensor(noise_cov=R)], tau=0.1, method=method).run(
        measurements, (x0, P0), mode_probabilities=mu0
    )
    x, P, mu = reference(method, models, Pi, x0, P0, mu0, measurements["position"], 0.1, R)
    np.testing.assert_allclose(run.means, x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(run.covs, P, rtol=0, atol=1e-9)
    np.testing.assert_allclose(run.mode_probabilities, mu, rtol=0, atol=1e-9)
    assert run.mode_probabilities[-1, 1] > run.mode_probabilities[-1, 2]  # left turn over right turn


# --------------------------------------------------------------------------- limits where the methods coincide


def kalman_run(model, x0, P0, z, tau, R):
    xs, Ps = [], []
    x, P, _ = kf_update(x0, P0, z[0], H4, R)
    xs.append(x), Ps.append(P)
    for k in range(1, len(z)):
        x, P, _ = kf_update(*kf_predict(model, tau, x, P), z[k], H4, R)
        xs.append(x), Ps.append(P)
    return np.array(xs), np.array(Ps)


@pytest.mark.parametrize("method", METHODS)
def test_one_model_is_the_kalman_filter(method):
    models, sensor, x0, P0, z = two_cv_problem(K=30)
    run = MultipleModelEstimator(models[:1], [[1.0]], sensors=[sensor], tau=1.0, method=method).run({"position": z}, (x0, P0))
    x, P = kalman_run(models[0], x0, P0, z, 1.0, sensor.noise_cov)
    np.testing.assert_allclose(run.means, x, atol=1e-10)
    np.testing.assert_allclose(run.covs, P, atol=1e-10)
    assert np.all(run.log_mode_probabilities == 0.0)


@pytest.mark.parametrize("method", METHODS)
def test_identical_models_are_the_kalman_filter_and_the_probabilities_follow_the_chain(method):
    """All r filters are the same KF, so Λ_j is the same for every j and μ_k = μ_{k−1} Π exactly: μ_k = μ_0 Πᵏ."""
    models, sensor, x0, P0, z = two_cv_problem(K=30)
    Pi = np.array([[0.7, 0.2, 0.1], [0.3, 0.3, 0.4], [0.05, 0.05, 0.9]])
    mu0 = np.array([0.5, 0.3, 0.2])
    estimator = MultipleModelEstimator([models[1]] * 3, Pi, sensors=[sensor], tau=1.0, method=method)
    run = estimator.run({"position": z}, (x0, P0), mode_probabilities=mu0)
    x, P = kalman_run(models[1], x0, P0, z, 1.0, sensor.noise_cov)
    np.testing.assert_allclose(run.means, x, atol=1e-10)
    np.testing.assert_allclose(run.covs, P, atol=1e-10)
    np.testing.assert_allclose(run.model_means, np.repeat(x[:, None], 3, axis=1), atol=1e-10)
    chain = np.array([mu0 @ np.linalg.matrix_power(Pi, k) for k in range(z.shape[0])])
    np.testing.assert_allclose(run.mode_probabilities, chain, atol=1e-12)
    assert estimator.modes == ("straight_0", "straight_1", "straight_2")


def test_no_switching_imm_equals_gpb2_equals_independent_filters():
    """Π = I: μ_{i|j} = δ_ij (IMM) and only the pairs (j, j) carry weight (GPB2), so both are r independent KFs
    weighted by Bayes' rule μ_j ∝ μ_0,j Π_k Λ_j,k (the static multiple-model estimator).  GPB1 is not: it restarts
    every filter from the merged estimate."""
    models, sensor, x0, P0, z = two_cv_problem(K=50)
    mu0 = np.array([0.3, 0.7])
    runs = {
        m: MultipleModelEstimator(models, np.eye(2), sensors=[sensor], tau=1.0, method=m).run(
            {"position": z}, (x0, P0), mode_probabilities=mu0
        )
        for m in METHODS
    }
    independent = [kalman_run(model, x0, P0, z, 1.0, sensor.noise_cov) for model in models]
    loglik = np.zeros((z.shape[0], 2))
    for j, model in enumerate(models):  # ℓ_j,k of each independent filter
        x, P = x0, P0
        for k in range(z.shape[0]):
            if k:
                x, P = kf_predict(model, 1.0, x, P)
            S = H4 @ P @ H4.T + sensor.noise_cov
            loglik[k, j] = multivariate_normal(H4 @ x, S).logpdf(z[k])
            x, P, _ = kf_update(x, P, z[k], H4, sensor.noise_cov)
    log_mu = np.log(mu0) + np.cumsum(loglik, axis=0)
    log_mu -= np.logaddexp(log_mu[:, 0], log_mu[:, 1])[:, None]
    for method in ("imm", "gpb2"):
        run = runs[method]
        for j in range(2):
            np.testing.assert_allclose(run.model_means[:, j], independent[j][0], atol=1e-9)
            np.testing.assert_allclose(run.model_covs[:, j], independent[j][1], atol=1e-9)
        np.testing.assert_allclose(run.log_mode_probabilities, log_mu, atol=1e-9)
    np.testing.assert_allclose(runs["imm"].means, runs["gpb2"].means, atol=1e-9)
    assert np.abs(runs["gpb1"].means - runs["imm"].means).max() > 1e-3


def test_identical_rows_imm_equals_gpb1():
    """π_ij = p_j for every i (the next mode does not depend on the last): μ_{i|j} = p_j μ_i / Σ_i p_j μ_i = μ_i,
    so every mixed estimate is the merged one and IMM is GPB1.  GPB2 still keeps the r² pairs apart."""
    models, sensor, x0, P0, z = two_cv_problem(K=50)
    Pi = np.array([[0.8, 0.2], [0.8, 0.2]])
    runs = {m: MultipleModelEstimator(models, Pi, sensors=[sensor], tau=1.0, method=m).run({"position": z}, (x0, P0)) for m in METHODS}
    for field in ("means", "covs", "log_mode_probabilities", "model_means"):
        np.testing.assert_allclose(getattr(runs["imm"], field), getattr(runs["gpb1"], field), atol=1e-10)
    assert np.abs(runs["gpb2"].means - runs["imm"].means).max() > 1e-3


# --------------------------------------------------------------------------- log space, layouts, turns


def _long_run(K):
    """Π = I and a model far from the data: ln μ of the wrong model falls by ~3 per step, far below e^−745."""
    rng = np.random.default_rng(7)
    truth = np.cumsum(np.full((K + 1, 2), 0.5), axis=0)
    z = truth + rng.normal(0, 0.1, (K + 1, 2))
    sensor = PositionSensor(noise_cov=np.eye(2) * 0.01)
    models = [Straight(noise_cov=np.eye(2) * 1e-4), Straight(noise_cov=np.eye(2) * 100.0)]
    x0 = np.array([0.5, 0.5, 0.5, 0.5])
    return MultipleModelEstimator(models, np.eye(2), sensors=[sensor], tau=1.0).run({"position": z}, (x0, np.eye(4)))


def _check_log_space(run, K):
    log_mu = run.log_mode_probabilities
    assert log_mu.shape == (K + 1, 2) and np.all(np.isfinite(log_mu))
    assert log_mu[-1, 1] < -745 * 4  # exp underflows to 0 long before: only the logarithm still holds it
    assert np.all(np.isfinite(run.means)) and np.all(np.isfinite(run.covs))
    np.testing.assert_allclose(np.exp(log_mu).sum(axis=1), 1.0)
    np.testing.assert_allclose(np.logaddexp(log_mu[:, 0], log_mu[:, 1]), 0.0, atol=1e-12)


def test_log_space_probabilities_stay_finite():
    _check_log_space(_long_run(2000), 2000)


@pytest.mark.slow
def test_log_space_probabilities_stay_finite_over_10000_steps():
    _check_log_space(_long_run(10_000), 10_000)


def test_a_mode_whose_probability_underflows_recovers():
    """Π = I: μ of the noisy model sinks far below e^−745 while the data are quiet, then the data jump and it
    takes over — a linear-space μ that underflowed to 0 would stay 0 (0 · Λ = 0)."""
    rng = np.random.default_rng(2)
    K = 400
    z = rng.normal(0, 0.1, (K + 1, 2))
    z[300:] = rng.normal(0, 30.0, (K - 299, 2))  # wild jumps: only the noisy model explains them
    sensor = PositionSensor(noise_cov=np.eye(2) * 0.01)
    models = [Straight(noise_cov=np.eye(2) * 1e-4), Straight(noise_cov=np.eye(2) * 1e4)]
    run = MultipleModelEstimator(models, np.eye(2), sensors=[sensor], tau=1.0).run({"position": z}, (np.zeros(4), np.eye(4)))
    assert np.all(np.isfinite(run.log_mode_probabilities))
    assert run.log_mode_probabilities[299, 1] < -745
    assert run.mode[299] == 0 and run.mode[-1] == 1


@pytest.mark.parametrize("method", METHODS)
def test_four_and_six_state_models_mix_in_the_union_layout(method):
    tau, noise = 0.1, np.diag([0.01, 0.01])
    sensor = PositionSensor(noise_cov=np.eye(2) * 0.01)
    schedule = Schedule.from_rows(
        [("straight", 40), {"mode": "constant_acceleration", "steps": 40, "acceleration": (2.0, -1.0)}, ("straight", 20)]
    )
    trajectory, measurements = simulate(schedule, [0.0, 1.0, 0.0, 1.0], tau, [sensor], seed=5, noise_cov=noise)
    models = [Straight(noise_cov=noise), ConstantAcceleration(noise_cov=noise)]
    assert union_layout([m.layout for m in models]) == LAYOUT_6
    estimator = MultipleModelEstimator(models, [[0.95, 0.05], [0.05, 0.95]], sensors=[sensor], tau=tau, method=method, missing_variance=0.5)
    run = estimator.run(measurements, Gaussian([0.0, 1.0, 0.0, 1.0], np.eye(4)))
    assert run.layout == LAYOUT_6 and run.means.shape == (101, 6) and run.covs.shape == (101, 6, 6)
    assert np.all(np.isfinite(run.log_mode_probabilities))
    np.testing.assert_allclose(run.mode_probabilities.sum(axis=1), 1.0, atol=1e-12)
    # the 4-state model's estimate holds ax = ay = 0 with the documented variance, uncorrelated
    ax = LAYOUT_6.index("ax")
    np.testing.assert_allclose(run.model_means[:, 0, ax], 0.0, atol=1e-12)
    np.testing.assert_allclose(run.model_covs[:, 0, ax, ax], 0.5, atol=1e-12)
    np.testing.assert_allclose(run.model_covs[:, 0, ax, :ax], 0.0, atol=1e-12)
    # acceleration is recognized while it lasts (GPB1, which restarts both models from one estimate, least)
    p_ca = run.mode_probabilities[:, 1]
    assert p_ca[60:81].mean() > p_ca[20:41].mean() + 0.1
    truth = trajectory.states_in(LAYOUT_6)
    if method != "gpb1":
        assert p_ca[60:81].mean() > 0.8
        assert np.all(np.abs(run.means[80, [ax, ax + 3]] - truth[80, [ax, ax + 3]]) < 0.5)
    assert np.sqrt(np.mean((run.means[:, [0, 3]] - truth[:, [0, 3]]) ** 2)) < 0.1


def test_a_left_turn_mode_tracks_a_turn_better_than_straight_alone():
    """ω and the centre from the mixed estimate at every step: a turn of radius r tangent to the current velocity."""
    tau, noise = 0.1, np.diag([0.001, 0.001])
    sensor = PositionSensor(noise_cov=np.eye(2) * 0.1)
    schedule = Schedule.from_rows([("straight", 30), ("left_turn", 80, 4.0), ("straight", 30)])
    trajectory, measurements = simulate(schedule, [0.0, 0.0, 0.0, 2.0], tau, [sensor], seed=0, noise_cov=noise)
    prior = Gaussian([0.0, 0.0, 0.0, 2.0], np.eye(4) * 0.1)
    cv = MultipleModelEstimator([Straight(noise_cov=noise)], [[1.0]], sensors=[sensor], tau=tau).run(measurements, prior)
    imm = MultipleModelEstimator(
        [Straight(noise_cov=noise), LeftTurn(radius=4.0, noise_cov=noise)], sojourn=2.0, sensors=[sensor], tau=tau
    ).run(measurements, prior)
    truth = trajectory.positions
    turn = slice(40, 111)
    error = {
        name: np.sqrt(np.mean(np.sum((r.means[turn][:, [0, 2]] - truth[turn]) ** 2, axis=1))) for name, r in (("cv", cv), ("imm", imm))
    }
    assert error["imm"] < 0.3 * error["cv"], error  # measured: 0.17 m against 1.0 m
    assert np.mean(imm.mode[50:111] == 1) > 0.9 and np.mean(imm.mode[10:31] == 0) > 0.9


# --------------------------------------------------------------------------- runs, Markov chain, recording, errors


@pytest.mark.parametrize("method", METHODS)
def test_stacked_runs_equal_the_runs_one_at_a_time(method):
    data = [two_cv_problem(K=25, seed=s) for s in range(3)]
    models, sensor, x0, P0, _ = data[0]
    z = np.stack([d[4] for d in data])  # (R, K+1, m)
    means = np.stack([x0, x0 + 1.0, x0 - 1.0])
    covs = np.stack([P0, 2 * P0, 3 * P0])
    estimator = MultipleModelEstimator(models, [[0.9, 0.1], [0.2, 0.8]], sensors=[sensor], tau=1.0, method=method)
    stacked = estimator.run_batch({"position": z}, (means, covs))
    assert len(stacked) == 3 and stacked[0].means.shape == (26, 4) and stacked[0].mode_probabilities.shape == (26, 2)
    for i in range(3):
        single = estimator.run({"position": z[i]}, (means[i], covs[i]))
        np.testing.assert_allclose(stacked[i].means, single.means, atol=1e-12)
        np.testing.assert_allclose(stacked[i].covs, single.covs, atol=1e-12)
        np.testing.assert_allclose(stacked[i].log_mode_probabilities, single.log_mode_probabilities, atol=1e-12)


def test_sojourn_matrix_is_the_continuous_time_chain():
    """Two modes leaving at rate a = 1/T: π_11(Δt) = (1 + e^{−2aΔt})/2; a mode's mean sojourn is T."""
    P = sojourn_matrix(np.array([4.0, 4.0]), 0.5)
    np.testing.assert_allclose(
        P, [[(1 + np.exp(-0.25)) / 2, (1 - np.exp(-0.25)) / 2]] * 1 + [[(1 - np.exp(-0.25)) / 2, (1 + np.exp(-0.25)) / 2]]
    )
    P3 = sojourn_matrix(np.array([1.0, 2.0, 5.0]), 1e-4)
    np.testing.assert_allclose(P3.sum(axis=1), 1.0)
    np.testing.assert_allclose((1 - np.diag(P3)) / 1e-4, [1.0, 0.5, 0.2], rtol=1e-3)


def test_recording_has_the_mode_probabilities(tmp_path):
    rerun = pytest.importorskip("rerun")
    from hybridtrack.recording import RerunRecorder

    models, sensor, x0, P0, z = two_cv_problem(K=20)
    path = tmp_path / "imm.rrd"
    estimator = MultipleModelEstimator(models, [[0.9, 0.1], [0.1, 0.9]], sensors=[sensor], tau=1.0, name="imm2")
    with RerunRecorder(path, {"test": "imm"}) as recorder:
        estimator.run({"position": z}, (x0, P0), recorder=recorder)
    assert path.stat().st_size > 0
    if hasattr(rerun, "recording"):
        paths = {str(c.entity_path) for c in rerun.recording.load_recording(str(path)).schema().component_columns()}
        for entity in (
            "/world/estimate/imm2",
            "/estimator/imm2/mode_probability/straight_0",
            "/estimator/imm2/mode_probability/straight_1",
        ):
            assert entity in paths, (entity, sorted(paths))


def test_parameter_errors():
    sensors = [PositionSensor()]
    cv = Straight()
    with pytest.raises(ValueError, match="method"):
        MultipleModelEstimator([cv], [[1.0]], sensors=sensors, method="gpb3")
    with pytest.raises(ValueError, match="transition_matrix: row 1 sums"):
        MultipleModelEstimator([cv, cv], [[0.5, 0.5], [0.5, 0.6]], sensors=sensors)
    with pytest.raises(ValueError, match="transition_matrix"):
        MultipleModelEstimator([cv, cv], [[1.0]], sensors=sensors)
    with pytest.raises(ValueError, match="exactly one"):
        MultipleModelEstimator([cv, cv], [[1.0, 0.0], [0.0, 1.0]], sojourn=2.0, sensors=sensors)
    with pytest.raises(ValueError, match="sojourn"):
        MultipleModelEstimator([cv, cv], sojourn=-1.0, sensors=sensors)
    with pytest.raises(ValueError, match="models"):
        MultipleModelEstimator([], [[1.0]], sensors=sensors)
    with pytest.raises(ValueError, match="missing_variance"):
        MultipleModelEstimator([cv, ConstantAcceleration()], sojourn=1.0, sensors=sensors, missing_variance=0.0)
    estimator = MultipleModelEstimator([cv, cv], sojourn=1.0, sensors=sensors, tau=0.1)
    with pytest.raises(ValueError, match="mode_probabilities"):
        estimator.run({"position": np.zeros((3, 2))}, (np.zeros(4), np.eye(4)), mode_probabilities=[0.2, 0.2])
    with pytest.raises(ValueError, match="prior"):
        estimator.run({"position": np.zeros((3, 2))}, (np.zeros(5), np.eye(5)))
    assert LAYOUT_4 == estimator.layout


@pytest.mark.parametrize("estimator", ["information", "potter", "bierman", "srif", "ekf"])
def test_any_registered_exact_estimator_gives_the_same_imm(estimator):
    models, sensor, x0, P0, z = two_cv_problem(K=30)
    Pi = [[0.9, 0.1], [0.2, 0.8]]
    reference_run = MultipleModelEstimator(models, Pi, sensors=[sensor], tau=1.0).run({"position": z}, (x0, P0))
    run = MultipleModelEstimator(models, Pi, sensors=[sensor], tau=1.0, estimator=estimator, method="gpb2").run({"position": z}, (x0, P0))
    gpb2 = MultipleModelEstimator(models, Pi, sensors=[sensor], tau=1.0, method="gpb2").run({"position": z}, (x0, P0))
    imm = MultipleModelEstimator(models, Pi, sensors=[sensor], tau=1.0, estimator=estimator).run({"position": z}, (x0, P0))
    np.testing.assert_allclose(imm.means, reference_run.means, atol=1e-8)
    np.testing.assert_allclose(imm.covs, reference_run.covs, atol=1e-8)
    np.testing.assert_allclose(imm.log_mode_probabilities, reference_run.log_mode_probabilities, atol=1e-8)
    np.testing.assert_allclose(run.means, gpb2.means, atol=1e-8)


@pytest.mark.parametrize("method", METHODS)
def test_update_of_a_prediction_is_the_imm_step(method):
    """IMM: step(z) = update(step(no measurement), z) (the mixing and prediction do not depend on z), over 4-,
    5- and 6-state modes; GPB1/GPB2 merge before updating, so their update is refused."""
    models = [
        ("straight", {"noise_density": 0.5}),
        ("coordinated_turn", {"noise_density": 0.5}),
        ("constant_acceleration", {"noise_density": 0.5}),
    ]
    sensor = PositionSensor(noise_cov=25.0 * np.eye(2))
    estimator = MultipleModelEstimator(models, sojourn=20.0, sensors=[sensor], method=method)
    rng = np.random.default_rng(5)
    R = 7
    x0 = np.column_stack([rng.normal(4e5, 100, R), rng.normal(0, 8, R), rng.normal(6e6, 100, R), rng.normal(0, 8, R)])
    state = estimator.start(x0, np.tile(np.diag([400.0, 25.0, 400.0, 25.0]), (R, 1, 1)), x0[:, [0, 2]], prior_layout=LAYOUT_4)
    z = x0[:, [0, 2]] + rng.normal(0, 30, (R, 2))
    predicted = estimator.step(state, np.full((R, 2), np.nan), 3.0)
    if method != "imm":
        with pytest.raises(ValueError, match="update"):
            estimator.update(predicted, z)
        return
    got, expected = estimator.update(predicted, z), estimator.step(state, z, 3.0)
    for name in ("mean", "cov", "model_means", "model_covs", "log_mode_probabilities", "model_loglik", "loglik"):
        np.testing.assert_allclose(getattr(got, name), getattr(expected, name), rtol=1e-12, atol=1e-9, err_msg=name)
