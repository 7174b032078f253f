"""The particle filter on clutter scans (``particle`` with ``accepts_scans``; seed 004, SPEC §6).

Λ(x) = (1 − P_D) + (P_D/λ) Σ_r N(z_r; h(x), R): with P_D = 1, λ = 0 and one
candidate it is the ordinary update (same seed, same particles); from a Gaussian
prior the exact posterior after one scan has PDA's (ungated) mean and covariance
and PDA's ln Λ — the particle estimates approach them; over a run in clutter it
tracks as well as PDA.
"""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.protocols import ClutterInnovation
from hybridtrack.engine.clutter import ClutterModel, region_around
from hybridtrack.sdk.scans import Scan
from hybridtrack_plugins.filters.particle import ParticleClutterInnovation, ParticleFilter
from hybridtrack_plugins.filters.pda import PDAFilter
from hybridtrack_plugins.sensors.bearing import BearingSensor

REGISTRY = ht.load_plugins(strict=True).registry
X0 = np.array([0.0, 1.0, 0.0, 2.0])
P0 = np.diag([1.0, 0.2, 1.0, 0.2])


def _model():
    return REGISTRY.create("motion_model", "straight", noise_cov=np.eye(2) * 0.05)


@pytest.mark.parametrize("kind", ["position", "bearing"])
def test_one_candidate_without_clutter_and_certain_detection_is_the_ordinary_update(kind):
    model = _model()
    layout = model.layout
    if kind == "position":
        sensor = REGISTRY.create("sensor", "position", noise_cov=np.diag([0.5, 0.3]))
    else:
        sensor = BearingSensor(name="bearing", sigma=np.deg2rad(2.0), observer=(-20.0, -5.0))
    t = model.transition(1.0, X0)
    bank = TransitionBank.stack([t] * 3)
    rng = np.random.default_rng(7)
    plain_pf = ParticleFilter(particles=500, seed=3, threshold=0.7)
    scan_pf = ParticleFilter(particles=500, seed=3, threshold=0.7, detection_probability=1.0, clutter_density=0.0)
    a = plain_pf.initialize(np.tile(X0, (3, 1)), np.stack([P0] * 3))
    b = scan_pf.initialize(np.tile(X0, (3, 1)), np.stack([P0] * 3))
    truth = X0.copy()
    resampled = 0
    for _ in range(6):
        truth = t.apply(truth)
        z = sensor.simulate(truth, layout, rng)
        a, ia = plain_pf.update(plain_pf.predict(a, bank), z, [sensor], layout)
        b, ib = scan_pf.update(scan_pf.predict(b, bank), [Scan(sensor.name, z[None])], [sensor], layout)
        assert isinstance(ib, ParticleClutterInnovation) and isinstance(ib, ClutterInnovation)
        np.testing.assert_allclose(b.log_weights, a.log_weights, rtol=0, atol=1e-9)
        np.testing.assert_allclose(b.particles, a.particles, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ib.loglik, ia.loglik, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ib.association_loglik, ia.loglik, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(ib.resampled, ia.resampled)
        np.testing.assert_allclose(ib.associations[0].weights, 1.0, atol=1e-12)  # the lone candidate is the target
        resampled += int(ia.resampled.sum())
    assert resampled > 0  # the resampling path was exercised too


@pytest.mark.parametrize("gate", [None, 0.99])
def test_from_a_gaussian_prior_one_scan_gives_the_pda_posterior_and_likelihood(gate):
    """The exact posterior of one scan from N(x⁻, P⁻) has PDA's mean and covariance (Bar-Shalom & Fortmann 1988 §6.4);
    with a gate, the candidate far away is left out by both."""
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.eye(2) * 0.2)
    layout = _model().layout
    x, P = np.array([1.0, 0.5, -1.0, 0.2]), np.diag([0.6, 0.1, 0.4, 0.1])
    scan = Scan(sensor.name, np.array([[1.3, -0.8], [0.2, -1.9], [1.9, -0.2], [5.0, 5.0]]))
    P_D, lam = 0.8, 0.3
    pda = PDAFilter(P_D, lam, gate_probability=gate)
    s_pda, i_pda = pda.update(pda.initialize(x[None], P[None]), scan, [sensor], layout)
    pf = ParticleFilter(particles=200_000, seed=1, detection_probability=P_D, clutter_density=lam, threshold=1e-9, gate_probability=gate)
    s_pf, i_pf = pf.update(pf.initialize(x[None], P[None]), scan, [sensor], layout)
    # Monte Carlo error ~ σ/√N_eff ≈ 1e-3 here
    np.testing.assert_allclose(pf.mean(s_pf), s_pda.x, atol=1e-2)
    np.testing.assert_allclose(pf.covariance(s_pf), s_pda.P, atol=1e-2)
    np.testing.assert_allclose(i_pf.loglik, i_pda.association_loglik, atol=1e-2)
    a_pf, a_pda = i_pf.associations[0], i_pda.associations[0]
    np.testing.assert_allclose(a_pf.weights, a_pda.weights, atol=5e-3)
    np.testing.assert_allclose(a_pf.missed, a_pda.missed, atol=5e-3)
    np.testing.assert_allclose(a_pf.weights.sum(axis=1) + a_pf.missed, 1.0, atol=1e-12)
    np.testing.assert_array_equal(a_pf.gated, a_pda.gated)
    assert a_pf.gate == a_pda.gate
    assert a_pf.selected[0] == a_pda.selected[0]


def test_an_empty_scan_keeps_the_weights_and_scores_the_miss():
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.eye(2) * 0.2)
    layout = _model().layout
    pf = ParticleFilter(particles=100, seed=2, detection_probability=0.7, clutter_density=0.1)
    state = pf.initialize(X0[None], P0[None])
    new, innovation = pf.update(state, Scan(sensor.name, np.zeros((0, 2))), [sensor], layout)
    np.testing.assert_array_equal(new.log_weights, state.log_weights)
    np.testing.assert_allclose(innovation.loglik, np.log(0.3))
    assert innovation.measurement_dim == 0
    certain = ParticleFilter(particles=100, seed=2, detection_probability=1.0, clutter_density=0.1)
    _, innovation = certain.update(certain.initialize(X0[None], P0[None]), Scan(sensor.name, np.zeros((0, 2))), [sensor], layout)
    np.testing.assert_array_equal(innovation.loglik, 0.0)  # impossible under P_D = 1: no measurement


def test_in_clutter_it_tracks_like_pda_on_a_linear_case():
    """Seeded run with λ = 0.1 /m², P_D = 0.9: the particle filter's RMSE at most 15 % above PDA's (both ≪ the clutter spacing)."""
    model = REGISTRY.create("motion_model", "straight", noise_cov=np.eye(2) * 0.01)
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.eye(2) * 0.1)
    layout = model.layout
    t = model.transition(0.5, X0)
    rng = np.random.default_rng(11)
    truth, states = X0.copy(), []
    for _ in range(40):
        truth = t.apply(truth) + t.G @ rng.multivariate_normal(np.zeros(2), t.Q)
        states.append(truth)
    states = np.array(states)
    positions = states[:, [0, 2]]
    clean = positions + rng.normal(0.0, np.sqrt(0.1), positions.shape)
    clutter = ClutterModel(0.1, 0.9, region_around(positions, 3.0))
    scans = [Scan(sensor.name, z) for z in _with_clutter(clean, clutter, rng)]
    bank = TransitionBank.stack([t])
    errors = {}
    for name, estimator in (
        ("pda", PDAFilter(0.9, 0.1, 0.99)),
        ("particle", ParticleFilter(particles=1000, seed=5, detection_probability=0.9, clutter_density=0.1)),
    ):
        state = estimator.initialize(X0[None], P0[None])
        err = []
        for k, scan in enumerate(scans):
            state = estimator.predict(state, bank)
            state, _ = estimator.update(state, scan, [sensor], layout)
            err.append(np.sum((estimator.mean(state)[0, [0, 2]] - positions[k]) ** 2))
        errors[name] = np.sqrt(np.mean(err))
    assert errors["pda"] < 1.0  # seeded: 0.46 m (PDA), 0.39 m (particle); clutter spacing 1/√λ ≈ 3.2 m
    assert errors["particle"] < 1.15 * errors["pda"]


def _with_clutter(clean, clutter, rng):
    """Scans: the detected measurement (probability P_D) plus Poisson(λV) uniform false ones (hybridtrack.sdk.scans's model)."""
    low, high = clutter.region
    volume = float(np.prod(high - low))
    out = []
    for z in clean:
        false = low + (high - low) * rng.random((rng.poisson(clutter.density * volume), 2))
        detected = z[None] if rng.random() < clutter.detection_probability else np.zeros((0, 2))
        out.append(np.concatenate([detected, false]))
    return out


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"detection_probability": 0.0}, ValueError, "detection_probability"),
        ({"detection_probability": 1.5}, ValueError, "detection_probability"),
        ({"clutter_density": -1.0}, ValueError, "clutter_density"),
        ({"clutter_density": float("inf")}, ValueError, "clutter_density"),
    ],
)
def test_bad_clutter_parameters_raise(kwargs, error, match):
    with pytest.raises(error, match=match):
        ParticleFilter(particles=10, **kwargs)


def test_bad_scans_raise():
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.eye(2) * 0.2)
    layout = _model().layout
    pf = ParticleFilter(particles=10, seed=0, detection_probability=0.9, clutter_density=0.1)
    state = pf.initialize(X0[None], P0[None])
    with pytest.raises(ValueError, match="not among the sensors"):
        pf.update(state, Scan("other", np.zeros((1, 2))), [sensor], layout)
    with pytest.raises(ValueError, match="dimension 3"):
        pf.update(state, Scan(sensor.name, np.zeros((1, 3))), [sensor], layout)
    with pytest.raises(ValueError, match="one scan per sensor"):
        pf.update(state, [Scan(sensor.name, np.zeros((1, 2)))] * 2, [sensor], layout)


def test_initialize_mixture_allocates_particles_systematically_and_matches_the_mixture_moments():
    means = np.array([[[0.0, 0.0, 0.0, 0.0], [10.0, 1.0, -5.0, 0.0]]])
    covs = np.stack([np.eye(4), 2.0 * np.eye(4)])[None]
    weights = np.array([[1.0, 3.0]])  # renormalised to ¼, ¾
    pf = ParticleFilter(particles=40_000, seed=9)
    state = pf.initialize_mixture(means, covs, weights)
    assert state.particles.shape == (1, 40_000, 4)
    near_second = np.linalg.norm(state.particles[0] - means[0, 1], axis=1) < np.linalg.norm(state.particles[0] - means[0, 0], axis=1)
    assert abs(near_second.mean() - 0.75) < 0.01  # exactly 30,000 drawn from the second (a few cross over)
    w = np.array([0.25, 0.75])
    mean = w @ means[0]
    d = means[0] - mean
    cov = np.einsum("c,cij->ij", w, covs[0]) + np.einsum("c,ci,cj->ij", w, d, d)
    np.testing.assert_allclose(pf.mean(state)[0], mean, atol=0.05)
    np.testing.assert_allclose(pf.covariance(state)[0], cov, atol=0.3)
    with pytest.raises(ValueError, match="weights"):
        pf.initialize_mixture(means, covs, np.array([[0.0, 0.0]]))
