"""The bootstrap particle filter (``particle``) against the Kalman filter, hand-derived resampling, seeds and errors.

On a linear-Gaussian system the SIR posterior converges to the KF's: the
errors of the particle mean, covariance and ℓ against the KF shrink like
1/√N (Crisan & Doucet 2002); the slope of log error against log N over
N = 10², 10³, 10⁴, 10⁵ must be close to −½.  Each N runs as a bank of
M = 10⁵/N independent filters (their own random streams), so the error
is averaged over M filters and the steps.
"""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.filters.particle import (
    ParticleFilter,
    ParticleInnovation,
    ParticleState,
    effective_sample_size,
    silverman_bandwidth,
    systematic_resample,
)
from hybridtrack_plugins.motion.ship import ShipTurn
from hybridtrack_plugins.sensors.bearing import BearingSensor

REGISTRY = ht.load_plugins(strict=True).registry
X0 = np.array([0.0, 1.0, 0.0, 2.0])
P0 = np.diag([1.0, 0.2, 1.0, 0.2])


def _linear_problem(steps: int, seed: int = 5):
    model = REGISTRY.create("motion_model", "straight", noise_cov=np.eye(2) * 0.05)
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.diag([0.5, 0.3]))
    t = model.transition(1.0, X0)
    rng = np.random.default_rng(seed)
    truth, zs = X0.copy(), []
    for _ in range(steps):
        truth = t.apply(truth) + t.G @ rng.multivariate_normal(np.zeros(2), t.Q)
        zs.append(sensor.simulate(truth, model.layout, rng))
    return t, sensor, model.layout, zs


def _run(estimator, M, t, sensor, layout, zs):
    bank = TransitionBank.stack([t] * M)
    state = estimator.initialize(np.tile(X0, (M, 1)), np.stack([P0] * M))
    out = []
    for z in zs:
        state = estimator.predict(state, bank)
        state, innovation = estimator.update(state, z, [sensor], layout)
        out.append((estimator.mean(state).copy(), estimator.covariance(state).copy(), innovation.loglik.copy()))
    return out, state


def test_particle_filter_converges_to_the_kalman_filter_as_one_over_root_n():
    t, sensor, layout, zs = _linear_problem(steps=5)
    reference, _ = _run(KalmanFilter(), 1, t, sensor, layout, zs)
    sizes = np.array([100, 1_000, 10_000, 100_000])
    errors = []
    for N in sizes:
        run, _ = _run(ParticleFilter(particles=int(N), seed=1), int(100_000 // N), t, sensor, layout, zs)
        mean_error, cov_error, loglik_error = [], [], []
        for (x, P, loglik), (x_kf, P_kf, loglik_kf) in zip(run, reference):
            e = np.linalg.solve(np.linalg.cholesky(P_kf[0]), (x - x_kf).T)  # whitened by the KF covariance
            mean_error.append(np.sqrt((e**2).sum(axis=0).mean()))
            cov_error.append(np.sqrt(((P - P_kf) ** 2).sum(axis=(1, 2)).mean()) / np.linalg.norm(P_kf[0]))
            loglik_error.append(np.sqrt(((loglik - loglik_kf) ** 2).mean()))
        errors.append([np.mean(mean_error), np.mean(cov_error), np.mean(loglik_error)])
    errors = np.array(errors)
    slopes = [np.polyfit(np.log(sizes), np.log(errors[:, j]), 1)[0] for j in range(3)]
    # measured over seeds 0–3: mean −0.51…−0.54, covariance −0.50…−0.54, ℓ −0.53…−0.65 (its O(1/N) bias
    # adds to the O(1/√N) spread); at N = 10⁵ the errors are ≈ 0.014, 0.012 and 0.003–0.008
    assert -0.62 < slopes[0] < -0.42, (slopes, errors)
    assert -0.62 < slopes[1] < -0.42, (slopes, errors)
    assert -0.75 < slopes[2] < -0.4, (slopes, errors)
    assert errors[-1, 0] < 0.03 and errors[-1, 1] < 0.03 and errors[-1, 2] < 0.02, errors


def test_same_seed_reproduces_and_another_seed_differs():
    t, sensor, layout, zs = _linear_problem(steps=4)

    def final(seed):
        _, state = _run(ParticleFilter(particles=300, seed=seed, threshold=0.8), 3, t, sensor, layout, zs)
        return state

    a, b, c = final(11), final(11), final(12)
    np.testing.assert_array_equal(a.particles, b.particles)
    np.testing.assert_array_equal(a.log_weights, b.log_weights)
    assert not np.array_equal(a.particles, c.particles)
    g1, g2 = final(np.random.default_rng(3)), final(np.random.default_rng(3))
    np.testing.assert_array_equal(g1.particles, g2.particles)


def test_a_filter_steps_the_same_whatever_bank_it_is_in():
    """Each filter draws from its own stream: take/concatenate commute with a step (copies stay identical)."""
    t, sensor, layout, zs = _linear_problem(steps=2)
    pf = ParticleFilter(particles=200, seed=4, threshold=1.0)
    state = pf.initialize(np.tile(X0, (3, 1)), np.stack([P0] * 3))
    bank3, bank1 = TransitionBank.stack([t] * 3), TransitionBank.stack([t] * 4)
    whole, _ = pf.update(pf.predict(state, bank3), zs[0], [sensor], layout)
    picked = pf.take(state, [2, 0, 0, 1])
    stepped, _ = pf.update(pf.predict(picked, bank1), zs[0], [sensor], layout)
    np.testing.assert_array_equal(stepped.particles, whole.particles[[2, 0, 0, 1]])
    np.testing.assert_array_equal(pf.mean(stepped), pf.mean(whole)[[2, 0, 0, 1]])


def test_systematic_resampling_by_hand():
    w = np.array([[0.1, 0.2, 0.3, 0.4], [0.7, 0.1, 0.1, 0.1]])
    # u = 0.5: points (j + ½)/4 = ⅛, ⅜, ⅝, ⅞ against c = (0.1, 0.3, 0.6, 1.0) and (0.7, 0.8, 0.9, 1.0)
    index = systematic_resample(np.log(w), np.array([0.5, 0.5]))
    np.testing.assert_array_equal(index, [[1, 2, 3, 3], [0, 0, 0, 2]])
    rng = np.random.default_rng(0)
    w = rng.dirichlet(np.ones(50), size=20)
    index = systematic_resample(np.log(w), rng.random(20))
    counts = np.stack([np.bincount(row, minlength=50) for row in index])
    assert ((counts >= np.floor(50 * w) - 1e-9) & (counts <= np.ceil(50 * w) + 1e-9)).all()  # ⌊N w⌋ or ⌈N w⌉ copies


def test_effective_sample_size_triggers_resampling():
    t, sensor, layout, zs = _linear_problem(steps=3)
    bank = TransitionBank.stack([t] * 4)
    N = 500
    for threshold in (1.0, 0.5, 1e-6):
        pf = ParticleFilter(particles=N, threshold=threshold, seed=2)
        state = pf.initialize(np.tile(X0, (4, 1)), np.stack([P0] * 4))
        for z in zs:
            predicted = pf.predict(state, bank)
            state, innovation = pf.update(predicted, z, [sensor], layout)
            assert isinstance(innovation, ParticleInnovation)
            ess = innovation.effective_sample_size
            assert ((ess > 1.0) & (ess < N)).all()
            np.testing.assert_array_equal(innovation.resampled, ess < threshold * N)
            if threshold == 1.0:
                assert innovation.resampled.all()
                np.testing.assert_allclose(state.weights, 1.0 / N, rtol=1e-12)
                np.testing.assert_allclose(state.effective_sample_size, N, rtol=1e-9)
            if threshold == 1e-6:
                assert not innovation.resampled.any()
                np.testing.assert_array_equal(state.particles, predicted.particles)
                np.testing.assert_allclose(state.effective_sample_size, ess, rtol=1e-12)
                w = state.weights
                np.testing.assert_allclose(1.0 / (w**2).sum(axis=1), ess, rtol=1e-9)


def test_log_weights_are_bayes_rule_by_hand():
    """One update without resampling: w ∝ w⁻ N(z; H x, R), ℓ = ln Σ w⁻ N(z; H x, R), ν̄ and S from the particles."""
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.diag([0.5, 0.3]))
    layout = ("x", "vx", "y", "vy")
    pf = ParticleFilter(particles=50, threshold=1e-9, seed=9)
    state = pf.initialize(X0[None], P0[None])
    z = np.array([0.3, -0.2])
    new, innovation = pf.update(state, z, [sensor], layout)
    X, w_prior = state.particles[0], state.weights[0]
    nu = z - X[:, [0, 2]]
    R = np.diag([0.5, 0.3])
    lik = np.exp(-0.5 * np.einsum("ki,ij,kj->k", nu, np.linalg.inv(R), nu)) / (2 * np.pi * np.sqrt(np.linalg.det(R)))
    np.testing.assert_allclose(new.weights[0], w_prior * lik / (w_prior * lik).sum(), rtol=1e-10)
    np.testing.assert_allclose(innovation.loglik[0], np.log((w_prior * lik).sum()), rtol=1e-12)
    nu_bar = w_prior @ nu
    S = (nu - nu_bar).T @ ((nu - nu_bar) * w_prior[:, None]) + R
    np.testing.assert_allclose(innovation.nu[0], nu_bar, rtol=1e-12)
    np.testing.assert_allclose(innovation.S[0], S, rtol=1e-12)
    np.testing.assert_allclose(innovation.nis[0], nu_bar @ np.linalg.solve(S, nu_bar), rtol=1e-10)
    np.testing.assert_allclose(pf.mean(new)[0], new.weights[0] @ X, rtol=1e-12)
    np.testing.assert_allclose(1.0 / effective_sample_size(new.log_weights), (new.weights**2).sum(axis=1), rtol=1e-10)


def test_a_nan_component_is_left_out():
    """z = (x, NaN) with a diagonal R updates exactly like a sensor measuring x alone."""
    layout = ("x", "vx", "y", "vy")
    xy = REGISTRY.create("sensor", "position", noise_cov=np.diag([0.5, 0.3]))
    x_only = REGISTRY.create("sensor", "position", components=("x",), noise_cov=np.diag([0.5]))
    pf = ParticleFilter(particles=100, threshold=0.9, seed=3)
    state = pf.initialize(X0[None], P0[None])
    a, ia = pf.update(state, np.array([0.4, np.nan]), [xy], layout)
    b, ib = pf.update(state, np.array([0.4]), [x_only], layout)
    np.testing.assert_allclose(a.particles, b.particles, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ia.loglik, ib.loglik, rtol=1e-12)
    assert ia.measurement_dim == 1
    c, ic = pf.update(state, np.array([np.nan, np.nan]), [xy], layout)
    assert ic.measurement_dim == 0 and c.particles is state.particles


def test_regularisation_jitters_the_resampled_particles():
    assert silverman_bandwidth(1000, 4) == pytest.approx((4 / 6) ** (1 / 8) * 1000 ** (-1 / 8))
    t, sensor, layout, zs = _linear_problem(steps=1)
    bank = TransitionBank.stack([t])
    plain, jittered = (
        ParticleFilter(particles=2000, threshold=1.0, seed=8),
        ParticleFilter(particles=2000, threshold=1.0, regularize=True, seed=8),
    )
    a, _ = plain.update(plain.predict(plain.initialize(X0[None], P0[None]), bank), zs[0], [sensor], layout)
    b, _ = jittered.update(jittered.predict(jittered.initialize(X0[None], P0[None]), bank), zs[0], [sensor], layout)
    assert len(np.unique(a.particles[0], axis=0)) < 2000  # resampling copies particles
    assert len(np.unique(b.particles[0], axis=0)) == 2000  # the kernel makes every copy distinct
    np.testing.assert_allclose(plain.mean(b), plain.mean(a), atol=0.1)
    assert np.all(np.diag(jittered.covariance(b)[0]) > np.diag(plain.covariance(a)[0]))  # the kernel adds h² D Dᵀ


def test_nonlinear_motion_propagates_each_particle_through_f():
    """A linearizing callable is evaluated at every particle: F x + B = f(x) exactly (noise switched off)."""
    ship = ShipTurn(sigma_velocity=0.0, sigma_rate=0.0)
    pf = ParticleFilter(particles=300, seed=6)
    mean = np.array([[0.0, 0.0, 5.0, 1.0, 0.05], [100.0, 50.0, -3.0, 2.0, -0.02]])
    cov = np.stack([np.diag([10.0, 10.0, 1.0, 1.0, 1e-4])] * 2)
    state = pf.initialize(mean, cov)
    predicted = pf.predict(state, ship.linearizer(2.0))
    np.testing.assert_allclose(predicted.particles, ship.f(state.particles, 2.0), rtol=1e-12, atol=1e-9)
    noisy = ParticleFilter(particles=20_000, seed=6)
    s = noisy.initialize(mean, cov)
    spread = noisy.covariance(noisy.predict(s, ShipTurn(sigma_velocity=0.5, sigma_rate=0.0).linearizer(2.0)))
    spread0 = noisy.covariance(noisy.predict(s, ship.linearizer(2.0)))
    # the velocity noise adds Γ Q Γᵀ: 4 σ_v² to each velocity variance (Γ rows vx, vy = T = 2)
    np.testing.assert_allclose(spread[:, 2, 2] - spread0[:, 2, 2], 4 * 0.25, rtol=0.1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bearings_from_two_observers_nees_is_sane(seed):
    """Two bearing sensors (triangulation), CV target, M = 40 Monte Carlo runs stacked as the bank (z per filter)."""
    model = REGISTRY.create("motion_model", "straight", noise_cov=np.eye(2) * 0.01)
    layout = model.layout
    sensors = [
        BearingSensor(name="west", sigma=np.deg2rad(1.0), observer=(-500.0, 0.0)),
        BearingSensor(name="east", sigma=np.deg2rad(1.0), observer=(500.0, 0.0)),
    ]
    t = model.transition(1.0, np.zeros(4))
    M, steps = 40, 15
    rng = np.random.default_rng(100 + seed)
    x0 = np.array([0.0, 2.0, 800.0, -1.0])
    P = np.diag([400.0, 1.0, 400.0, 1.0])
    truth = x0 + rng.standard_normal((M, 4)) @ np.linalg.cholesky(P).T
    pf = ParticleFilter(particles=3000, seed=seed)
    state = pf.initialize(np.tile(x0, (M, 1)), np.stack([P] * M))
    bank = TransitionBank.stack([t] * M)
    nees, nis = [], []
    for _ in range(steps):
        truth = t.apply(truth) + rng.standard_normal((M, 2)) @ np.linalg.cholesky(t.Q).T @ t.G.T
        z = np.concatenate([s.simulate(truth, layout, rng) for s in sensors], axis=1)  # (M, 2)
        state, innovation = pf.update(pf.predict(state, bank), z, sensors, layout)
        e = truth - pf.mean(state)
        nees.append(np.einsum("mi,mi->m", e, np.linalg.solve(pf.covariance(state), e[..., None])[..., 0]))
        nis.append(innovation.nis)
        assert np.isfinite(innovation.loglik).all()
    nees, nis = np.array(nees), np.array(nis)
    # n = 4, m = 2: averages over 40 runs × 15 steps near 4 and 2 (measured NEES 3.52, 4.52, 4.37 and
    # NIS 1.97, 2.12, 1.95 for seeds 0, 1, 2; per-step 95 % χ² bounds of the NEES average: 3.2–4.9)
    assert 3.0 < nees.mean() < 5.5, nees.mean()
    assert 1.6 < nis.mean() < 2.6, nis.mean()


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"particles": 0}, ValueError, "particles"),
        ({"particles": -5}, ValueError, "particles"),
        ({"particles": 10.5}, TypeError, "particles"),
        ({"particles": True}, TypeError, "particles"),
        ({"threshold": 0.0}, ValueError, "threshold"),
        ({"threshold": 1.5}, ValueError, "threshold"),
        ({"threshold": float("nan")}, ValueError, "threshold"),
        ({"threshold": "half"}, TypeError, "threshold"),
        ({"seed": -1}, ValueError, "seed"),
        ({"seed": 1.5}, TypeError, "seed"),
        ({"seed": "abc"}, TypeError, "seed"),
        ({"regularize": "yes"}, TypeError, "regularize"),
    ],
)
def test_bad_parameters_raise(kwargs, error, match):
    with pytest.raises(error, match=match):
        ParticleFilter(**kwargs)


def test_bad_state_and_transitions_raise():
    pf = ParticleFilter(particles=10)
    with pytest.raises(TypeError, match="state"):
        pf.predict(
            (np.zeros((1, 4)), np.eye(4)[None]), TransitionBank.stack([REGISTRY.create("motion_model", "straight").transition(1.0, X0)])
        )
    state = pf.initialize(X0[None], P0[None])
    assert isinstance(state, ParticleState) and state.particles.shape == (1, 10, 4)
    bank = TransitionBank.stack([REGISTRY.create("motion_model", "straight").transition(1.0, X0)] * 2)
    with pytest.raises(ValueError, match="transitions.F"):
        pf.predict(state, bank)


def test_in_a_pipeline_with_a_detector_the_scores_follow_the_kalman_filter():
    """The particle filter in a Pipeline (two modes, two sensors, a CUSUM detector) against the KF's scores.

    While its model is right (steps 0–20) the straight filter follows the KF: |ℓ − ℓ_KF| ≤ 0.035, mean within
    0.007.  A mismatched filter is where the bootstrap proposal fails: z lies far in the tail of the particle
    cloud, the weights collapse and ℓ falls below the KF's — the straight filter after the turn starts (KF NIS ≈ 5)
    by up to 3.0, the left-turn filter (turn centre fixed at the prior, KF NIS 20–60) to −1065 against −22 at the
    last step.  The ranking of the two filters (what the detectors use) agrees with the KF's wherever the KF's
    ℓ differ by more than 0.5 (36 of 41 steps).
    """
    from hybridtrack import Gaussian, Schedule
    from hybridtrack.engine.pipeline import Pipeline
    from hybridtrack.engine.simulate import simulate
    from hybridtrack_plugins.sensors.position import PositionSensor

    schedule = Schedule.from_rows([("straight", 20), ("left_turn", 20, 3.0)])
    sensors = [PositionSensor(name="a"), PositionSensor(name="b", components="x", noise_cov=[[0.04]])]
    _, z = simulate(schedule, np.array([0.0, 0.0, 0.0, 2.0]), 0.1, sensors, seed=3, noise_cov=np.diag([1e-3, 1e-3]))
    models = ["straight", ("left_turn", {"radius": 3.0, "noise_cov": np.diag([1e-3, 1e-3])})]
    prior = Gaussian(np.array([0.0, 0.0, 0.0, 2.0]), 0.01 * np.eye(4))
    kf, pf = (
        Pipeline(models=models, estimator=estimator, sensors=sensors, measurements=z, prior=prior, tau=0.1, detectors=["cusum"]).run()
        for estimator in ("kalman", ParticleFilter(particles=20_000, seed=0))
    )
    assert np.abs(pf.loglik[:21, 0] - kf.loglik[:21, 0]).max() < 0.1
    assert np.abs(pf.means[:21, 0] - kf.means[:21, 0]).max() < 0.02
    assert (pf.loglik[:, 1] <= kf.loglik[:, 1] + 0.1).all()  # the collapsed mismatched filter: ℓ below the KF's
    kf_order, pf_order = kf.loglik[:, 0] > kf.loglik[:, 1], pf.loglik[:, 0] > pf.loglik[:, 1]
    assert (pf_order == kf_order)[np.abs(kf.loglik[:, 0] - kf.loglik[:, 1]) > 0.5].all()
    assert np.isfinite(pf.loglik).all() and "cusum" in pf.statistics
