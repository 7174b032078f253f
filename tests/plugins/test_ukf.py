"""The unscented Kalman filter bank (plugins/filters/ukf.py): exact on linear motion (the covariance KF), its
sigma-point moments against Monte Carlo through the coordinated turn (closer than the EKF's linearization), and
tracking a turn with the turn rate in the state."""

import numpy as np
import pytest

from hybridtrack.algorithms.multiple_model import MultipleModelEstimator
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import resolve
from hybridtrack_plugins.filters.ukf import UnscentedKalmanFilter
from hybridtrack_plugins.motion.linear_modes import Straight
from hybridtrack_plugins.motion.real_motion import CoordinatedTurn

LAYOUT = ("x", "vx", "y", "vy")


def test_linear_motion_equals_the_kalman_filter():
    """A linear f through the linearizing callable: the unscented transform is exact, so the UKF is the KF."""
    rng = np.random.default_rng(1)
    T = Straight(noise_density=0.3).transition(2.0)
    bank = TransitionBank.stack([T] * 3)
    ukf, kf = resolve("estimator", ("ukf", {})), resolve("estimator", ("kalman", {}))
    sensor = resolve("sensor", ("position", {"noise_cov": 4.0 * np.eye(2)}))
    A = rng.standard_normal((3, 4, 4))
    P0 = A @ np.swapaxes(A, 1, 2) + np.eye(4)
    x0 = rng.standard_normal((3, 4)) * [100.0, 10.0, 100.0, 10.0] + [3e5, 0.0, 6e6, 0.0]  # map-grid positions
    su, sk = ukf.initialize(x0, P0), kf.initialize(x0, P0)
    for z in rng.standard_normal((10, 2)) * 10.0 + [3e5, 6e6]:
        su, sk = ukf.predict(su, lambda x: bank), kf.predict(sk, bank)
        np.testing.assert_allclose(ukf.mean(su), kf.mean(sk), rtol=1e-12, atol=1e-8)  # f(χ) at 6·10⁶ m: ulp 10⁻⁹
        P = kf.covariance(sk)  # the deviations f(χ) − x⁻ of points at 6·10⁶ m: rounding of 10⁻⁹ m against P's metres
        np.testing.assert_allclose(ukf.covariance(su), P, rtol=1e-8, atol=1e-8 * np.abs(P).max())
        (su, iu), (sk, ik) = ukf.update(su, z, [sensor], LAYOUT), kf.update(sk, z, [sensor], LAYOUT)
        np.testing.assert_allclose(iu.loglik, ik.loglik, rtol=1e-8)


def test_sigma_point_moments_are_closer_to_monte_carlo_than_the_ekf():
    """A turn-rate estimate with σ_ω = 0.05 rad/s over 20 s (aT up to ±2 rad): the mean and covariance of f(x),
    x ~ N(x̂, P), from 400,000 draws, against the UKF's and the EKF's predictions (no process noise)."""
    model = CoordinatedTurn(noise_density=0.0, rate_density=0.0, max_rate=1.0)
    x = np.array([[0.0, 10.0, 0.0, 0.0, 0.02]])
    P = np.diag([25.0, 1.0, 25.0, 1.0, 0.05**2])[None]
    draws = np.random.default_rng(2).multivariate_normal(x[0], P[0], 400_000)
    images = model.propagate(draws, 20.0)
    mc_mean, mc_cov = images.mean(axis=0), np.cov(images, rowvar=False)
    errors = {}
    for name in ("ukf", "ekf"):
        est = resolve("estimator", (name, {}))
        state = est.predict(est.initialize(x, P), model.linearizer(20.0))
        errors[name] = (
            np.linalg.norm(est.mean(state)[0, [0, 2]] - mc_mean[[0, 2]]),
            np.linalg.norm(est.covariance(state)[0, :4, :4] - mc_cov[:4, :4]),
        )
    assert errors["ukf"][0] < 0.2 * errors["ekf"][0] and errors["ukf"][1] < errors["ekf"][1], errors


def test_ukf_tracks_a_turn_with_the_turn_rate_in_the_state():
    rng = np.random.default_rng(5)
    model = CoordinatedTurn(noise_density=1e-4, rate_density=1e-8, max_rate=0.1)
    truth = np.array([2.0e5, 8.0, 5.5e6, 0.0, 0.01])
    ukf = resolve("estimator", ("ukf", {}))
    sensor = resolve("sensor", ("position", {"noise_cov": 100.0 * np.eye(2)}))
    z0 = truth[[0, 2]] + 10.0 * rng.standard_normal(2)
    state = ukf.initialize(np.array([[z0[0], 8.0, z0[1], 0.0, 0.0]]), np.diag([100.0, 4.0, 100.0, 4.0, 0.02**2])[None])
    for _ in range(30):
        truth = model.propagate(truth, 10.0)
        state = ukf.predict(state, model.linearizer(10.0))
        state, _ = ukf.update(state, truth[[0, 2]] + 10.0 * rng.standard_normal(2), [sensor], model.layout)
    omega, var = ukf.mean(state)[0, 4], ukf.covariance(state)[0, 4, 4]
    assert abs(omega - 0.01) < 3 * np.sqrt(var) and abs(omega - 0.01) < 2e-3, (omega, np.sqrt(var))


@pytest.mark.parametrize(
    ("kwargs", "match"), [({"alpha": 0.0}, "alpha"), ({"beta": float("nan")}, "beta"), ({"kappa": float("inf")}, "kappa")]
)
def test_bad_parameters_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        resolve("estimator", ("ukf", kwargs))


def _leg(seed: int, straight: int, turn: int = 40):
    """North at 10 m/s for ``straight`` fixes 2 s apart, then a left turn of 200 m; σ = 5 m: (t, truth, z)."""
    rng = np.random.default_rng(seed)
    t = np.arange(straight + turn + 1) * 2.0
    pos = np.zeros((t.size, 2))
    pos[: straight + 1, 1] = 10.0 * t[: straight + 1]
    angle = 10.0 / 200.0 * (t[straight:] - t[straight])
    pos[straight:] = pos[straight] + np.array([-200.0, 0.0]) + 200.0 * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return t, pos, pos + rng.normal(0.0, 5.0, pos.shape)


def _turn_rate_imm(estimator: str, t, z):
    """The run of an IMM of straight and the coordinated turn with ``estimator`` inside on the fixes z (σ = 5 m)."""
    sensor = resolve("sensor", ("position", {"name": "p", "noise_cov": 25.0 * np.eye(2)}))
    imm = MultipleModelEstimator(
        models=[("straight", {"noise_density": 0.01}), ("coordinated_turn", {"noise_density": 0.01})],
        sensors=[sensor],
        sojourn=60.0,
        estimator=estimator,
        missing_variance={"omega": 1e-3},
    )
    return imm.run({"p": z}, (np.array([z[0, 0], 0.0, z[0, 1], 10.0, 0.0]), np.diag([25.0, 4.0, 25.0, 4.0, 1e-3])), times=t)


def test_in_the_multiple_model_bank_the_ukf_takes_its_sigma_points(monkeypatch):
    """An IMM of straight and the coordinated turn with the UKF inside: the engine's bank hands the UKF the
    linearizing callable (called at 2n + 1 points per step, not once at the means as for the EKF), and both
    follow the turn rate of a 200 m turn at 10 m/s."""
    t, pos, z = _leg(4, 40)
    calls = []
    original = UnscentedKalmanFilter._sigma_point_predict
    monkeypatch.setattr(UnscentedKalmanFilter, "_sigma_point_predict", lambda self, s, tr: calls.append(1) or original(self, s, tr))
    omegas = {}
    for name in ("ukf", "ekf"):
        run = _turn_rate_imm(name, t, z)
        omegas[name] = np.median(run.model_means[55:, 1, 4])
        assert np.mean(run.mode[50:] == 1) > 0.8, name
    assert len(calls) >= 80  # one sigma-point prediction per step (the coordinated turn's group)
    assert omegas["ukf"] == pytest.approx(0.05, rel=0.1) and omegas["ekf"] == pytest.approx(0.05, rel=0.1), omegas
    assert omegas["ukf"] != omegas["ekf"]


@pytest.mark.parametrize("name", ["particle", "gaussian_sum"])
def test_the_bank_hands_points_per_filter_to_the_other_nonlinear_estimators(name):
    """The engine's linearizing callable takes k points per filter (a particle filter's particles, filter-major)
    as well as one (a Gaussian sum's component means): an IMM of straight and the coordinated turn runs with
    either estimator inside and follows the turn."""
    t, pos, z = _leg(8, 20)
    run = _turn_rate_imm(name, t, z)
    assert np.all(np.isfinite(run.means)) and np.mean(run.mode[35:] == 1) > 0.7, run.mode
    assert np.sqrt(np.mean(np.sum((run.means[:, [0, 2]] - pos) ** 2, axis=1))) < 10.0
