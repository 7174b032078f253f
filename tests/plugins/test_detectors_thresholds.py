"""Thresholds and parameter checks shared by the detectors (SPEC §4; seed 001 §3)."""

import math

import numpy as np
import pytest

from hybridtrack.sdk.thresholds import THREE_SIGMA_ALPHA, sprt_thresholds, two_sided_normal_bound
from hybridtrack_plugins.detectors.cusum import CUSUM
from hybridtrack_plugins.detectors.dynamic_threshold import DynamicThreshold, SpeedDropCue
from hybridtrack_plugins.detectors.glr import GLR
from hybridtrack_plugins.detectors.signal_function import SignalFunction
from hybridtrack_plugins.detectors.sprt_change import ChangeTimeSPRT
from hybridtrack_plugins.detectors.sprt_pairwise import PairwiseSPRT


def test_wald_thresholds_by_hand():
    upper, lower = sprt_thresholds(0.05, 0.1)
    assert upper == pytest.approx(math.log(0.9 / 0.05))
    assert lower == pytest.approx(math.log(0.1 / 0.95))
    assert upper > 0 > lower


def test_three_sigma_rule_is_alpha_0027():
    assert THREE_SIGMA_ALPHA == pytest.approx(0.0026998, rel=1e-4)
    assert two_sided_normal_bound(THREE_SIGMA_ALPHA) == pytest.approx(3.0)


@pytest.mark.parametrize("factory", [PairwiseSPRT, ChangeTimeSPRT])
@pytest.mark.parametrize(
    "alpha, beta, message",
    [
        (0.0, 0.1, "alpha"),
        (1.0, 0.1, "alpha"),
        (-0.1, 0.1, "alpha"),
        (0.1, 0.0, "beta"),
        (0.1, 1.5, "beta"),
        (0.6, 0.4, "alpha \\+ beta"),
        (0.7, 0.5, "alpha \\+ beta"),
        ("x", 0.1, "alpha"),
    ],
)
def test_bad_error_probabilities_are_named(factory, alpha, beta, message):
    with pytest.raises(ValueError, match=message):
        factory(alpha=alpha, beta=beta)


def test_setting_alpha_moves_the_thresholds_and_is_checked():
    d = PairwiseSPRT(alpha=0.05, beta=0.05)
    d.alpha = 0.01
    assert d.upper == pytest.approx(math.log(0.95 / 0.01)) and d.lower == pytest.approx(math.log(0.05 / 0.99))
    with pytest.raises(ValueError, match="alpha \\+ beta"):
        d.alpha = 0.97


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: SignalFunction(window=0), "window"),
        (lambda: SignalFunction(alpha=1.5), "alpha"),
        (lambda: SignalFunction(calibration="t"), "calibration"),
        (lambda: ChangeTimeSPRT(pruning="random"), "pruning"),
        (lambda: ChangeTimeSPRT(bank_size=0), "bank_size"),
        (lambda: ChangeTimeSPRT(hypotheses=["only"]), "hypotheses"),
        (lambda: GLR(window=0), "window"),
        (lambda: GLR(alpha=1e-7), "alpha"),
        (lambda: CUSUM(drift=-1.0), "drift"),
        (lambda: SpeedDropCue(drop=1.2), "drop"),
        (lambda: SpeedDropCue(lags=(30, 60)), "lags"),
        (lambda: DynamicThreshold(likelihood_ratio=2000.0), "likelihood_ratio"),
        (lambda: DynamicThreshold(cue="heel"), "cue"),
    ],
)
def test_bad_parameters_are_named(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_pairwise_rejects_a_bank_that_changes_size():
    d = PairwiseSPRT()
    d.observe(0, np.zeros(3), np.zeros(3), 2)
    with pytest.raises(ValueError, match="reset"):
        d.observe(1, np.zeros(4), np.zeros(4), 2)
