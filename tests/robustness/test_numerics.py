"""Silent numerics: inputs beyond the float64 arithmetic of a filter raise a ValueError naming them.

Every estimator, given a measurement, a prior mean or a prior covariance whose
squares or products overflow float64, raises a ValueError that names the
offending input (``z``, ``mean``, ``cov``) or the quantity that overflowed
(predicted covariance, innovation covariance, NIS) and says that the values
exceed the float64 arithmetic of the filter — never NaN/inf outputs, never a
numpy RuntimeWarning (warnings are errors in these tests).
"""

import warnings

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack.core.interfaces import LinearTransition, TransitionBank
from hybridtrack.sdk.scans import Scan
from hybridtrack_plugins.sensors.position import PositionSensor

ESTIMATORS = [
    "kalman",
    "information",
    "decentralized",
    "potter",
    "bierman",
    "srif",
    "srif_decentralized",
    "ekf",
    "ekf_sqrt",
    "ekf_ud",
    "nearest_neighbour",
    "pda",
]
LAYOUT = ("x", "vx", "y", "vy")
G = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
TOO_LARGE = "exceeds the float64 arithmetic of the filter"
OVERFLOWED = "the values exceed the float64 arithmetic of the filter"


def _straight(F_scale=1.0):
    F = np.kron(np.eye(2), np.array([[1.0, 0.1], [0.0, 1.0]])) * F_scale
    return TransitionBank.stack([LinearTransition(F, np.zeros(4), G, np.eye(2) * 1e-3)])


def _run(name, mean, cov, z, sensor=None, bank=None, steps=1):
    """initialize → (predict → update) × steps → predict, with every warning an error."""
    estimator = ht.load_plugins(strict=True).registry.create("estimator", name)
    sensor = sensor or PositionSensor(noise_cov=0.01 * np.eye(2))
    bank = bank or _straight()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        state = estimator.initialize(np.asarray(mean, dtype=float)[None], np.asarray(cov, dtype=float)[None])
        for _ in range(steps):
            state = estimator.predict(state, bank)
            state, innovation = estimator.update(state, z, [sensor], LAYOUT)
        state = estimator.predict(state, bank)
    return estimator, state, innovation


ZERO, EYE, Z_OK = np.zeros(4), np.eye(4), np.array([1.0, 0.5])

INPUTS = {
    "z=1e200": dict(mean=ZERO, cov=EYE, z=np.array([1e200, 0.0]), match=rf"^z: measurement value 1e\+200 at index \(0,\) {TOO_LARGE}"),
    "z=1e300": dict(mean=ZERO, cov=EYE, z=np.array([0.0, 1e300]), match=rf"^z: measurement value 1e\+300 at index \(1,\) {TOO_LARGE}"),
    "z=-1e200 per filter row": dict(
        mean=ZERO, cov=EYE, z=np.array([[-1e200, 0.0]]), match=rf"^z: measurement value -1e\+200 {''}at index \(0, 0\) {TOO_LARGE}"
    ),
    "mean=1e200": dict(
        mean=np.array([1e200, 0.0, 0.0, 0.0]), cov=EYE, z=Z_OK, match=rf"^mean: prior mean value 1e\+200 at index \(0, 0\) {TOO_LARGE}"
    ),
    "cov=1e200 I": dict(
        mean=ZERO, cov=1e200 * EYE, z=Z_OK, match=rf"^cov: prior covariance value 1e\+200 at index \(0, 0, 0\) {TOO_LARGE}"
    ),
    "cov=1e-200 I": dict(
        mean=ZERO,
        cov=1e-200 * EYE,
        z=Z_OK,
        match=r"^cov: prior variance 1e-200 at index \(0, 0, 0\) is too small for the float64 arithmetic",
    ),
}


@pytest.mark.parametrize("case", list(INPUTS))
@pytest.mark.parametrize("name", ESTIMATORS)
def test_inputs_beyond_float64_arithmetic_raise_naming_the_input(name, case):
    spec = INPUTS[case]
    with pytest.raises(ValueError, match=spec["match"]):
        _run(name, spec["mean"], spec["cov"], spec["z"])


@pytest.mark.parametrize("name", ESTIMATORS)
def test_an_overflowing_nis_raises_naming_it(name):
    """z = 1e150 is accepted, but with R = 1e-12 and a tight prior ν²/S overflows: the NIS (or d², node NIS) is named."""
    sensor = PositionSensor(noise_cov=1e-12 * np.eye(2))
    with pytest.raises(
        ValueError,
        match=rf"^(innovation|update): the (NIS νᵀS⁻¹ν|node NIS|squared distances d2) of '{name}' has value (inf|nan) .*{OVERFLOWED}",
    ):
        _run(name, ZERO, 1e-12 * EYE, np.array([1e150, 0.0]), sensor=sensor)


@pytest.mark.parametrize("name", ESTIMATORS)
def test_an_overflowing_predicted_covariance_raises_naming_it(name):
    """F = 1e100 (…) on P = 1e120 I: F P Fᵀ overflows — in the predicted covariance (or its factors), or, for the
    square-root forms that never form P, in the innovation covariance of the next update."""
    with pytest.raises(
        ValueError,
        match=rf"^(predict|update): the (predicted covariance|predicted variances d|predicted covariance factor U|innovation covariance) of '{name}' has value (inf|nan) .*{OVERFLOWED}",
    ):
        _run(name, ZERO, 1e120 * EYE, Z_OK, bank=_straight(1e100))


@pytest.mark.parametrize("name", ["nearest_neighbour", "pda"])
def test_a_scan_candidate_beyond_float64_arithmetic_raises_naming_the_scan(name):
    with pytest.raises(ValueError, match=rf"^z: measurement \(scan of sensor 'position'\) value 1e\+200 at index \(1, 0\) {TOO_LARGE}"):
        _run(name, ZERO, EYE, Scan("position", np.array([[1.0, 0.5], [1e200, 0.0]])))


@pytest.mark.parametrize("name", ESTIMATORS)
def test_large_but_processable_inputs_run_without_warnings(name):
    """The limits are not too tight: UTM-scale coordinates with a diffuse prior stay finite and quiet."""
    estimator, state, innovation = _run(name, np.array([5e6, 1.0, 5e6, 2.0]), 1e6 * EYE, np.array([5e6 + 0.1, 5e6 - 0.1]), steps=3)
    assert np.isfinite(estimator.mean(state)).all()
    assert np.isfinite(innovation.nis).all() and np.isfinite(innovation.loglik).all()
