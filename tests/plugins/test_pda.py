"""PDA filter bank (plugins/filters/pda.py): the Kalman filter without clutter, hand-computed β,
the association likelihood, the bank against single filters, bad input (SPEC §6; seed 004)."""

import numpy as np
import pytest
from _filters_support import LAYOUT, MatrixSensor, position_sensor, straight, turn
from scipy.stats import chi2, multivariate_normal

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.protocols import ClutterInnovation
from hybridtrack.sdk.scans import Scan
from hybridtrack.testing import check_estimator
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.filters.pda import PDAFilter


def _hybrid_measurements(rng, steps=40):
    """A straight-then-right-turn truth and its (x, y) measurements (R = 0.01 I)."""
    x = np.array([0.0, 0.0, 0.0, 2.0])
    transitions = [straight()] * 15 + [turn(x, 5.0, left=False)] * (steps - 15)
    zs = []
    for t in transitions:
        x = t.apply(x) + t.G @ rng.multivariate_normal(np.zeros(2), t.Q)
        zs.append(x[[0, 2]] + rng.normal(0.0, 0.1, 2))
    return np.array(zs)


def _bank():
    return TransitionBank.stack([straight(q=q) for q in (0.001, 0.01, 0.1)])


def test_without_clutter_and_with_certain_detection_pda_is_the_kalman_filter_exactly():
    rng = np.random.default_rng(0)
    Z = _hybrid_measurements(rng)
    sensor = position_sensor()
    bank = _bank()
    mean, cov = np.tile([0.0, 0.0, 0.0, 2.0], (3, 1)), np.tile(np.eye(4), (3, 1, 1))
    kf, pda = KalmanFilter(), PDAFilter(detection_probability=1.0, clutter_density=0.0, gate_probability=None)
    assert pda.exact_kalman
    s_kf, s_scan, s_plain = kf.initialize(mean, cov), pda.initialize(mean, cov), pda.initialize(mean, cov)
    for z in Z:
        s_kf, s_scan, s_plain = kf.predict(s_kf, bank), pda.predict(s_scan, bank), pda.predict(s_plain, bank)
        s_kf, i_kf = kf.update(s_kf, z, [sensor], LAYOUT)
        s_scan, i_scan = pda.update(s_scan, Scan("pos", z[None]), [sensor], LAYOUT)
        s_plain, i_plain = pda.update(s_plain, z, [sensor], LAYOUT)
        for state, innovation in ((s_scan, i_scan), (s_plain, i_plain)):
            # to rounding: 'kalman' may take its axis-separable fast path, PDA the general covariance form
            np.testing.assert_allclose(state.x, s_kf.x, rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(state.P, s_kf.P, rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(innovation.nu, i_kf.nu, rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(innovation.loglik, i_kf.loglik, rtol=1e-12)
            a = innovation.associations[0]
            np.testing.assert_array_equal(a.weights, np.ones((3, 1)))
            np.testing.assert_array_equal(a.missed, np.zeros(3))
            # with λ = 0 and P_D = 1 the association likelihood is the Gaussian ℓ itself
            np.testing.assert_allclose(a.loglik, i_kf.loglik, rtol=1e-12)


def test_the_kalman_configuration_passes_the_exact_contract_check():
    check_estimator(PDAFilter(1.0, 0.0, None))  # every mean, covariance and innovation against the covariance KF


def test_a_gated_lone_candidate_without_clutter_is_the_kalman_update():
    sensor = position_sensor()
    pda = PDAFilter(1.0, 0.0, gate_probability=0.99)
    kf = KalmanFilter()
    mean, cov = np.array([[0.0, 1.0, 0.0, 1.0]]), np.eye(4)[None] * 0.5
    z = np.array([0.3, -0.2])
    s_pda, inn = pda.update(pda.initialize(mean, cov), Scan("pos", z), [sensor], LAYOUT)
    s_kf, _ = kf.update(kf.initialize(mean, cov), z, [sensor], LAYOUT)
    np.testing.assert_allclose(s_pda.x, s_kf.x, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(s_pda.P, s_kf.P, rtol=1e-12, atol=1e-14)


def test_two_candidates_match_the_hand_computed_weights_and_update():
    # x⁻ = 0, P⁻ = I, H picks (x, y), R = I  ⇒  S = 2 I, K = P⁻Hᵀ S⁻¹ = ½ Hᵀ
    sensor = position_sensor(R=np.eye(2))
    lam, P_D, P_G = 0.1, 0.9, 0.99
    pda = PDAFilter(P_D, lam, P_G)
    z = np.array([[1.0, 0.0], [0.0, 2.0]])
    state, innovation = pda.update(pda.initialize(np.zeros((1, 4)), np.eye(4)[None]), Scan("pos", z), [sensor], LAYOUT)

    S = 2.0 * np.eye(2)
    d2 = np.array([1.0 / 2.0, 4.0 / 2.0])  # νᵀ S⁻¹ ν
    e = np.exp(-0.5 * d2)
    b = lam * np.sqrt(np.linalg.det(2 * np.pi * S)) * (1 - P_D * P_G) / P_D  # = 0.1 · 4π · 0.109 / 0.9
    beta = e / (b + e.sum())
    beta0 = b / (b + e.sum())
    a = innovation.associations[0]
    assert a.gate == pytest.approx(chi2.ppf(0.99, 2))
    np.testing.assert_allclose(a.distances[0], d2, rtol=1e-14)
    np.testing.assert_allclose(a.weights[0], beta, rtol=1e-12)
    np.testing.assert_allclose(a.missed[0], beta0, rtol=1e-12)
    assert a.selected[0] == 0

    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    K = 0.5 * H.T
    nu = beta @ z  # ẑ = 0
    np.testing.assert_allclose(innovation.nu[0], nu, rtol=1e-12)
    np.testing.assert_allclose(state.x[0], K @ nu, rtol=1e-12)
    Pc = np.eye(4) - K @ H  # (I − K H) P⁻ with P⁻ = I
    spread = sum(bi * np.outer(zi, zi) for bi, zi in zip(beta, z)) - np.outer(nu, nu)
    P = beta0 * np.eye(4) + (1 - beta0) * Pc + K @ spread @ K.T
    np.testing.assert_allclose(state.P[0], P, rtol=1e-12, atol=1e-15)

    # ln Λ = ln[(1 − P_D P_G) + (P_D/λ) Σ N(z_i; ẑ, S)]
    Lambda = (1 - P_D * P_G) + P_D / lam * sum(multivariate_normal(np.zeros(2), S).pdf(zi) for zi in z)
    np.testing.assert_allclose(a.loglik[0], np.log(Lambda), rtol=1e-12)
    assert isinstance(innovation, ClutterInnovation)
    np.testing.assert_allclose(innovation.association_loglik, a.loglik)


def test_a_candidate_outside_the_gate_gets_no_weight_and_an_empty_scan_leaves_the_prediction():
    sensor = position_sensor(R=np.eye(2))
    pda = PDAFilter(0.9, 0.1, 0.99)
    prior = pda.initialize(np.zeros((1, 4)), np.eye(4)[None])
    state, innovation = pda.update(prior, Scan("pos", [[1.0, 0.0], [50.0, 0.0]]), [sensor], LAYOUT)
    a = innovation.associations[0]
    np.testing.assert_array_equal(a.gated[0], [True, False])
    assert a.weights[0, 1] == 0.0
    alone, _ = pda.update(prior, Scan("pos", [[1.0, 0.0]]), [sensor], LAYOUT)
    np.testing.assert_array_equal(state.x, alone.x)
    np.testing.assert_array_equal(state.P, alone.P)

    # nothing gated: β₀ = 1, no correction; ln Λ = ln(1 − P_D P_G)
    for scan in (Scan("pos", [[50.0, 50.0]]), Scan("pos", np.zeros((0, 2)))):
        state, innovation = pda.update(prior, scan, [sensor], LAYOUT)
        np.testing.assert_array_equal(state.x, prior.x)
        np.testing.assert_array_equal(state.P, prior.P)
        a = innovation.associations[0]
        assert a.missed[0] == 1.0 and a.selected[0] == -1
        np.testing.assert_allclose(a.loglik, np.log(1 - 0.9 * 0.99))
    assert innovation.measurement_dim == 0  # an empty scan contributes no innovation (m = 0)


def test_far_candidates_do_not_underflow_without_a_gate():
    sensor = position_sensor(R=np.eye(2) * 1e-4)
    pda = PDAFilter(0.9, 1e-3, gate_probability=None)
    prior = pda.initialize(np.zeros((1, 4)), np.eye(4)[None] * 1e-4)
    state, innovation = pda.update(prior, Scan("pos", [[30.0, 0.0], [0.0, 40.0]]), [sensor], LAYOUT)
    assert np.all(np.isfinite(state.x)) and np.all(np.isfinite(state.P))
    a = innovation.associations[0]
    assert a.missed[0] == pytest.approx(1.0) and np.isfinite(a.loglik[0])


def test_the_bank_equals_its_filters_run_one_by_one():
    rng = np.random.default_rng(3)
    sensor = position_sensor(R=np.eye(2) * 0.05)
    transitions = [straight(q=0.01), turn([0.0, 0.0, 0.0, 2.0], 5.0, left=True), turn([0.0, 0.0, 0.0, 2.0], 5.0, left=False)]
    bank = TransitionBank.stack(transitions)
    pda = PDAFilter(0.8, 2.0, 0.99)
    mean, cov = np.tile([0.0, 0.0, 0.0, 2.0], (3, 1)), np.tile(np.eye(4) * 0.1, (3, 1, 1))
    whole = pda.initialize(mean, cov)
    singles = [pda.initialize(mean[:1], cov[:1]) for _ in transitions]
    for k in range(15):
        truth = np.array([0.0, 0.2 * k])
        scan = Scan("pos", np.vstack([truth + rng.normal(0, 0.2, 2), truth + rng.uniform(-1, 1, (rng.poisson(3), 2))]))
        whole, w_inn = pda.update(pda.predict(whole, bank), scan, [sensor], LAYOUT)
        for j, t in enumerate(transitions):
            singles[j], s_inn = pda.update(pda.predict(singles[j], TransitionBank.stack([t])), scan, [sensor], LAYOUT)
            np.testing.assert_allclose(whole.x[j], singles[j].x[0], rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(whole.P[j], singles[j].P[0], rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(w_inn.associations[0].weights[j], s_inn.associations[0].weights[0], rtol=1e-10, atol=1e-14)


def test_sequential_scans_of_two_sensors_without_clutter_equal_the_centralized_kalman_filter():
    rng = np.random.default_rng(5)
    xy = position_sensor(R=np.array([[0.04, 0.01], [0.01, 0.09]]), name="xy")
    x_only = MatrixSensor([[1.0, 0.0, 0.0, 0.0]], [[0.02]], name="x")
    pda, kf = PDAFilter(1.0, 0.0, None), KalmanFilter()
    bank = _bank()
    mean, cov = np.tile([0.0, 1.0, 0.0, 1.0], (3, 1)), np.tile(np.eye(4), (3, 1, 1))
    s_pda, s_kf = pda.initialize(mean, cov), kf.initialize(mean, cov)
    for k in range(10):
        z_xy, z_x = rng.normal(0.1 * k, 0.2, 2), rng.normal(0.1 * k, 0.2, 1)
        s_pda, inn = pda.update(pda.predict(s_pda, bank), [Scan("xy", z_xy), Scan("x", z_x)], [xy, x_only], LAYOUT)
        s_kf, _ = kf.update(kf.predict(s_kf, bank), np.concatenate([z_xy, z_x]), [xy, x_only], LAYOUT)
        np.testing.assert_allclose(s_pda.x, s_kf.x, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(s_pda.P, s_kf.P, rtol=1e-9, atol=1e-12)
        assert inn.measurement_dim == 3 and len(inn.associations) == 2
        # the stacked innovation is consistent: NIS = Σ of the sensors' NIS
        nis = sum(
            np.einsum("mi,mi->m", n, np.linalg.solve(S, n[..., None])[..., 0])
            for n, S in ((inn.nu[:, :2], inn.S[:, :2, :2]), (inn.nu[:, 2:], inn.S[:, 2:, 2:]))
        )
        np.testing.assert_allclose(inn.nis, nis, rtol=1e-9)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"detection_probability": 0.0}, "detection_probability"),
        ({"detection_probability": 1.5}, "detection_probability"),
        ({"detection_probability": float("nan")}, "detection_probability"),
        ({"clutter_density": -1.0}, "clutter_density"),
        ({"clutter_density": float("inf")}, "clutter_density"),
        ({"gate_probability": 0.0}, "gate_probability"),
        ({"gate_probability": 1.0}, "gate_probability"),
        ({"gate_probability": 1.2}, "gate_probability"),
        ({"form": "inverse"}, "form"),
    ],
)
def test_bad_parameters_raise_value_error(kwargs, message):
    with pytest.raises(ValueError, match=message):
        PDAFilter(**kwargs)


def test_bad_scans_raise_value_error():
    pda = PDAFilter(0.9, 0.1)
    state = pda.initialize(np.zeros((1, 4)), np.eye(4)[None])
    sensor = position_sensor()
    with pytest.raises(ValueError, match="not among the sensors"):
        pda.update(state, Scan("radar", [[0.0, 0.0]]), [sensor], LAYOUT)
    with pytest.raises(ValueError, match="dimension"):
        pda.update(state, Scan("pos", [[0.0, 0.0, 0.0]]), [sensor], LAYOUT)
    with pytest.raises(ValueError, match="one scan per sensor"):
        pda.update(state, [Scan("pos", [[0.0, 0.0]]), Scan("pos", [[1.0, 0.0]])], [sensor], LAYOUT)
    with pytest.raises(ValueError, match="NaN or inf"):
        Scan("pos", [[np.nan, 0.0]])


def test_pda_agrees_with_stone_soup_on_the_same_measurements():
    pytest.importorskip("stonesoup")
    import datetime

    from stonesoup.dataassociator.probability import PDA
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.updater.probability import PDAUpdater

    tau, lam, P_D, P_G = 1.0, 0.02, 0.8, 0.99
    R = np.array([[1.0, 0.3], [0.3, 2.0]])
    model = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.5), ConstantVelocity(0.5)])
    measurement_model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R)
    dt = datetime.timedelta(seconds=tau)
    F, Q = model.matrix(time_interval=dt), model.covar(time_interval=dt)
    updater = PDAUpdater(measurement_model)
    associator = PDA(PDAHypothesiser(KalmanPredictor(model), updater, clutter_spatial_density=lam, prob_detect=P_D, prob_gate=P_G))

    t = datetime.datetime(2024, 1, 1)
    x0, P0 = np.array([0.0, 1.0, 0.0, -0.5]), np.diag([4.0, 1.0, 4.0, 1.0])
    track = Track([GaussianState(x0.reshape(-1, 1), P0, timestamp=t)])
    pda, sensor = PDAFilter(P_D, lam, P_G), MatrixSensor([[1.0, 0, 0, 0], [0, 0, 1.0, 0]], R, name="pos")
    state = pda.initialize(x0[None], P0[None])
    bank = TransitionBank(F[None], np.zeros((1, 4)), Q[None])
    rng = np.random.default_rng(11)
    truth = x0.copy()
    compared_weights = 0
    for _ in range(15):
        t += dt
        truth = F @ truth
        z = [truth[[0, 2]] + rng.multivariate_normal(np.zeros(2), R)] if rng.random() < P_D else []
        z += list(truth[[0, 2]] + rng.uniform(-10, 10, (rng.poisson(lam * 400), 2)))
        Z = np.array(z).reshape(-1, 2)
        hypotheses = associator.associate(
            {track}, {Detection(zi.reshape(-1, 1), timestamp=t, measurement_model=measurement_model) for zi in Z}, t
        )[track]
        posterior = updater.update(hypotheses)
        track.append(posterior)
        state, innovation = pda.update(pda.predict(state, bank), Scan("pos", Z), [sensor], LAYOUT)
        np.testing.assert_allclose(state.x[0], np.asarray(posterior.state_vector, float).ravel(), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(state.P[0], np.asarray(posterior.covar, float), rtol=1e-9, atol=1e-9)
        a = innovation.associations[0]
        for h in hypotheses:
            if not h:  # missed detection
                assert a.missed[0] == pytest.approx(float(h.probability), rel=1e-9)
                continue
            i = int(np.flatnonzero(np.all(Z == np.asarray(h.measurement.state_vector, float).ravel(), axis=1))[0])
            assert a.weights[0, i] == pytest.approx(float(h.probability), rel=1e-9)
            compared_weights += 1
    assert compared_weights > 15
