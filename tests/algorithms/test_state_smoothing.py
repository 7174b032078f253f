"""The RTS smoother (hybridtrack.algorithms.state_smoothing) against FilterPy's, and the multiple-model pass."""

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter, rts_smoother

from hybridtrack.algorithms.state_smoothing import rts_smooth, smooth_models
from hybridtrack.core.plugins import resolve


def filtered_cv_run(seed=3, steps=40):
    """A constant-velocity Kalman filter (FilterPy) over irregular reports: its posteriors and the F, Q per step."""
    rng = np.random.default_rng(seed)
    model = resolve("motion_model", ("straight", {"noise_density": 0.05}))
    times = np.cumsum(np.r_[0.0, rng.uniform(0.5, 12.0, steps - 1)])
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P = np.array([0.0, 5.0, 0.0, 1.0]), np.diag([100.0, 4.0, 100.0, 4.0])
    kf.H, kf.R = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]), 25.0 * np.eye(2)
    truth = np.array([5.0, 1.0]) * times[:, None] + np.cumsum(rng.normal(0, 2.0, (steps, 2)), axis=0)
    means, covs, Fs, Qs = [], [], [], []
    for k, t in enumerate(times):
        if k:
            transition = model.transition(t - times[k - 1], kf.x)
            kf.F, kf.Q = transition.F, transition.process_noise
            kf.predict()
        kf.update(truth[k] + rng.normal(0, 5.0, 2))
        means.append(kf.x.copy())
        covs.append(kf.P.copy())
    for k in range(steps):  # FilterPy's rts_smoother takes F_{k+1}, Q_{k+1} at index k
        transition = model.transition(times[min(k + 1, steps - 1)] - times[k] if k + 1 < steps else 1.0, means[k])
        Fs.append(transition.F)
        Qs.append(transition.process_noise)
    return model, times, np.array(means), np.array(covs), Fs, Qs


def test_rts_equals_filterpy_on_irregular_reports():
    model, times, means, covs, Fs, Qs = filtered_cv_run()
    expected, expected_covs, _, _ = rts_smoother(means, covs, Fs, Qs)
    smoothed, smoothed_covs = rts_smooth(means, covs, times, model)
    np.testing.assert_allclose(smoothed, expected, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(smoothed_covs, expected_covs, rtol=1e-10, atol=1e-9)
    np.testing.assert_array_equal(smoothed[-1], means[-1])
    assert np.all(np.trace(smoothed_covs, axis1=1, axis2=2) <= np.trace(covs, axis1=1, axis2=2) + 1e-9)


def test_a_model_of_no_probability_carries_no_error_back():
    """Two identical models, one of probability e⁻⁸⁰⁰ (filtered and smoothed) with filtered means 10 km off: the
    backward mixing gives it no weight in the other's target, so the combined smoothed estimate equals the single
    model's RTS."""
    model, times, means, covs, _, _ = filtered_cv_run()
    model_means = np.stack([means, means + [1e4, 0.0, 1e4, 0.0]], axis=1)
    model_covs = np.stack([covs, covs], axis=1)
    log_mu = np.tile([0.0, -800.0], (len(times), 1))
    log_transitions = np.tile(np.log([[0.99, 0.01], [0.01, 0.99]]), (len(times), 1, 1))
    _, _, combined, combined_covs = smooth_models(
        model_means, model_covs, log_mu, log_mu, log_transitions, times, [model, model], model.layout
    )
    expected, expected_covs = rts_smooth(means, covs, times, model)
    np.testing.assert_allclose(combined, expected, atol=1e-9)
    np.testing.assert_allclose(combined_covs, expected_covs, atol=1e-9)


def test_the_smoothed_imm_beats_the_filtered_one_on_a_turn():
    """Straight, a 90° coordinated turn of 0.02 rad/s, straight; positions with σ = 10 m: the
    smoothed IMM (straight + coordinated turn) has the smaller position error and turn-rate error."""
    from hybridtrack.algorithms.multiple_model import MultipleModelEstimator

    rng = np.random.default_rng(7)
    dt, omega = 5.0, 0.02
    speed, heading, p = 6.0, 0.0, np.zeros(2)
    truth, rates = [], []
    for k in range(150):
        w = omega if 40 <= k < 40 + int(np.pi / 2 / omega / dt) else 0.0
        heading += w * dt
        p = p + speed * dt * np.array([np.cos(heading), np.sin(heading)])
        truth.append([p[0], speed * np.cos(heading), p[1], speed * np.sin(heading), w])
        rates.append(w)
    truth = np.array(truth)
    z = truth[:, [0, 2]] + 10.0 * rng.standard_normal((150, 2))
    imm = MultipleModelEstimator(
        [("straight", {"noise_density": 0.001}), ("coordinated_turn", {"noise_density": 0.001})],
        sensors=[resolve("sensor", ("position", {"noise_cov": 100.0 * np.eye(2)}))],
        estimator="ekf",
        sojourn=120.0,
        missing_variance={"omega": 1e-4},
    )
    x0 = truth[0].copy()
    run = imm.run({"position": z}, (x0, np.diag([100.0, 1.0, 100.0, 1.0, 1e-4])), times=dt * np.arange(150))
    smoothed = imm.smooth(run)
    error = {
        name: np.sqrt(np.mean(np.sum((r.means[:, [0, 2]] - truth[:, [0, 2]]) ** 2, axis=1)))
        for name, r in (("filtered", run), ("smoothed", smoothed))
    }
    assert error["smoothed"] < 0.8 * error["filtered"], error
    # the turn rate (of the turn model) over the run: the filtered one lags the turn's start and end, the smoothed not
    omega_error = {name: np.mean(np.abs(r.model_means[:, 1, 4] - truth[:, 4])) for name, r in (("filtered", run), ("smoothed", smoothed))}
    assert omega_error["smoothed"] < omega_error["filtered"], omega_error


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda m, t, x, P: rts_smooth(x, P[:-1], t, m), "expected shapes"),
        (lambda m, t, x, P: rts_smooth(x, P, t[::-1], m), "strictly increasing"),
        (lambda m, t, x, P: rts_smooth(x[:, :2], P[:, :2, :2], t, m), r"expected shapes \(5, 4\)"),
    ],
)
def test_bad_inputs_name_what_is_wrong(call, message):
    model, times, means, covs, _, _ = filtered_cv_run(steps=5)
    with pytest.raises(ValueError, match=message):
        call(model, times, means, covs)


def test_a_step_outside_the_gate_keeps_its_filtered_estimate():
    """A nearly noise-free straight model (σ 10 m filtered) whose next smoothed state lies 10 km aside: the backward
    step would move the estimate 10 km, far outside the χ² gate of the filtered covariance, so the filtered estimate
    stays; 10 m aside it moves (inside the gate)."""
    model = resolve("motion_model", ("straight", {"noise_density": 1e-9}))
    x0, P0 = np.array([0.0, 5.0, 0.0, 0.0]), np.diag([100.0, 1.0, 100.0, 1.0])
    for offset, kept in ((1e4, True), (10.0, False)):
        x1 = np.array([50.0, 5.0, offset, 0.0])
        smoothed, _ = rts_smooth(np.stack([x0, x1]), np.stack([P0, P0]), np.array([0.0, 10.0]), model)
        assert np.array_equal(smoothed[0], x0) == kept, (offset, smoothed[0])
