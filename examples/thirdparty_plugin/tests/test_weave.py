"""Tests of the weave mode, including hybridtrack's contract checks (fixture from hybridtrack's pytest plugin)."""

import numpy as np
import pytest

from hybridtrack_zigzag import Weave


@pytest.mark.parametrize("noise_cov", [None, np.diag([0.1, 0.1])])
def test_weave_honours_the_motion_model_contract(hybridtrack_contracts, noise_cov):
    hybridtrack_contracts.check_motion_model(Weave(amplitude=0.4, period=15.0, noise_cov=noise_cov))


def test_weave_is_registered(hybridtrack_registry):
    assert hybridtrack_registry.get("motion_model", "weave") is Weave


def test_noise_free_weave_keeps_speed_and_swings_the_heading():
    model, tau = Weave(amplitude=0.5, period=20.0), 0.5
    x = np.array([0.0, 10.0, 0.0, 0.0, 0.0])  # heading east, phase 0
    headings, speeds = [], []
    for _ in range(80):  # two periods
        x = model.propagate(x, tau, x)
        headings.append(np.arctan2(x[3], x[1]))
        speeds.append(np.hypot(x[1], x[3]))
    np.testing.assert_allclose(speeds, 10.0, rtol=1e-12)
    assert max(headings) == pytest.approx(0.5, abs=1e-3) and min(headings) == pytest.approx(-0.5, abs=1e-3)
    assert headings[39] == pytest.approx(0.0, abs=1e-9)  # back to the mean course after a period
    np.testing.assert_allclose(x[4], 2 * np.pi * 2)


def test_bad_parameters_are_rejected():
    with pytest.raises(ValueError, match="period"):
        Weave(period=0.0)
    with pytest.raises(ValueError, match="noise_cov"):
        Weave(noise_cov=np.eye(4))
