"""Extended filters: the three forms agree; f and h are relinearized; angles are wrapped; linear filters refuse nonlinear input."""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack_plugins.motion.ship import ShipTurn
from hybridtrack_plugins.sensors.radar import PolarRadarSensor, RadarSensor

LAYOUT = ShipTurn.layout
REL = 1e-9


def _ship_data(sensor, steps=60, seed=0, tau=2.0):
    rng = np.random.default_rng(seed)
    model = ShipTurn(sigma_velocity=0.05, sigma_rate=2e-4)
    x = np.array([2000.0, 3000.0, 5.0, -2.0, 0.01])
    Lq = np.linalg.cholesky(model.noise_cov)
    G = model.noise_gain(tau)
    X, Z = [], []
    for _ in range(steps):
        x = model.f(x, tau) + G @ (Lq @ rng.standard_normal(3))
        X.append(x)
        Z.append(sensor.simulate(x, LAYOUT, rng))
    return model, np.array(X), np.array(Z)


@pytest.mark.parametrize("sensor", [PolarRadarSensor(range_std=5.0), RadarSensor(range_std=5.0)], ids=["polar", "cartesian"])
def test_extended_forms_agree(sensor):
    model, _, Z = _ship_data(sensor)
    registry = ht.load_plugins(strict=True).registry
    names = ["ekf", "ekf_sqrt", "ekf_ud"]
    ests = [registry.create("estimator", n) for n in names]
    x0 = np.array([[1990.0, 3010.0, 4.0, -1.5, 0.0], [2010.0, 2990.0, 5.5, -2.5, 0.02]])
    P0 = np.stack([np.diag([100.0, 100.0, 4.0, 4.0, 1e-4])] * 2)
    states = [e.initialize(x0, P0) for e in ests]
    lin = model.linearizer(2.0)
    for z in Z:
        states = [e.predict(s, lin) for e, s in zip(ests, states)]
        out = [e.update(s, z, [sensor], LAYOUT) for e, s in zip(ests, states)]
        states = [o[0] for o in out]
        ref_state, ref_inn = out[0]
        for e, (s, inn) in zip(ests[1:], out[1:]):
            np.testing.assert_allclose(e.mean(s), ref_state.mean, rtol=REL)
            np.testing.assert_allclose(e.covariance(s), ref_state.covariance, rtol=1e-8, atol=1e-12)
            np.testing.assert_allclose(inn.loglik, ref_inn.loglik, rtol=REL)
            np.testing.assert_allclose(inn.S, ref_inn.S, rtol=REL)


def test_predict_is_f_of_the_estimate():
    model = ShipTurn()
    ekf = ht.load_plugins().registry.create("estimator", "ekf")
    x0 = np.array([[0.0, 0.0, 5.0, 1.0, 0.05], [1.0, 2.0, -3.0, 4.0, 0.0]])
    state = ekf.predict(ekf.initialize(x0, np.stack([np.eye(5)] * 2)), model.linearizer(3.0))
    np.testing.assert_allclose(state.mean, ShipTurn.f(x0, 3.0), rtol=1e-12)
    F = ShipTurn.jacobian(x0, 3.0)
    np.testing.assert_allclose(state.covariance, F @ np.swapaxes(F, 1, 2) + model.linearize(3.0, x0).Q, rtol=1e-12)


def test_azimuth_innovation_wrapped_across_pi():
    """Target just across the −x axis from the estimate: ν_θ is small, not ≈ 2π."""
    sensor = PolarRadarSensor(range_std=1.0, azimuth_std=1e-3)
    ekf = ht.load_plugins().registry.create("estimator", "ekf")
    state = ekf.initialize(np.array([[-1000.0, -1.0, 0, 0, 0]]), np.eye(5)[None] * 4.0)
    z = np.array([1000.0, np.pi - 0.0005])  # the estimate is at θ ≈ −π + 0.001
    state, inn = ekf.update(state, z, [sensor], LAYOUT)
    assert abs(inn.nu[0, 1]) < 0.01
    assert inn.nis[0] < 10


def test_bearing_sensor_wrapped():
    bearing = pytest.importorskip("hybridtrack_plugins.sensors.bearing")
    sensor = bearing.BearingSensor(sigma=np.deg2rad(0.5), observer=(0.0, 0.0), convention="north")
    layout = ("x", "vx", "y", "vy")
    ekf = ht.load_plugins().registry.create("estimator", "ekf_sqrt")
    # target due south, slightly west vs slightly east: bearings ≈ ±π
    state = ekf.initialize(np.array([[1.0, 0.0, -1000.0, 0.0]]), np.diag([100.0, 1.0, 100.0, 1.0])[None])
    z = np.array([-np.pi + 0.002])
    state, inn = ekf.update(state, z, [sensor], layout)
    assert abs(inn.nu[0, 0]) < 0.01
    ref = ht.load_plugins().registry.create("estimator", "ekf")
    s2, i2 = ref.update(ref.initialize(np.array([[1.0, 0.0, -1000.0, 0.0]]), np.diag([100.0, 1.0, 100.0, 1.0])[None]), z, [sensor], layout)
    np.testing.assert_allclose(inn.loglik, i2.loglik, rtol=1e-10)
    np.testing.assert_allclose(ekf.mean(state), ref.mean(s2), rtol=1e-10)


def test_linear_filters_refuse_nonlinear_input():
    registry = ht.load_plugins().registry
    for name in ("kalman", "information", "potter", "srif"):
        est = registry.create("estimator", name)
        state = est.initialize(np.ones((1, 5)) * 100, np.eye(5)[None])
        with pytest.raises(ValueError, match="sensors: .* nonlinear|linear sensors only"):
            est.update(state, np.array([100.0, 0.5]), [PolarRadarSensor()], LAYOUT)
        with pytest.raises(ValueError, match="transitions: .* takes a TransitionBank"):
            est.predict(state, ShipTurn().linearizer(1.0))


def test_stacked_runs_with_per_row_radar_noise_equal_single_runs():
    """Monte Carlo runs stacked as a bank (z of shape (M, 2), the converted R(z) differs per row): every form
    gives each row exactly what the same filter gives on that run alone (a shared H with a stacked R used to
    be solved as a stack of vectors in the square-root forms' whitening)."""
    sensor = RadarSensor(range_std=5.0, azimuth_std=2e-3)
    runs = [_ship_data(sensor, steps=25, seed=s) for s in (1, 2, 3)]
    model = runs[0][0]
    Z = np.stack([r[2] for r in runs], axis=1)  # (steps, M, 2)
    registry = ht.load_plugins(strict=True).registry
    x0 = np.array([1990.0, 3010.0, 4.0, -1.5, 0.0])
    P0 = np.diag([100.0, 100.0, 4.0, 4.0, 1e-4])
    lin = model.linearizer(2.0)
    for name in ("ekf", "ekf_sqrt", "ekf_ud"):
        est = registry.create("estimator", name)
        stacked = est.initialize(np.tile(x0, (3, 1)), np.stack([P0] * 3))
        singles = [est.initialize(x0[None], P0[None]) for _ in range(3)]
        for z in Z:
            stacked, inn = est.update(est.predict(stacked, lin), z, [sensor], LAYOUT)
            outs = [est.update(est.predict(s, lin), z[i], [sensor], LAYOUT) for i, s in enumerate(singles)]
            singles = [o[0] for o in outs]
            for i, (s, single_inn) in enumerate(outs):
                np.testing.assert_allclose(est.mean(stacked)[i], est.mean(s)[0], rtol=1e-10)
                np.testing.assert_allclose(inn.loglik[i], single_inn.loglik[0], rtol=1e-10)
