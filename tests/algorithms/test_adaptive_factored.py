"""Inside the adaptive estimators a bank keeps its estimator's own form from step to step.

Square-root filters (Potter, Bierman, SRIF) propagate their factors: the
estimator's ``initialize`` runs once per bank created from an estimate (never
per step), growth copies a filter's factors (``take``), and the estimates
equal the covariance KF's.  The ill-conditioned case of docs/estimators.md
(R = 1e-12·I, P0 = 1e12·I) run inside an adaptive estimator stays positive
definite with the factored forms.
"""

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule, get_registry
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.engine.simulate import simulate
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = 0.01 * np.eye(2)
MODES = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
FACTORED = ["potter", "bierman", "srif"]


def counted(name: str):
    """The registered estimator ``name`` with a count of its ``initialize`` calls."""
    estimator = get_registry().create("estimator", name)
    calls = []
    original = estimator.initialize

    def initialize(mean, cov):
        calls.append(np.shape(mean)[0])
        return original(mean, cov)

    estimator.initialize = initialize
    return estimator, calls


def _example(seed=3):
    sensors = [PositionSensor(noise_cov=NOISE)]
    schedule = Schedule.from_rows([("straight", 15), ("right_turn", 20, 5.0), ("straight", 10)])
    truth, z = simulate(schedule, X0, 0.1, sensors, seed=seed, noise_cov=NOISE)
    return schedule, sensors, z


def _close(a, b):
    scale = max(1.0, float(np.abs(b).max()))
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize("name", FACTORED)
def test_known_switch_propagates_factors_and_equals_the_kalman_filter(name):
    schedule, sensors, z = _example()
    estimator, calls = counted(name)
    kwargs = dict(
        sensors=sensors, tau=0.1, r_min=3.0, r_max=5.0, n=2, follow="most_likely", switch_estimate="filtered", switch_inflation=1.0
    )
    run = KnownSwitchAdaptive(estimator=estimator, **kwargs).run(z, Gaussian(X0, np.eye(4)), schedule)
    reference = KnownSwitchAdaptive(estimator="kalman", **kwargs).run(z, Gaussian(X0, np.eye(4)), schedule)
    assert calls == [5]  # one bank created from the prior; every later segment's bank copies the followed filter's factors
    _close(run.means, reference.means)
    _close(run.covs, reference.covs)
    np.testing.assert_array_equal(run.mode, reference.mode)
    assert [d.step for d in run.decisions] == [d.step for d in reference.decisions]


@pytest.mark.parametrize("name", FACTORED)
def test_unknown_change_grows_by_copying_factors_and_equals_the_kalman_filter(name):
    _, sensors, z = _example()
    estimator, calls = counted(name)
    kwargs = dict(modes=MODES, sensors=sensors, tau=0.1, alpha=0.05, beta=0.05, bank_size=6)
    run = UnknownChangeAdaptive(estimator=estimator, **kwargs).run(z, Gaussian(X0, np.eye(4)))
    reference = UnknownChangeAdaptive(estimator="kalman", **kwargs).run(z, Gaussian(X0, np.eye(4)))
    assert calls == [1]  # the bank grows every step by copies of filter 0 (take), not by re-initialization
    assert run.bank_sizes.max() > 1
    _close(run.means, reference.means)
    _close(run.covs, reference.covs)
    np.testing.assert_array_equal(run.mode, reference.mode)
    np.testing.assert_array_equal(run.bank_sizes, reference.bank_sizes)


@pytest.mark.parametrize("name", FACTORED)
def test_the_joint_switch_estimate_equals_the_kalman_filter(name):
    schedule, sensors, z = _example()
    kwargs = dict(sensors=sensors, tau=0.1, r_min=3.0, r_max=5.0, n=2)  # defaults: mixture, joint switch state
    run = KnownSwitchAdaptive(estimator=name, **kwargs).run(z, Gaussian(X0, np.eye(4)), schedule)
    reference = KnownSwitchAdaptive(estimator="kalman", **kwargs).run(z, Gaussian(X0, np.eye(4)), schedule)
    _close(run.means, reference.means)
    _close(run.covs, reference.covs)
    assert [d.step for d in run.decisions] == [d.step for d in reference.decisions]


@pytest.mark.parametrize("name", FACTORED)
def test_the_ill_conditioned_case_inside_an_adaptive_estimator_stays_positive_definite(name):
    sensors = [PositionSensor(noise_cov=1e-12 * np.eye(2))]
    schedule = Schedule.from_rows([("straight", 50), ("right_turn", 50, 5.0)])
    _, z = simulate(schedule, np.array([0.0, 1.0, 0.0, 1.0]), 1.0, sensors, seed=0, noise_cov=1e-6 * np.eye(2))
    adaptive = KnownSwitchAdaptive(
        estimator=name, sensors=sensors, tau=1.0, modes=["straight", ("right_turn", {"radius": 5.0, "noise_cov": 1e-6 * np.eye(2)})]
    )
    run = adaptive.run(z, Gaussian(np.zeros(4), 1e12 * np.eye(4)), schedule)
    assert np.isfinite(run.covs).all()
    np.linalg.cholesky(run.covs[1:])  # every step's covariance positive definite
