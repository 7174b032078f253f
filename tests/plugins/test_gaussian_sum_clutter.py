"""The Gaussian-sum filter on clutter scans (``gaussian_sum`` with ``accepts_scans``; Salmond 1990; seed 004).

Every component branches into a missed child and one Kalman child per gated
candidate, then the mixture is reduced.  One component, P_D = 1, λ = 0, no gate
and one candidate: the Kalman filter (1e-12).  From one Gaussian component and
without reduction, one scan gives exactly PDA's (ungated) mean, covariance and
ln Λ — the PDA update is the moment match of this mixture (Bar-Shalom &
Fortmann 1988 §6.4).
"""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.protocols import ClutterInnovation
from hybridtrack.sdk.scans import Scan
from hybridtrack_plugins.filters.gaussian_sum import GaussianSumFilter
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.filters.pda import PDAFilter

REGISTRY = ht.load_plugins(strict=True).registry
X0 = np.array([0.0, 1.0, 0.0, 2.0])
P0 = np.diag([1.0, 0.2, 1.0, 0.2])


def _setup():
    model = REGISTRY.create("motion_model", "straight", noise_cov=np.eye(2) * 0.05)
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.diag([0.5, 0.3]))
    return model, sensor, model.layout


def test_one_component_without_clutter_is_the_kalman_filter():
    model, sensor, layout = _setup()
    t = model.transition(1.0, X0)
    bank = TransitionBank.stack([t, t])
    gs = GaussianSumFilter(detection_probability=1.0, clutter_density=0.0, gate_probability=None)
    kf = KalmanFilter()
    a, b = kf.initialize(np.tile(X0, (2, 1)), np.stack([P0] * 2)), gs.initialize(np.tile(X0, (2, 1)), np.stack([P0] * 2))
    rng = np.random.default_rng(3)
    truth = X0.copy()
    for _ in range(8):
        truth = t.apply(truth)
        z = sensor.simulate(truth, layout, rng)
        a, ia = kf.update(kf.predict(a, bank), z, [sensor], layout)
        b, ib = gs.update(gs.predict(b, bank), Scan(sensor.name, z[None]), [sensor], layout)
        assert isinstance(ib, ClutterInnovation)
        np.testing.assert_allclose(gs.mean(b), kf.mean(a), rtol=0, atol=1e-12)
        np.testing.assert_allclose(gs.covariance(b), kf.covariance(a), rtol=0, atol=1e-12)
        np.testing.assert_allclose(ib.loglik, ia.loglik, rtol=0, atol=1e-12)


@pytest.mark.parametrize("gate", [None, 0.99])
def test_one_scan_from_one_component_is_the_pda_posterior_before_reduction(gate):
    _, sensor, layout = _setup()
    x, P = np.array([1.0, 0.5, -1.0, 0.2]), np.diag([0.6, 0.1, 0.4, 0.1])
    scan = Scan(sensor.name, np.array([[1.3, -0.8], [0.2, -1.9], [1.9, -0.2], [9.0, 9.0]]))
    P_D, lam = 0.8, 0.3
    pda = PDAFilter(P_D, lam, gate_probability=gate)
    s_pda, i_pda = pda.update(pda.initialize(x[None], P[None]), scan, [sensor], layout)
    gs = GaussianSumFilter(
        merge_threshold=None, prune_threshold=0.0, max_components=50, detection_probability=P_D, clutter_density=lam, gate_probability=gate
    )
    s_gs, i_gs = gs.update(gs.initialize(x[None], P[None]), scan, [sensor], layout)
    np.testing.assert_allclose(gs.mean(s_gs), s_pda.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(gs.covariance(s_gs), s_pda.P, rtol=0, atol=1e-12)
    np.testing.assert_allclose(i_gs.association_loglik, i_pda.association_loglik, rtol=0, atol=1e-12)
    a_gs, a_pda = i_gs.associations[0], i_pda.associations[0]
    np.testing.assert_allclose(a_gs.weights, a_pda.weights, atol=1e-12)
    np.testing.assert_allclose(a_gs.missed, a_pda.missed, atol=1e-12)
    np.testing.assert_array_equal(a_gs.gated, a_pda.gated)
    assert int(np.isfinite(s_gs.log_weights).sum()) == 1 + int(a_pda.gated.sum())  # the missed child and one per gated candidate


def test_reduction_keeps_the_mixture_bounded_over_a_run_in_clutter():
    model, sensor, layout = _setup()
    t = model.transition(0.5, X0)
    bank = TransitionBank.stack([t])
    rng = np.random.default_rng(4)
    gs = GaussianSumFilter(max_components=6, detection_probability=0.9, clutter_density=0.2)
    state = gs.initialize(X0[None], P0[None])
    truth = X0.copy()
    for _ in range(15):
        truth = t.apply(truth)
        z = np.concatenate([sensor.simulate(truth, layout, rng)[None], truth[[0, 2]] + rng.uniform(-4, 4, (6, 2))])
        state, innovation = gs.update(gs.predict(state, bank), Scan(sensor.name, z), [sensor], layout)
        assert state.x.shape[1] <= 6
        np.testing.assert_allclose(np.exp(state.log_weights).sum(axis=1), 1.0)
        assert np.isfinite(innovation.loglik).all()
    assert np.linalg.norm(gs.mean(state)[0, [0, 2]] - truth[[0, 2]]) < 2.0


def test_bad_clutter_parameters_and_scans_raise():
    _, sensor, layout = _setup()
    with pytest.raises(ValueError, match="detection_probability"):
        GaussianSumFilter(detection_probability=0.0)
    with pytest.raises(ValueError, match="clutter_density"):
        GaussianSumFilter(clutter_density=-0.1)
    with pytest.raises(ValueError, match="gate_probability"):
        GaussianSumFilter(gate_probability=1.0)
    gs = GaussianSumFilter(detection_probability=0.9, clutter_density=0.1)
    state = gs.initialize(X0[None], P0[None])
    with pytest.raises(ValueError, match="not among the sensors"):
        gs.update(state, Scan("other", np.zeros((1, 2))), [sensor], layout)
