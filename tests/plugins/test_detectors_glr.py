"""GLR with a sliding window, CUSUM, empirical-CDF normalization, H0 thresholds and the dynamic-threshold wrapper (seed 003)."""

import numpy as np
import pytest
from scipy.stats import binom, norm

from hybridtrack_plugins.detectors import null_calibration
from hybridtrack_plugins.detectors.cusum import CUSUM
from hybridtrack_plugins.detectors.dynamic_threshold import DynamicThreshold, SpeedDropCue
from hybridtrack_plugins.detectors.glr import GLR


def test_glr_statistic_against_brute_force():
    y = np.random.default_rng(1).standard_normal(30)
    d = GLR(window=5, normalize=False, alpha=0.01)
    values = [d.update_statistic(v) for v in y]
    for n in range(30):
        brute = max((y[k : n + 1].sum() ** 2) / (2 * (n - k + 1)) for k in range(max(0, n - 4), n + 1))
        assert values[n] == pytest.approx(brute)
    np.testing.assert_allclose(null_calibration.glr_statistics(y[None], 5)[0], values)


def test_cusum_recursion_by_hand():
    d = CUSUM(drift=0.5, normalize=False, alpha=0.01)
    assert [d.update_statistic(v) for v in (1.0, 1.0, -3.0)] == pytest.approx([0.5, 1.0, 2.5])
    np.testing.assert_allclose(null_calibration.cusum_statistics(np.array([[1.0, 1.0, -3.0]]), 0.5)[0], [0.5, 1.0, 2.5])


def test_empirical_normalizer_maps_the_reference_distribution_to_n01():
    rng = np.random.default_rng(2)
    normalize = null_calibration.EmpiricalNormalizer(rng.exponential(2.0, 20000))
    y = normalize(rng.exponential(2.0, 20000))
    assert abs(y.mean()) < 0.03 and y.std() == pytest.approx(1.0, abs=0.03)
    assert np.isfinite(normalize(np.array([-1.0, 1e9]))).all()


@pytest.mark.parametrize(
    "make", [lambda: GLR(window=10, alpha=0.01, normalize=False), lambda: CUSUM(drift=0.5, alpha=0.01, normalize=False)]
)
def test_per_step_false_alarm_rate_under_h0_is_alpha(make):
    """Fresh seeded N(0,1) data (not the threshold's simulation): exceedances at steps spaced 50 apart ~ Binomial(n, α)."""
    y = np.random.default_rng(99).standard_normal((2000, 160))
    detector = make()
    g = (
        null_calibration.glr_statistics(y, detector.window)
        if isinstance(detector, GLR)
        else null_calibration.cusum_statistics(y, detector.drift)
    )
    hits = int((g[:, [59, 109, 159]] > detector.threshold).sum())
    n = 2000 * 3
    assert binom.ppf(0.0005, n, 0.01) <= hits <= binom.ppf(0.9995, n, 0.01)


def test_thresholds_are_cached_and_seeded():
    a, b = GLR(window=7, alpha=0.01), GLR(window=7, alpha=0.001)
    assert a.h0_sample() is b.h0_sample() and a.threshold < b.threshold
    assert GLR(window=7, alpha=0.01, seed=3).threshold != a.threshold


def test_glr_on_the_nis_detects_a_mean_shift():
    rng = np.random.default_rng(4)
    d = GLR(window=10, alpha=0.001)
    steps = [d.observe(k, np.zeros(1), np.array([rng.chisquare(2) * (1 if k < 40 else 4)]), 2) for k in range(80)]
    fired = [s.decision.step for s in steps if s.decision is not None]
    assert fired and fired[0] >= 40


def test_speed_drop_cue_uses_the_mean_speed_30_to_60_steps_back():
    cue = SpeedDropCue(drop=0.1)
    held = [cue.update(k, 10.0) for k in range(61)]
    assert not any(held)
    assert cue.update(61, 8.9) and not cue.update(62, 9.5)


def test_dynamic_threshold_lowers_the_threshold_while_the_cue_holds_and_detects_sooner():
    shift = np.concatenate([np.zeros(100), np.full(40, 1.0)])
    noise = np.random.default_rng(8).standard_normal(140)
    speeds = np.concatenate([np.full(105, 10.0), np.full(35, 8.0)])  # the speed drops in the turn
    delays = {}
    for L_C in (1.0, 20.0):
        wrapper = DynamicThreshold(("glr", {"window": 10, "alpha": 0.0005, "normalize": False}), ("speed_drop", {"drop": 0.05}), L_C)
        first = None
        for k in range(140):
            wrapper.feed_cue(k, speeds[k])
            out = wrapper.observe_value(k, shift[k] + noise[k])
            # the static threshold λ(α) is reported beside the current one (recorded as static vs dynamic)
            assert out.thresholds["static_threshold"] == pytest.approx(wrapper.detector.threshold_for(0.0005))
            if k == 120:
                assert out.statistics["cue"] == 1.0
                assert out.thresholds["threshold"] == pytest.approx(wrapper.detector.threshold_for(0.0005 * L_C))
                assert L_C == 1.0 or out.thresholds["threshold"] < out.thresholds["static_threshold"]
            if out.decision is not None and k >= 100 and first is None:
                first = k
        delays[L_C] = first
    assert delays[20.0] is not None and delays[1.0] is not None and delays[20.0] <= delays[1.0]
    assert norm.isf(0.0005) > 0


def _ar1(rng, shape, rho=0.9):
    """Stationary AR(1) with N(0, 1) marginals: y_n = ρ y_{n−1} + √(1 − ρ²) e_n."""
    y = np.empty(shape)
    y[:, 0] = rng.standard_normal(shape[0])
    for n in range(1, shape[1]):
        y[:, n] = rho * y[:, n - 1] + np.sqrt(1 - rho * rho) * rng.standard_normal(shape[0])
    return y


def test_null_sample_calibrates_the_threshold_on_an_autocorrelated_signal():
    """N(0,1) marginals but autocorrelated (as a filtered estimate): λ(α) from independent input gives far more
    than α false alarms per step; λ(α) from a null sample of g on the same kind of signal gives α."""
    rng = np.random.default_rng(5)
    null = null_calibration.glr_statistics(_ar1(rng, (1000, 300)), 10)[:, 50:]
    calibrated = GLR(window=10, alpha=0.01, normalize=False, null_sample=null)
    independent = GLR(window=10, alpha=0.01, normalize=False)
    assert calibrated.threshold_sample().size == null.size and calibrated.threshold > 2 * independent.threshold
    assert calibrated.threshold == pytest.approx(np.quantile(null, 0.99))
    fresh = null_calibration.glr_statistics(_ar1(np.random.default_rng(6), (3000, 160)), 10)[:, [59, 109, 159]]  # 50 steps apart
    n = fresh.size
    hits = int((fresh > calibrated.threshold).sum())
    assert binom.ppf(0.0005, n, 0.01) <= hits <= binom.ppf(0.9995, n, 0.01)
    assert (fresh > independent.threshold).mean() > 0.05
    wrapper = DynamicThreshold(("glr", {"window": 10, "alpha": 0.01, "normalize": False, "null_sample": null}), "speed_drop", 3.0)
    assert wrapper.detector.threshold_for(0.03) == pytest.approx(np.quantile(null, 0.97))
    with pytest.raises(ValueError, match="null_sample"):
        GLR(window=10, null_sample=[1.0, np.nan] * 10)
