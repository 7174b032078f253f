"""The contract checks themselves: they pass correct toy components and catch each kind of violation."""

import numpy as np
import pytest

from hybridtrack.core.algorithm import Algorithm
from hybridtrack.core.interfaces import Detector, DetectorStep, Estimator, MotionModel, Solution, Solver
from hybridtrack.core.types import Decision
from hybridtrack.core.validation import check_prior
from hybridtrack.sdk import kalman_reference
from hybridtrack.testing import (
    LinearPositionSensor,
    build_example,
    check_algorithm,
    check_component,
    check_detector,
    check_estimator,
    check_motion_model,
    check_sensor,
    check_solver,
    cv_transition,
    example_parameters,
)
from hybridtrack.testing._reference import kalman_update

# --------------------------------------------------------------------------- toy components


class ToyStraight(MotionModel):
    """Constant velocity, written independently of the built-in plugin."""

    name = "toy_straight"
    layout = ("x", "vx", "y", "vy")

    def __init__(self, q: float = 0.1):
        self.noise_cov = q * np.eye(2)

    def transition(self, tau, switch_state):
        return cv_transition(tau, self.noise_cov[0, 0])


class RowOnly(ToyStraight):
    """Breaks vectorization: propagates only the first row of a stack."""

    def propagate(self, x, tau, switch_state):
        x = np.asarray(x, dtype=float)
        return self.transition(tau, switch_state).apply(x.reshape(-1, 4)[0]) if x.ndim > 1 else super().propagate(x, tau, switch_state)


class ForgetfulEnter(ToyStraight):
    """Breaks enter: drops the velocities even when entering from its own layout."""

    def enter(self, state, layout, parameters=None):
        out = super().enter(state, layout)
        out[[1, 3]] = 0.0
        return out


class WrongNoiseShape(ToyStraight):
    """noise_cov does not match the Q of its transitions."""

    def __init__(self):
        super().__init__()
        self.noise_cov = np.eye(3)


class ZeroJacobian(LinearPositionSensor):
    linear = False

    def jacobian(self, x, layout):
        return np.zeros_like(super().jacobian(x, layout))


class GlobalNoise(LinearPositionSensor):
    """Ignores the Generator it is given."""

    def simulate(self, x, layout, rng):
        return super().simulate(x, layout, np.random.default_rng())


class NoNoise(LinearPositionSensor):
    def simulate(self, x, layout, rng):
        return self.measure(x, layout)


class ToyKalman(Estimator):
    """The reference covariance-form KF wrapped as an estimator."""

    name = "toy_kalman"

    def initialize(self, mean, cov):
        return check_prior(mean, cov)

    def predict(self, state, transitions):
        return kalman_reference.predict(*state, transitions.F, transitions.B, transitions.Q)

    def update(self, state, z, sensors, layout):
        mean, cov, innovation = kalman_update(*state, z, sensors, layout)
        return (mean, cov), innovation

    def mean(self, state):
        return state[0]

    def covariance(self, state):
        return state[1]

    def take(self, state, rows):
        return state[0][rows], state[1][rows]

    def concatenate(self, states):
        return np.concatenate([s[0] for s in states]), np.concatenate([s[1] for s in states])


class NaNAsZero(ToyKalman):
    """Treats a missing measurement as z = 0."""

    def update(self, state, z, sensors, layout):
        return super().update(state, np.nan_to_num(np.asarray(z, dtype=float)), sensors, layout)


class TakeIgnoresOrder(ToyKalman):
    """take() returns the rows sorted instead of in the order asked."""

    def take(self, state, rows):
        return super().take(state, np.sort(rows))


class NoPriorCheck(ToyKalman):
    def initialize(self, mean, cov):
        return np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)


class Biased(ToyKalman):
    """Consistent shapes, wrong numbers: adds 1 m to every updated x."""

    exact_kalman = True

    def update(self, state, z, sensors, layout):
        (mean, cov), innovation = super().update(state, z, sensors, layout)
        if innovation.measurement_dim:
            mean = mean + np.array([1.0, 0, 0, 0])
        return (mean, cov), innovation


class ToySum(Detector):
    """Cumulative log-likelihood ratio of filter 1 against filter 0."""

    name = "toy_sum"

    def __init__(self, threshold: float = 5.0):
        self.threshold = threshold
        self.reset()

    def reset(self):
        self.total = 0.0

    def step(self, step, innovation):
        self.total += float(innovation.loglik[1] - innovation.loglik[0])
        decision = "change" if self.total > self.threshold else None
        return DetectorStep({"llr": self.total}, {"upper": self.threshold}, decision)


class NoReset(ToySum):
    """Keeps its running sum across reset()."""

    def __init__(self, threshold: float = 5.0):
        super().__init__(threshold)
        self.reset = lambda: None


class NaNStatistic(ToySum):
    def step(self, step, innovation):
        return DetectorStep({"llr": float("nan")})


class ToyLeastSquares(Solver):
    """Fits θ in y = A θ + noise by least squares."""

    name = "toy_lsq"

    @staticmethod
    def example_problem():
        rng = np.random.default_rng(3)
        A = rng.normal(size=(20, 2))
        return A, A @ np.array([1.0, -2.0]) + 0.01 * rng.normal(size=20)

    def solve(self, problem):
        A, y = problem
        theta, *_ = np.linalg.lstsq(A, y, rcond=None)
        cost = float(np.sum((y - A @ theta) ** 2))
        return Solution(theta, np.linalg.inv(A.T @ A) * cost / (len(y) - 2), cost, 1, 1, True)


class NaNSolver(ToyLeastSquares):
    def solve(self, problem):
        solution = super().solve(problem)
        return Solution(np.full(2, np.nan), solution.covariance, solution.cost, 1, 1, False)


class ToyRun:
    def __init__(self, times, means, covs, decisions=()):
        self.times, self.means, self.covs, self.decisions = times, means, covs, decisions


class ToyFixes(Algorithm):
    """Takes each fix as the position, velocity 0 (a correct, if poor, algorithm)."""

    layout = ("x", "vx", "y", "vy")

    def __init__(self, *, sensors, tau=None, name="toy_fixes"):
        self.sensor, self.tau, self.name = sensors[0], tau, name

    def estimate(self, z):
        means = np.zeros((len(z), 4))
        means[:, [0, 2]] = z
        return means

    def run(self, measurements, prior, *, times=None):
        z = measurements[self.sensor.name]
        t = self.tau * np.arange(len(z)) if times is None else np.asarray(times)
        return ToyRun(t, self.estimate(z), np.broadcast_to(np.eye(4), (len(z), 4, 4)).copy(), self.decisions(len(z)))

    def decisions(self, steps):
        return (Decision(3, "toy", "straight", 1.0),)


class NoRun:
    layout = ("x", "vx", "y", "vy")
    name = "no_run"

    def __init__(self, **_):
        pass


class Lost(ToyFixes):
    def estimate(self, z):
        return np.zeros((len(z), 4))


class Restless(ToyFixes):
    def estimate(self, z):
        return super().estimate(z) + np.random.default_rng().normal(size=(len(z), 4))


class Backwards(ToyFixes):
    def decisions(self, steps):
        return (Decision(5, "toy", "a", 1.0), Decision(2, "toy", "b", 1.0))


class SegmentsNeeded(ToyFixes):
    example_run = {"segments": [10, 10]}

    def run(self, measurements, prior, segments, *, times=None):
        assert sum(segments) == len(measurements[self.sensor.name]) - 1
        return super().run(measurements, prior, times=times)


# --------------------------------------------------------------------------- tests


def test_correct_components_pass():
    check_motion_model(ToyStraight())
    check_sensor(LinearPositionSensor("xy", ("x", "y"), [[4.0, 1.0], [1.0, 9.0]]))
    check_sensor(LinearPositionSensor("x only", ("x",)))
    check_estimator(ToyKalman())
    check_detector(ToySum())
    assert isinstance(check_solver(ToyLeastSquares()), Solution)
    assert check_algorithm(ToyFixes).means.shape == (21, 4)
    check_algorithm(SegmentsNeeded)  # example_run: the further arguments of run


@pytest.mark.parametrize(
    "factory, message",
    [
        (NoRun, "is not a hybridtrack.core.algorithm.Algorithm"),
        (Lost, "does not follow a straight target"),
        (Restless, "means of a run given the same times"),
        (Backwards, "not in step order"),
    ],
    ids=lambda value: value.__name__ if isinstance(value, type) else None,
)
def test_algorithm_violations_are_caught(factory, message):
    with pytest.raises(AssertionError, match=message):
        check_algorithm(factory)


@pytest.mark.parametrize(
    "check, component, message",
    [
        (check_motion_model, RowOnly(), "propagate of a (5, n) stack"),
        (check_motion_model, ForgetfulEnter(), "enter(state, own layout)"),
        (check_motion_model, WrongNoiseShape(), "noise_cov has shape (3, 3)"),
        (check_sensor, ZeroJacobian(), "jacobian at state 0 against finite differences"),
        (check_sensor, GlobalNoise(), "simulate with the same seed"),
        (check_sensor, NoNoise(), "simulated noise covariance"),
        (check_estimator, NaNAsZero(), "innovation nu has shape (3, 3), expected (3, 2)"),
        (check_estimator, TakeIgnoresOrder(), "mean after take([2, 0, 0])"),
        (check_estimator, NoPriorCheck(), "did not raise ValueError"),
        (check_estimator, Biased(), "mean after update at step 0 (both sensors) against the covariance-form KF"),
        (check_detector, NoReset(), "differs after reset()"),
        (check_detector, NaNStatistic(), "statistic 'llr' is NaN"),
        (check_solver, NaNSolver(), "solution parameters contains NaN"),
    ],
    ids=lambda value: type(value).__name__ if not callable(value) or isinstance(value, type) else None,
)
def test_violations_are_caught_with_a_clear_message(check, component, message):
    with pytest.raises(AssertionError) as info:
        check(component)
    assert message in str(info.value)
    assert type(component).__qualname__ in str(info.value)  # the message names the component


def test_an_approximate_estimator_can_opt_out_of_the_kalman_comparison():
    Biased.exact_kalman = False
    try:
        check_estimator(Biased())
    finally:
        Biased.exact_kalman = True


def test_the_kits_kalman_update_is_the_reference_step_on_the_sensors_with_a_measurement():
    """NaN rows drop their sensor: the update is sdk.kalman_reference.update with the other sensors' H and R; all-NaN
    z is no update (m = 0)."""
    rng = np.random.default_rng(3)
    mean, A = rng.normal(size=(2, 4)), rng.normal(size=(2, 4, 4))
    cov = A @ np.swapaxes(A, -1, -2) + np.eye(4)
    xy, x = LinearPositionSensor("xy", ("x", "y"), [[4.0, 1.0], [1.0, 9.0]]), LinearPositionSensor("x", ("x",), [[2.0]])
    z = np.array([1.0, 2.0, np.nan])
    got_mean, got_cov, innovation = kalman_update(mean, cov, z, [xy, x], ("x", "vx", "y", "vy"))
    H = np.broadcast_to(xy.matrix(("x", "vx", "y", "vy")), (2, 2, 4))
    want_mean, want_cov, nu, S, loglik, nis = kalman_reference.update(mean, cov, z[:2], H, xy.noise_cov)
    np.testing.assert_array_equal(got_mean, want_mean)
    np.testing.assert_array_equal(got_cov, want_cov)
    for got, want in zip((innovation.nu, innovation.S, innovation.loglik, innovation.nis), (nu, S, loglik, nis)):
        np.testing.assert_array_equal(got, want)
    same_mean, same_cov, nothing = kalman_update(mean, cov, np.full(3, np.nan), [xy, x], ("x", "vx", "y", "vy"))
    assert same_mean is mean and same_cov is cov and nothing.nu.shape == (2, 0)


def test_solver_without_a_problem_is_only_named():
    class NoExample(ToyLeastSquares):
        example_problem = None

    assert check_solver(NoExample()) is None
    assert isinstance(check_solver(NoExample(), ToyLeastSquares.example_problem()), Solution)


def test_check_component_dispatches_by_kind_and_rejects_unknown_kinds():
    check_component("motion_model", ToyStraight())
    with pytest.raises(AssertionError, match="is not a hybridtrack.core.interfaces.Sensor"):
        check_component("sensor", ToyStraight())
    with pytest.raises(ValueError, match="unknown component kind 'filter'"):
        check_component("filter", ToyKalman())
    check_component("algorithm", ToyFixes)  # an algorithm's factory: the check builds it


def test_example_parameters_convention():
    class WithDict(ToySum):
        example_parameters = {"threshold": 2.0}

    class WithMethod(ToySum):
        @classmethod
        def example_parameters(cls):
            return {"threshold": 3.0}

    class Broken(ToySum):
        example_parameters = [("threshold", 1.0)]

    assert example_parameters(ToySum) == {}
    assert build_example(WithDict).threshold == 2.0
    assert build_example(WithMethod).threshold == 3.0
    with pytest.raises(TypeError, match="example_parameters must be a dict"):
        example_parameters(Broken)

    def needs_radius(radius):
        return radius

    with pytest.raises(AssertionError, match="needs_radius: cannot be built with example parameters"):
        build_example(needs_radius)


@pytest.mark.hybridtrack_contract
def test_the_pytest_plugin_fixtures(hybridtrack_contracts, hybridtrack_registry):
    hybridtrack_contracts.check_component("motion_model", ToyStraight())
    assert hybridtrack_contracts.check_estimator is check_estimator
    assert hybridtrack_contracts.check_algorithm is check_algorithm
    assert {"imm", "gpb1", "gpb2", "known_switch", "unknown_change", "known_modes"} <= set(hybridtrack_registry.names("algorithm"))
    assert "straight" in hybridtrack_registry.names("motion_model")
