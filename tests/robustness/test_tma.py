"""Bearings-only TMA on bad or ill-posed input: each case a clear error, or an answer reported as unobservable.

Reproductions of the reliability issue ("bearings-only, collision course"): a
constant bearing of 0 or π was solved to a target 4·10¹⁰ m away with
``converged=True, consistent=True``; degrees passed as radians were accepted; a
start at the observer's position ended in ``LinAlgError``; an empty batch gave an
``IndexError``.
"""

import warnings

import numpy as np
import pytest

from hybridtrack_plugins.solvers.levenberg_marquardt import BatchLevenbergMarquardt, LevenbergMarquardt
from hybridtrack_plugins.solvers.n_bearings import NBearings
from hybridtrack_plugins.solvers.observer import Seed002Scenario, example_problem, simulate_bearings
from hybridtrack_plugins.solvers.scipy_reference import ScipyLeastSquares
from hybridtrack_plugins.solvers.tma_model import (
    BearingsBatch,
    BearingsProblem,
    UnobservabilityWarning,
    UnobservableError,
    constant_bearing,
)

SOLVERS = {
    "lm": LevenbergMarquardt(),
    "lm_batch": BatchLevenbergMarquardt(),
    "lm_batch_numpy": BatchLevenbergMarquardt(engine="numpy"),
    "n_bearings": NBearings(),
    "scipy": ScipyLeastSquares(),
}
START_SOLVERS = {k: v for k, v in SOLVERS.items() if k != "n_bearings"}  # the ones that take a starting guess
SIGMA = np.deg2rad(0.5)


@pytest.fixture(scope="module")
def seed():
    """(times, observer, prior, bearings) of a 60-bearing seed 002 problem."""
    problem = example_problem()
    return problem.times, problem.observer, problem.initial, problem.bearings


def solve_unobservable(solver, problem):
    with pytest.warns(UnobservabilityWarning, match="unobservable"):
        solution = solver.solve(problem)
    assert not solution.converged
    assert "unobservable" in solution.message
    assert np.isnan(solution.covariance).all()
    return solution


# --------------------------------------------------------------------------- constant bearing (the reported defect)

CONSTANT = {"0": 0.0, "pi": np.pi, "minus_pi_2": -np.pi / 2, "0.3": 0.3, "0_and_pi": None}


@pytest.mark.parametrize("value", list(CONSTANT), ids=str)
@pytest.mark.parametrize("name", list(SOLVERS))
def test_constant_bearing_of_any_value_is_unobservable(seed, name, value):
    """All bearings equal modulo π (dead ahead, astern, any value): converged=False, warning, NaN θ."""
    times, observer, prior, _ = seed
    X = np.full(len(times), CONSTANT[value]) if CONSTANT[value] is not None else np.where(np.arange(len(times)) < 30, 0.0, np.pi)
    solution = solve_unobservable(SOLVERS[name], BearingsProblem(times, X, observer, sigma=SIGMA, initial=prior))
    assert np.isnan(solution.parameters).all()
    assert not solution.consistent


@pytest.mark.parametrize("name", list(SOLVERS))
def test_noisy_constant_bearing_with_known_sigma_is_unobservable(seed, name):
    times, observer, prior, _ = seed
    X = np.random.default_rng(3).normal(0.0, SIGMA, len(times))  # collision course, σ = 0.5°
    solve_unobservable(SOLVERS[name], BearingsProblem(times, X, observer, sigma=SIGMA, initial=prior))


@pytest.mark.parametrize("value", [0.0, np.pi, 0.3])
@pytest.mark.parametrize("name", list(SOLVERS))
def test_noisy_constant_bearing_with_unknown_sigma_is_not_converged(seed, name, value):
    """σ unknown: the answer is checked after solving (JᵀJ singular or a constant bearing fits as well)."""
    times, observer, prior, _ = seed
    X = value + np.random.default_rng(1).normal(0.0, SIGMA, len(times))
    solve_unobservable(SOLVERS[name], BearingsProblem(times, X, observer, initial=prior))


def test_batch_flags_only_its_constant_bearing_problems(seed):
    times, observer, prior, X = seed
    bearings = np.stack([X, np.zeros_like(X), X, np.full_like(X, np.pi)])
    batch = BearingsBatch(times, bearings, observer, sigma=SIGMA, initial=prior)
    for solver in (BatchLevenbergMarquardt(), BatchLevenbergMarquardt(engine="numpy"), NBearings()):
        with pytest.warns(UnobservabilityWarning, match=r"problem\(s\) \[1, 3\]"):
            answer = solver.solve_batch(batch)
        assert answer.converged.tolist() == [True, False, True, False]
        assert np.isnan(answer.parameters[[1, 3]]).all() and "constant bearing" in answer.messages[1]
        alone = solver.solve(batch.problem(0))
        np.testing.assert_allclose(answer.parameters[[0, 2]], [alone.parameters] * 2, rtol=1e-9)
        assert answer.iterations[0] == alone.iterations


def test_valid_problem_is_not_flagged(seed):
    times, observer, prior, X = seed
    assert not constant_bearing(X, SIGMA) and not constant_bearing(X, None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for solver in SOLVERS.values():
            assert solver.solve(BearingsProblem(times, X, observer, sigma=SIGMA, initial=prior)).converged
            assert solver.solve(BearingsProblem(times, X, observer, initial=prior)).converged


def test_slowly_changing_bearing_is_not_constant():
    """A bearing drifting by 20σ over the run is observable (the χ² test rejects a constant bearing)."""
    X = np.linspace(0.0, 20 * SIGMA, 60) + np.random.default_rng(0).normal(0.0, SIGMA, 60)
    assert not constant_bearing(X, SIGMA)


# --------------------------------------------------------------------------- bearings that cannot be radians


@pytest.mark.parametrize("value", [7.0, -7.0, 90.0, 359.0])
def test_bearing_beyond_two_pi_is_refused_as_probably_degrees(seed, value):
    times, observer, prior, X = seed
    bad = X.copy()
    bad[5] = value
    with pytest.raises(ValueError, match=rf"bearings: index 5 is {value!r}, not an angle in radians.*degrees.*deg2rad"):
        BearingsProblem(times, bad, observer, sigma=SIGMA, initial=prior)


@pytest.mark.parametrize("name", ["n_bearings", "lm"])
def test_bearings_in_degrees_never_reach_a_solver(seed, name):
    """The seed problem in degrees (the issue: N-bearings reported convergence on it)."""
    times, observer, prior, X = seed
    with pytest.raises(ValueError, match="degrees passed by mistake"):
        SOLVERS[name].solve(BearingsProblem(times, np.rad2deg(X), observer, sigma=SIGMA, initial=prior))


def test_batch_names_the_problem_given_in_degrees(seed):
    times, observer, prior, X = seed
    bearings = np.stack([X, X, np.rad2deg(X)])
    with pytest.raises(ValueError, match=r"bearings: problem 2, bearing \d+ is .*not an angle in radians"):
        BearingsBatch(times, bearings, observer, initial=prior)


# --------------------------------------------------------------------------- starting guess


@pytest.mark.parametrize("velocity", [(0.0, 0.0), (1.0, 1.0)])
@pytest.mark.parametrize("name", list(START_SOLVERS))
def test_start_at_the_observer_position_is_a_clear_error(seed, name, velocity):
    """Used to end in LinAlgError: Eigenvalues did not converge."""
    times, observer, _, X = seed
    start = np.array([*observer[0], *velocity])
    with pytest.raises(ValueError, match=r"initial: the starting guess.* on the observer at bearing 0 \(t = 0.0 s\)"):
        START_SOLVERS[name].solve(BearingsProblem(times, X, observer, sigma=SIGMA, initial=start))


def test_start_meeting_the_observer_later_is_a_clear_error(seed):
    times, observer, _, X = seed
    k = 20
    start = np.array([*observer[k], 0.0, 0.0])  # a stationary guess on the observer's position at bearing 20
    with pytest.raises(ValueError, match=rf"initial: .*at bearing {k} "):
        LevenbergMarquardt().solve(BearingsProblem(times, X, observer, initial=start))


@pytest.mark.parametrize("engine", ["auto", "numpy"])
def test_batch_names_the_problem_starting_at_the_observer(seed, engine):
    times, observer, prior, X = seed
    initial = np.stack([prior, prior, [*observer[0], 0.0, 0.0]])
    batch = BearingsBatch(times, np.stack([X, X, X]), observer, sigma=SIGMA, initial=initial)
    with pytest.raises(ValueError, match="initial: the starting guess of problem 2 puts the target on the observer"):
        BatchLevenbergMarquardt(engine=engine).solve_batch(batch)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_initial_guess_with_nan_or_inf(seed, bad):
    times, observer, prior, X = seed
    start = prior.copy()
    start[2] = bad
    with pytest.raises(ValueError, match=r"initial: contains NaN or inf at index \(2,\)"):
        BearingsProblem(times, X, observer, initial=start)
    with pytest.raises(ValueError, match=r"initial: problem 1 contains"):
        BearingsBatch(times, np.stack([X, X]), observer, initial=np.stack([prior, start]))


def test_initial_guess_of_wrong_length(seed):
    times, observer, _, X = seed
    with pytest.raises(ValueError, match=r"initial: expected shape \(4,\), got \(3,\)"):
        BearingsProblem(times, X, observer, initial=np.zeros(3))


# --------------------------------------------------------------------------- data values and shapes


@pytest.mark.parametrize("field", ["bearings", "times", "observer"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_or_inf_is_refused_naming_the_field(seed, field, bad):
    times, observer, prior, X = seed
    data = {"times": times.copy(), "bearings": X.copy(), "observer": observer.copy()}
    data[field][7] = bad
    with pytest.raises(ValueError, match=rf"{field}: .*(index \(?7|NaN or inf)"):
        BearingsProblem(**data, initial=prior)


@pytest.mark.parametrize("field", ["bearings", "observer"])
def test_batch_names_the_problem_with_nan(seed, field):
    times, observer, prior, X = seed
    bearings = np.stack([X, X, X])
    observers = np.stack([observer] * 3)
    (bearings if field == "bearings" else observers)[1, 9] = np.nan
    with pytest.raises(ValueError, match=rf"{field}: problem 1 contains nan at index \(9"):
        BearingsBatch(times, bearings, observers, initial=prior)


@pytest.mark.parametrize(
    "change, message",
    [
        ("decreasing", r"times: time at index 10 .* is earlier than the time at index 9 .*strictly increasing"),
        ("duplicate", r"times: time at index 10 .* is a duplicate of the time at index 9"),
    ],
)
def test_times_not_increasing(seed, change, message):
    times, observer, prior, X = seed
    t = times.copy()
    t[10] = t[9] - 1.0 if change == "decreasing" else t[9]
    with pytest.raises(ValueError, match=message):
        BearingsProblem(t, X, observer, initial=prior)
    with pytest.raises(ValueError, match=message):
        BearingsBatch(t, X[None], observer, initial=prior)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"bearings": "2d"}, r"bearings: expected shape \(\*,\), got \(2, 60\)"),
        ({"times": "2d"}, r"times: expected shape \(K,\)"),
        ({"observer": "3 columns"}, r"observer: expected shape \(\*, 2\), got \(60, 3\)"),
        ({"times": "short"}, r"times \(59,\), bearings \(60,\) and observer \(60, 2\): expected shapes"),
        ({"observer": "long"}, r"observer \(61, 2\): expected shapes"),
        ({"bearings": "short"}, r"bearings \(59,\)"),
    ],
    ids=lambda v: v if isinstance(v, str) else next(iter(v)) + "_" + next(iter(v.values())),
)
def test_wrong_shapes_and_mismatched_lengths(seed, change, message):
    times, observer, prior, X = seed
    data = {"times": times, "bearings": X, "observer": observer}
    field, how = next(iter(change.items()))
    if how == "2d":
        data[field] = np.stack([data[field]] * 2)
    elif how == "3 columns":
        data[field] = np.column_stack([observer, observer[:, 0]])
    elif how == "short":
        data[field] = data[field][:-1]
    elif how == "long":
        data[field] = np.concatenate([observer, observer[-1:] + 1.0])
    with pytest.raises(ValueError, match=message):
        BearingsProblem(**data, initial=prior)


@pytest.mark.parametrize(
    "change, message",
    [
        ("times", r"times: expected shape \(60,\) to match bearings \(2, 60\), got \(59,\)"),
        ("observer", r"observer: expected shape \(60, 2\) or \(2, 60, 2\), got \(3, 60, 2\)"),
        ("initial", r"initial: expected shape \(4,\) or \(2, 4\), got \(3, 4\)"),
        ("bearings", r"bearings: expected shape \(B, n\), got \(60,\)"),
    ],
)
def test_batch_shapes(seed, change, message):
    times, observer, prior, X = seed
    data = {"times": times, "bearings": np.stack([X, X]), "observer": observer, "initial": prior}
    data[change] = {
        "times": times[:-1],
        "observer": np.stack([observer] * 3),
        "initial": np.stack([prior] * 3),
        "bearings": X,
    }[change]
    with pytest.raises(ValueError, match=message):
        BearingsBatch(**data)


@pytest.mark.parametrize("sigma", [-0.01, -np.inf, np.nan, np.inf])
def test_bad_sigma(seed, sigma):
    times, observer, prior, X = seed
    with pytest.raises(ValueError, match=r"sigma: expected a finite bearing noise σ ≥ 0 in radians"):
        BearingsProblem(times, X, observer, sigma=sigma, initial=prior)


def test_zero_sigma_means_noise_free_and_skips_the_chi2_test(seed):
    """σ = 0 is allowed (noise-free data, the σ = 0 Monte Carlo): no χ² test, `consistent` None."""
    times, observer, prior, X = seed
    solution = LevenbergMarquardt().solve(BearingsProblem(times, X, observer, sigma=0.0, initial=prior))
    assert solution.consistent is None and np.isnan(solution.chi2_pvalue)


@pytest.mark.parametrize("n", [0, 1, 2, 3])
def test_fewer_than_four_bearings(n):
    with pytest.raises(ValueError, match=rf"bearings: bearings-only TMA needs at least 4 bearings .* got {n}"):
        BearingsProblem(np.arange(n, dtype=float), np.full(n, 0.1), np.zeros((n, 2)))


def test_empty_batch_is_a_clear_error(seed):
    """Used to end in IndexError (LM) or an empty answer (N-bearings)."""
    times, observer, prior, _ = seed
    with pytest.raises(ValueError, match=r"bearings: the batch holds no problem \(shape \(0, 60\)\)"):
        BearingsBatch(times, np.zeros((0, len(times))), observer, initial=prior)


# --------------------------------------------------------------------------- observer


@pytest.mark.parametrize("motion", ["straight", "stationary"])
@pytest.mark.parametrize("name", list(SOLVERS))
def test_observer_that_never_maneuvers(name, motion):
    times = np.arange(50) * 10.0
    speed = 5.0 if motion == "straight" else 0.0
    observer = np.stack([speed * times, np.zeros_like(times)], axis=1)
    X = simulate_bearings(np.array([1000.0, 20000.0, 3.0, -2.0]), times, observer, 0.0, np.random.default_rng(0))
    with pytest.raises(UnobservableError, match="observer never maneuvers"):
        SOLVERS[name].solve(BearingsProblem(times, X, observer, initial=np.array([0.0, 15000.0, 0.0, 0.0])))


def test_batch_names_the_problem_whose_observer_never_maneuvers():
    scenario = Seed002Scenario(interval=20.0)
    times, observer = scenario.times(), scenario.observer()
    straight = np.stack([5.0 * times, np.zeros_like(times)], axis=1)
    observers = np.stack([observer, straight, observer])
    X = np.stack([simulate_bearings(scenario.prior_theta(), times, o, 0.0, np.random.default_rng(0)) for o in observers])
    batch = BearingsBatch(times, X, observers, initial=scenario.prior_theta())
    for solver in (BatchLevenbergMarquardt(), NBearings()):
        with pytest.raises(UnobservableError, match=r"problems \[1\]"):
            solver.solve_batch(batch)
