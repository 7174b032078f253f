"""Covariance-form KF bank: against filterpy, against a per-filter loop, forms, missing data, bad input."""

import numpy as np
import pytest
from _filters_support import LAYOUT, MatrixSensor, bank_of, position_sensor, radii_bank, random_spd, simulate, straight, turn
from filterpy.kalman import KalmanFilter as FilterpyKF

import hybridtrack as ht
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack_plugins.filters.kalman import KalmanFilter


def _run(est, transitions, sensors, Z, x0, P0):
    state = est.initialize(x0, P0)
    out = []
    for k in range(Z.shape[-2]):
        state = est.predict(state, transitions)
        state, inn = est.update(state, Z[..., k, :], sensors, LAYOUT)
        out.append((state, inn))
    return out


def test_registered():
    registry = ht.load_plugins(strict=True).registry
    assert isinstance(registry.create("estimator", "kalman"), KalmanFilter)


@pytest.mark.parametrize("form", ["joseph", "symmetric"])
def test_equals_filterpy(form):
    rng = np.random.default_rng(1)
    tr = turn(np.array([0.0, 0.0, 0.0, 2.0]), 5.0, left=False, q=0.01)
    sensor = position_sensor(np.array([[0.04, 0.01], [0.01, 0.02]]))
    _, Z = simulate(tr, [sensor], np.array([0.0, 0.0, 0.0, 2.0]), 60, rng)
    x0, P0 = np.array([0.1, 0.0, -0.1, 1.9]), np.diag([1.0, 0.5, 1.0, 0.5])

    ref = FilterpyKF(dim_x=4, dim_z=2)
    ref.x, ref.P, ref.F, ref.Q, ref.H, ref.R = x0.copy(), P0.copy(), tr.F.copy(), tr.process_noise, sensor.H, sensor.noise_cov
    ref.B, u = tr.B[:, None], np.array([1.0])

    out = _run(KalmanFilter(form=form), bank_of([tr]), [sensor], Z[0], x0[None], P0[None])
    for k, (state, inn) in enumerate(out):
        ref.predict(u=u)
        np.testing.assert_allclose(state.predicted_mean[0], ref.x, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(state.predicted_covariance[0], ref.P, rtol=1e-10, atol=1e-14)
        ref.update(Z[0, k])
        np.testing.assert_allclose(state.mean[0], ref.x, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(state.covariance[0], ref.P, rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(inn.nu[0], ref.y, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(inn.S[0], ref.S, rtol=1e-10)
        np.testing.assert_allclose(inn.loglik[0], ref.log_likelihood, rtol=1e-10)
        nis = ref.y @ np.linalg.solve(ref.S, ref.y)
        np.testing.assert_allclose(inn.nis[0], nis, rtol=1e-9)


def test_bank_equals_per_filter_loop():
    rng = np.random.default_rng(2)
    s0 = np.array([0.0, 0.0, 0.0, 2.0])
    trs = radii_bank(s0)
    sensors = [position_sensor(np.diag([0.1, 0.2]), name="a"), position_sensor(np.array([[0.3]]), ("x",), name="b")]
    _, Z = simulate(trs[3], sensors, s0, 40, rng)
    M = len(trs)
    x0 = np.tile(s0, (M, 1)) + rng.normal(0, 0.1, (M, 4))
    P0 = np.stack([random_spd(rng, 4) for _ in range(M)])
    bank = _run(KalmanFilter(), bank_of(trs), sensors, Z[0], x0, P0)
    for i in range(M):
        single = _run(KalmanFilter(), bank_of([trs[i]]), sensors, Z[0], x0[i : i + 1], P0[i : i + 1])
        for (sb, ib), (ss, is_) in zip(bank, single):
            np.testing.assert_allclose(sb.mean[i], ss.mean[0], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(sb.covariance[i], ss.covariance[0], rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(ib.loglik[i], is_.loglik[0], rtol=1e-12)


def test_selection_path_equals_general_h():
    """Position sensor (selection H) vs the same H given as a non-selection matrix (scaled by 1 in a mixed row)."""
    rng = np.random.default_rng(3)
    tr = straight(q=0.01)
    sel = position_sensor(np.diag([0.05, 0.07]))
    H = sel.H.copy()
    general = MatrixSensor(H + np.array([[0, 0, 0, 0], [0, 1e-300, 0, 0]]), sel.noise_cov)  # not a pure selection
    _, Z = simulate(tr, [sel], np.zeros(4), 30, rng)
    x0, P0 = np.zeros((1, 4)), np.eye(4)[None]
    est_sel, est_gen = KalmanFilter(), KalmanFilter()
    a = _run(est_sel, bank_of([tr]), [sel], Z[0], x0, P0)
    b = _run(est_gen, bank_of([tr]), [general], Z[0], x0, P0)
    assert est_sel.assembler.sensor_model(sel, LAYOUT).selection == (0, 2)
    assert est_gen.assembler.sensor_model(general, LAYOUT).selection is None
    for (sa, ia), (sb, ib) in zip(a, b):
        np.testing.assert_allclose(sa.mean, sb.mean, rtol=1e-12, atol=1e-290)
        np.testing.assert_allclose(sa.covariance, sb.covariance, rtol=1e-12, atol=1e-290)
        np.testing.assert_allclose(ia.loglik, ib.loglik, rtol=1e-12)


def test_update_forms_agree_on_well_conditioned_problem():
    rng = np.random.default_rng(4)
    tr = straight(q=0.01)
    s = position_sensor(np.diag([0.5, 0.5]))
    _, Z = simulate(tr, [s], np.zeros(4), 50, rng)
    runs = {
        f: _run(KalmanFilter(form=f), bank_of([tr]), [s], Z[0], np.zeros((1, 4)), np.eye(4)[None])
        for f in ("joseph", "symmetric", "conventional")
    }
    for k in range(50):
        for f in ("symmetric", "conventional"):
            np.testing.assert_allclose(runs[f][k][0].covariance, runs["joseph"][k][0].covariance, rtol=1e-9, atol=1e-15)
            np.testing.assert_allclose(runs[f][k][0].mean, runs["joseph"][k][0].mean, rtol=1e-9, atol=1e-15)


def test_missing_measurement_is_prediction_only():
    est = KalmanFilter()
    s = position_sensor()
    state = est.predict(est.initialize(np.ones((2, 4)), np.stack([np.eye(4)] * 2)), bank_of([straight()] * 2))
    new, inn = est.update(state, np.array([np.nan, np.nan]), [s], LAYOUT)
    np.testing.assert_array_equal(new.mean, state.mean)
    np.testing.assert_array_equal(new.covariance, state.covariance)
    assert inn.nu.shape == (2, 0) and inn.S.shape == (2, 0, 0)
    np.testing.assert_array_equal(inn.loglik, 0.0)
    np.testing.assert_array_equal(inn.nis, 0.0)


def test_nan_rows_skip_that_sensor_only():
    est = KalmanFilter()
    a, b = position_sensor(name="a"), position_sensor(np.array([[0.2]]), ("x",), name="b")
    state = est.predict(est.initialize(np.zeros((1, 4)), np.eye(4)[None]), bank_of([straight()]))
    both, _ = est.update(state, np.array([np.nan, np.nan, 0.3]), [a, b], LAYOUT)
    only_b, inn_b = est.update(state, np.array([0.3]), [b], LAYOUT)
    np.testing.assert_array_equal(both.mean, only_b.mean)
    np.testing.assert_array_equal(both.covariance, only_b.covariance)
    assert inn_b.nu.shape == (1, 1)


@pytest.mark.parametrize(
    "mean, cov, match",
    [
        (np.zeros(4), np.eye(4), r"mean: expected shape \(\*, \*\)"),
        (np.zeros((2, 4)), np.eye(4), r"cov: expected shape \(2, 4, 4\)"),
        (np.full((1, 4), np.nan), np.eye(4)[None], "mean: contains NaN"),
        (np.zeros((1, 4)), np.full((1, 4, 4), np.inf), "cov: contains NaN or inf"),
    ],
)
def test_bad_prior_raises(mean, cov, match):
    with pytest.raises(ValueError, match=match):
        KalmanFilter().initialize(mean, cov)


def test_bad_step_input_raises():
    est = KalmanFilter()
    state = est.initialize(np.zeros((2, 4)), np.stack([np.eye(4)] * 2))
    with pytest.raises(ValueError, match=r"transitions.F: expected shape \(2, 4, 4\)"):
        est.predict(state, bank_of([straight()]))
    bad = TransitionBank(np.full((2, 4, 4), np.nan), np.zeros((2, 4)), np.zeros((2, 4, 4)))
    with pytest.raises(ValueError, match="transitions.F: contains NaN"):
        est.predict(state, bad)
    with pytest.raises(ValueError, match=r"z: expected shape \(2,\) or \(2, 2\)"):
        est.update(state, np.zeros(3), [position_sensor()], LAYOUT)
    with pytest.raises(ValueError, match="z: contains inf"):
        est.update(state, np.array([np.inf, 0.0]), [position_sensor()], LAYOUT)
    with pytest.raises(ValueError, match="layout: expected 4"):
        est.update(state, np.zeros(2), [position_sensor()], LAYOUT[:3])
    with pytest.raises(ValueError, match="form: expected one of"):
        KalmanFilter(form="nope")


@pytest.mark.parametrize("form", ["joseph", "symmetric"])
def test_repeated_components_across_sensors(form):
    """Two sensors measuring the same coordinate: the selection path must add both gains."""
    a, b = position_sensor(np.diag([0.02, 0.05]), name="a"), position_sensor(np.array([[0.1]]), ("x",), name="b")
    H = np.vstack([a.H, b.H])
    stacked = MatrixSensor(H + np.array([[0, 1e-300, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]), np.diag([0.02, 0.05, 0.1]))
    x0, P0 = np.zeros((1, 4)), np.eye(4)[None]
    z = np.array([1.0, 2.0, 3.0])
    ea, eb = KalmanFilter(form=form), KalmanFilter(form=form)
    sa, _ = ea.update(ea.initialize(x0, P0), z, [a, b], LAYOUT)
    sb, _ = eb.update(eb.initialize(x0, P0), z, [stacked], LAYOUT)
    np.testing.assert_allclose(sa.covariance, sb.covariance, rtol=1e-12, atol=1e-290)
    np.testing.assert_allclose(sa.mean, sb.mean, rtol=1e-12, atol=1e-290)


@pytest.mark.parametrize("form", ["joseph", "symmetric"])
def test_axis_separable_path_equals_dense(form):
    """Block-diagonal F, Q, P0 with diagonal-R selection sensors: the separable fast path equals the dense KF."""
    from hybridtrack_plugins.filters.kalman import AxisState, CovarianceState

    rng = np.random.default_rng(5)
    s0 = np.array([0.0, 0.0, 0.0, 2.0])
    trs = radii_bank(s0, n_radii=4)
    both = position_sensor(np.diag([0.02, 0.05]), name="xy")
    x_only = position_sensor(np.array([[0.03]]), ("x",), name="x")
    correlated = position_sensor(np.array([[0.05, 0.01], [0.01, 0.05]]), name="corr")
    _, Z = simulate(trs[2], [both], s0, 40, rng)
    M = len(trs)
    x0 = np.tile(s0, (M, 1)) + rng.normal(0, 0.1, (M, 4))
    P0 = np.stack([np.diag(rng.uniform(0.5, 2.0, 4)) for _ in range(M)])
    P0[:, 0, 1] = P0[:, 1, 0] = 0.1
    fast, dense = KalmanFilter(form=form), KalmanFilter(form=form, structure=False)
    bank = bank_of(trs)
    sf, sd = fast.initialize(x0, P0), dense.initialize(x0, P0)
    kinds = set()
    for k in range(40):
        sf, sd = fast.predict(sf, bank), dense.predict(sd, bank)
        if k % 10 == 3:
            sensors, z = [x_only], Z[0, k, :1]
        elif k == 25:
            sensors, z = [correlated], Z[0, k]  # forces the dense form for one step, then back
        elif k == 30:
            sensors, z = [both], np.array([np.nan, np.nan])
        else:
            sensors, z = [both], Z[0, k]
        sf, inf_ = fast.update(sf, z, sensors, LAYOUT)
        sd, ind = dense.update(sd, z, sensors, LAYOUT)
        kinds.add(type(sf))
        np.testing.assert_allclose(sf.mean, sd.mean, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(sf.covariance, sd.covariance, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(sf.predicted_covariance, sd.predicted_covariance, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(inf_.nu, ind.nu, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(inf_.S, ind.S, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(inf_.loglik, ind.loglik, rtol=1e-10)
        np.testing.assert_allclose(inf_.nis, ind.nis, rtol=1e-9)
    assert kinds == {AxisState, CovarianceState}


def test_axis_separable_path_equals_filterpy():
    rng = np.random.default_rng(6)
    tr = turn(np.array([0.0, 0.0, 0.0, 2.0]), 3.0, left=True, q=0.01)
    sensor = position_sensor(np.diag([0.04, 0.02]))
    _, Z = simulate(tr, [sensor], np.array([0.0, 0.0, 0.0, 2.0]), 50, rng)
    x0, P0 = np.array([0.1, 0.0, -0.1, 1.9]), np.diag([1.0, 0.5, 1.0, 0.5])
    ref = FilterpyKF(dim_x=4, dim_z=2)
    ref.x, ref.P, ref.F, ref.Q, ref.H, ref.R = x0.copy(), P0.copy(), tr.F.copy(), tr.process_noise, sensor.H, sensor.noise_cov
    ref.B, u = tr.B[:, None], np.array([1.0])
    out = _run(KalmanFilter(), bank_of([tr]), [sensor], Z[0], x0[None], P0[None])
    assert type(out[-1][0]).__name__ == "AxisState"
    for k, (state, inn) in enumerate(out):
        ref.predict(u=u)
        ref.update(Z[0, k])
        np.testing.assert_allclose(state.mean[0], ref.x, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(state.covariance[0], ref.P, rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(inn.S[0], ref.S, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(inn.loglik[0], ref.log_likelihood, rtol=1e-10)
