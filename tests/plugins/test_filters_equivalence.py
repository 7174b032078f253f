"""Every information and square-root form equals the covariance KF on a well-conditioned problem (≤ 1e-9 relative)."""

import numpy as np
import pytest
from _filters_support import G4, LAYOUT, bank_of, position_sensor, radii_bank, random_spd, simulate

import hybridtrack as ht
from hybridtrack.core.interfaces import LinearTransition, TransitionBank

REL = 1e-9
FORMS = ["information", "decentralized", "potter", "bierman", "srif", "srif_decentralized"]


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


def _stop(q=0.001, tau=0.1):
    return LinearTransition(np.kron(np.eye(2), [[1.0, 0.0], [0.0, 0.0]]), np.zeros(4), G4, np.eye(2) * q)


def _problem(with_stop):
    rng = np.random.default_rng(7)
    s0 = np.array([0.0, 0.0, 0.0, 2.0])
    trs = radii_bank(s0, n_radii=3)
    if with_stop:
        trs.append(_stop())
    sensors = [position_sensor(np.array([[0.05, 0.01], [0.01, 0.08]]), name="a"), position_sensor(np.array([[0.2]]), ("x",), name="b")]
    _, Z = simulate(trs[1], sensors, s0, 30, rng)
    Z = Z[0].copy()
    Z[4, 2] = np.nan  # sensor b missing
    Z[8] = np.nan  # nothing measured
    M = len(trs)
    x0 = np.tile(s0, (M, 1)) + rng.normal(0, 0.2, (M, 4))
    P0 = np.stack([random_spd(rng, 4) for _ in range(M)])
    return trs, sensors, Z, x0, P0


@pytest.mark.parametrize("noise_root", [True, False], ids=["noise_root", "eigen_root"])
@pytest.mark.parametrize("with_stop", [False, True], ids=["invertible_F", "singular_F"])
@pytest.mark.parametrize("name", FORMS)
def test_form_equals_covariance_kf(name, with_stop, noise_root):
    trs, sensors, Z, x0, P0 = _problem(with_stop)
    bank = bank_of(trs)
    if not noise_root:
        bank = TransitionBank(bank.F, bank.B, bank.Q)
    registry = ht.load_plugins(strict=True).registry
    ref, est = registry.create("estimator", "kalman"), registry.create("estimator", name)
    sr, se = ref.initialize(x0, P0), est.initialize(x0, P0)
    np.testing.assert_allclose(est.covariance(se), P0, rtol=1e-12)
    for k in range(Z.shape[0]):
        sr, se = ref.predict(sr, bank), est.predict(se, bank)
        assert _rel(est.mean(se), ref.mean(sr)) <= REL
        assert _rel(est.covariance(se), ref.covariance(sr)) <= REL
        sr, ir = ref.update(sr, Z[k], sensors, LAYOUT)
        se, ie = est.update(se, Z[k], sensors, LAYOUT)
        assert _rel(est.mean(se), ref.mean(sr)) <= REL
        assert _rel(est.covariance(se), ref.covariance(sr)) <= REL
        assert _rel(est.predicted_mean(se), sr.predicted_mean) <= REL
        assert _rel(est.predicted_covariance(se), sr.predicted_covariance) <= REL
        assert ie.nu.shape == ir.nu.shape
        if ir.measurement_dim:
            assert _rel(ie.nu, ir.nu) <= REL
            assert _rel(ie.S, ir.S) <= REL
            np.testing.assert_allclose(ie.loglik, ir.loglik, rtol=REL)
            np.testing.assert_allclose(ie.nis, ir.nis, rtol=1e-8)
        else:
            np.testing.assert_array_equal(ie.loglik, 0.0)


@pytest.mark.parametrize("name", FORMS)
def test_form_equals_covariance_kf_with_per_filter_measurements_and_noise(name):
    """z of shape (M, m) (Monte Carlo runs as a bank) with a measurement-dependent R per filter (radar pseudo-measurements)."""
    from hybridtrack_plugins.sensors.radar import RadarSensor

    rng = np.random.default_rng(11)
    s0 = np.array([300.0, 1.0, 400.0, -2.0])
    trs = radii_bank(s0, n_radii=2)
    M = len(trs)
    radar = RadarSensor(range_std=2.0, azimuth_std=np.deg2rad(0.5))
    X = np.tile(s0, (M, 1)) + rng.normal(0, 1.0, (M, 4))
    registry = ht.load_plugins(strict=True).registry
    ref, est = registry.create("estimator", "kalman"), registry.create("estimator", name)
    P0 = np.stack([np.diag([25.0, 1.0, 25.0, 1.0])] * M)
    sr, se = ref.initialize(np.tile(s0, (M, 1)), P0), est.initialize(np.tile(s0, (M, 1)), P0)
    bank = bank_of(trs)
    for _ in range(15):
        X = np.einsum("mij,mj->mi", bank.F, X) + bank.B
        z = radar.simulate(X, LAYOUT, rng)  # (M, 2): one measurement per filter, R differs per filter
        sr, se = ref.predict(sr, bank), est.predict(se, bank)
        sr, ir = ref.update(sr, z, [radar], LAYOUT)
        se, ie = est.update(se, z, [radar], LAYOUT)
        assert _rel(est.mean(se), ref.mean(sr)) <= REL
        assert _rel(est.covariance(se), ref.covariance(sr)) <= REL
        np.testing.assert_allclose(ie.loglik, ir.loglik, rtol=REL)
        assert _rel(ie.S, ir.S) <= REL
