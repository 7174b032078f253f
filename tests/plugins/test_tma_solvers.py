"""Bearings-only TMA solvers (seed 002): exactness, agreement with scipy, batch = single, ill-posed input."""

import warnings

import numpy as np
import pytest

from hybridtrack.core.plugins import load_plugins
from hybridtrack_plugins.sensors.bearing import bearing_gradient
from hybridtrack_plugins.solvers.levenberg_marquardt import BatchLevenbergMarquardt, LevenbergMarquardt, LMSettings
from hybridtrack_plugins.solvers.n_bearings import NBearings
from hybridtrack_plugins.solvers.observer import Seed002Scenario, simulate_bearings
from hybridtrack_plugins.solvers.scipy_reference import ScipyLeastSquares
from hybridtrack_plugins.solvers.tma_model import (
    BearingsBatch,
    BearingsProblem,
    ScaledProblem,
    UnobservabilityWarning,
    UnobservableError,
    normal_equations,
    time_powers,
)


def scenario_data(count, sigma_deg, seed, interval=4.0, convention="north"):
    scenario = Seed002Scenario(interval=interval, convention=convention)
    rng = np.random.default_rng(seed)
    theta = scenario.draw_targets(rng, count)
    times, observer = scenario.times(), scenario.observer()
    X = simulate_bearings(theta, times, observer, np.deg2rad(sigma_deg), rng, convention)
    return theta, times, observer, X, scenario.prior_theta()


def relative_error(estimate, truth):
    return np.max(np.abs(estimate - truth) / np.abs(truth).max(axis=-1, keepdims=True))


def test_registered():
    names = load_plugins(strict=True).registry.names("solver")
    for name in ("levenberg_marquardt", "levenberg_marquardt_batch", "n_bearings", "scipy_least_squares"):
        assert name in names


@pytest.mark.parametrize("convention", ["north", "math"])
def test_noise_free_bearings_are_recovered_exactly(convention):
    theta, times, observer, X, prior = scenario_data(6, 0.0, seed=11, convention=convention)
    for i in range(len(theta)):
        problem = BearingsProblem(times, X[i], observer, sigma=0.0, initial=prior, convention=convention)
        for solver in (LevenbergMarquardt(), NBearings(), BatchLevenbergMarquardt()):
            solution = solver.solve(problem)
            assert solution.converged, (solver.name, solution.message)
            assert relative_error(solution.parameters, theta[i]) < 1e-6, solver.name
            assert solution.sqrt_ka < 1e-6
    batch = BearingsBatch(times, X, observer, sigma=0.0, initial=prior, convention=convention)
    assert relative_error(BatchLevenbergMarquardt().solve_batch(batch).parameters, theta) < 1e-6
    assert relative_error(NBearings().solve_batch(batch).parameters, theta) < 1e-6


def test_lm_agrees_with_scipy_least_squares():
    theta, times, observer, X, prior = scenario_data(8, 0.5, seed=5)
    lm = LevenbergMarquardt(LMSettings(F_tol=1e-16))
    reference = ScipyLeastSquares(ftol=1e-15, xtol=1e-15, gtol=1e-15)
    for i in range(len(theta)):
        problem = BearingsProblem(times, X[i], observer, sigma=np.deg2rad(0.5), initial=prior)
        ours, theirs = lm.solve(problem), reference.solve(problem)
        assert ours.converged and theirs.converged
        assert relative_error(ours.parameters, theirs.parameters) < 1e-7
        assert ours.cost <= theirs.cost * (1 + 1e-9)
        np.testing.assert_allclose(ours.covariance, theirs.covariance, rtol=1e-5, atol=0)


def test_batched_lm_equals_single_lm():
    theta, times, observer, X, prior = scenario_data(24, 1.0, seed=8)
    sigma = np.deg2rad(1.0)
    batch = BearingsBatch(times, X, observer, sigma=sigma, initial=prior)
    stacked = BatchLevenbergMarquardt(chunk_size=7).solve_batch(batch)  # chunks must not matter
    single = LevenbergMarquardt()
    iterations_equal = 0
    for i in range(len(theta)):
        one = single.solve(batch.problem(i))
        assert relative_error(stacked.parameters[i], one.parameters) < 1e-8
        np.testing.assert_allclose(stacked.covariance[i], one.covariance, rtol=1e-6)
        assert stacked.cost[i] == pytest.approx(one.cost, rel=1e-10)
        assert bool(stacked.converged[i]) == one.converged
        iterations_equal += stacked.iterations[i] == one.iterations and stacked.evaluations[i] == one.evaluations
    assert iterations_equal >= len(theta) - 1  # a count may differ only by a rounding tie at ΔF ≈ 0
    whole = BatchLevenbergMarquardt(chunk_size=1000).solve_batch(batch)
    np.testing.assert_array_equal(whole.iterations, stacked.iterations)


def test_batched_n_bearings_equals_single():
    theta, times, observer, X, prior = scenario_data(10, 0.5, seed=2)
    batch = BearingsBatch(times, X, observer, sigma=np.deg2rad(0.5))
    stacked = NBearings().solve_batch(batch)
    for i in range(len(theta)):
        one = NBearings().solve(batch.problem(i))
        assert relative_error(stacked.parameters[i], one.parameters) < 1e-8
        np.testing.assert_allclose(stacked.covariance[i], one.covariance, rtol=1e-6)
        assert stacked.sqrt_ka[i] == pytest.approx(one.sqrt_ka, rel=1e-9)


def test_normal_equations_match_explicit_jacobian():
    theta, times, observer, X, prior = scenario_data(3, 0.5, seed=4)
    scaled = ScaledProblem.build(times, X, observer, prior, times[0], "north")
    s = scaled.scaling.to_scaled(theta * 1.01)
    r = scaled.residuals(s)
    J = scaled.jacobian(s)
    dx = s[:, 0, None] + s[:, 2, None] * scaled.tau - scaled.ox
    dy = s[:, 1, None] + s[:, 3, None] * scaled.tau - scaled.oy
    p, q = bearing_gradient(dx, dy, "north")
    H, g = normal_equations(p, q, r, time_powers(scaled.tau))
    np.testing.assert_allclose(H, np.swapaxes(J, -1, -2) @ J, rtol=1e-12)
    np.testing.assert_allclose(g, np.einsum("bki,bk->bi", J, r), rtol=1e-10, atol=1e-14)


def test_statistics_of_the_ml_answer():
    """√Ka ≈ σ, the χ²(n−4) test passes at the true σ, and the covariance matches the scatter (NEES)."""
    sigma_deg = 0.5
    theta, times, observer, X, prior = scenario_data(300, sigma_deg, seed=21, interval=2.0)
    result = BatchLevenbergMarquardt().solve_batch(BearingsBatch(times, X, observer, sigma=np.deg2rad(sigma_deg), initial=prior))
    assert result.converged.all()
    assert np.mean(result.sqrt_ka_deg) == pytest.approx(sigma_deg, rel=0.02)
    assert np.mean(result.consistent) > 0.95
    error = result.parameters - theta
    nees = np.einsum("bi,bi->b", error, np.linalg.solve(result.covariance, error[..., None])[..., 0])
    assert 3.3 < nees.mean() < 5.0  # E = 4 for an efficient estimator; 300 draws


def test_iterations_and_evaluations_are_reported():
    theta, times, observer, X, prior = scenario_data(1, 0.5, seed=1)
    solution = LevenbergMarquardt().solve(BearingsProblem(times, X[0], observer, sigma=np.deg2rad(0.5), initial=prior))
    assert solution.iterations >= 2
    assert solution.evaluations >= solution.iterations + 1
    assert solution.message == "ΔF < F_tol"
    assert solution.sqrt_ka_deg == pytest.approx(np.rad2deg(np.sqrt(solution.cost / len(times))))
    assert 0 <= solution.chi2_pvalue <= 1 and solution.chi2_dof == len(times) - 4


def test_n_bearings_is_biased_by_the_first_bearing():
    theta, times, observer, X, prior = scenario_data(1, 0.0, seed=6)
    X = X.copy()
    X[0, 0] += np.deg2rad(1.0)  # only φ_0 wrong
    lm = LevenbergMarquardt().solve(BearingsProblem(times, X[0], observer, initial=prior))
    nb = NBearings().solve(BearingsProblem(times, X[0], observer))
    assert relative_error(lm.parameters, theta[0]) < 0.01
    assert relative_error(nb.parameters, theta[0]) > 0.01


# --------------------------------------------------------------------------- ill-posed input


def straight_observer(n=50):
    times = np.arange(n) * 10.0
    return times, np.stack([5.0 * times, np.zeros(n)], axis=1)


ALL_SOLVERS = [LevenbergMarquardt(), BatchLevenbergMarquardt(), NBearings(), ScipyLeastSquares()]


@pytest.mark.parametrize("solver", ALL_SOLVERS, ids=lambda s: s.name)
def test_constant_velocity_observer_is_unobservable(solver):
    times, observer = straight_observer()
    theta = np.array([1000.0, 20000.0, 3.0, -2.0])
    X = simulate_bearings(theta, times, observer, 0.0, np.random.default_rng(0))
    with pytest.raises(UnobservableError, match="never maneuvers"):
        solver.solve(BearingsProblem(times, X, observer, initial=theta * 1.1))


def test_batch_with_a_non_maneuvering_observer_is_refused():
    times, observer = straight_observer()
    X = np.zeros((3, len(times)))
    with pytest.raises(UnobservableError):
        BatchLevenbergMarquardt().solve_batch(BearingsBatch(times, X, observer, initial=np.array([0.0, 1e4, 1.0, 0.0])))
    with pytest.raises(UnobservableError):
        NBearings().solve_batch(BearingsBatch(times, X, observer))


def test_singular_geometry_warns_and_is_not_converged():
    """Observer and target on one line of sight: bearings are constant, range and radial speed unobservable."""
    times = np.arange(40) * 10.0
    speed = np.where(times < 200, 5.0, 10.0)  # a speed change: a maneuver, but along the line of sight
    y = np.concatenate([[0.0], np.cumsum(speed[:-1] * 10.0)])
    observer = np.stack([np.zeros_like(y), y], axis=1)
    theta = np.array([0.0, 30000.0, 0.0, 4.0])
    X = simulate_bearings(theta, times, observer, 0.0, np.random.default_rng(0))
    problem = BearingsProblem(times, X, observer, sigma=np.deg2rad(0.5), initial=np.array([0.0, 20000.0, 0.0, 1.0]))
    for solver in (LevenbergMarquardt(), BatchLevenbergMarquardt(), NBearings()):
        with pytest.warns(UnobservabilityWarning):
            solution = solver.solve(problem)
        assert not solution.converged, solver.name
        assert "unobservable" in solution.message, solution.message
        assert np.isnan(solution.covariance).all(), solver.name


@pytest.mark.parametrize("n", [0, 1, 3])
def test_fewer_than_four_bearings(n):
    with pytest.raises(ValueError, match="at least 4 bearings"):
        BearingsProblem(np.arange(n, dtype=float), np.zeros(n), np.zeros((n, 2)))
    with pytest.raises(ValueError, match="at least 4 bearings"):
        BearingsBatch(np.arange(n, dtype=float), np.zeros((2, n)), np.zeros((n, 2)))


def test_nan_bearing_is_refused_naming_it():
    theta, times, observer, X, prior = scenario_data(1, 0.5, seed=1)
    bad = X[0].copy()
    bad[17] = np.nan
    with pytest.raises(ValueError, match=r"bearings: contains NaN or inf at index \(17,\)"):
        BearingsProblem(times, bad, observer, initial=prior)
    with pytest.raises(ValueError, match="bearings"):
        BearingsBatch(times, np.stack([X[0], bad]), observer, initial=prior)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"observer": np.zeros((5, 2))}, "expected shapes"),
        ({"times": np.arange(4.0)}, "expected shapes"),
        ({"initial": np.zeros(3)}, "initial"),
        ({"sigma": -1.0}, "sigma"),
        ({"convention": "compass"}, "convention"),
    ],
)
def test_bad_problem_fields(change, message):
    kwargs = dict(times=np.arange(6.0), bearings=np.zeros(6), observer=np.zeros((6, 2)))
    kwargs.update(change)
    with pytest.raises(ValueError, match=message):
        BearingsProblem(**kwargs)


def test_lm_needs_a_start_and_valid_settings():
    theta, times, observer, X, prior = scenario_data(1, 0.5, seed=1)
    with pytest.raises(ValueError, match="initial"):
        LevenbergMarquardt().solve(BearingsProblem(times, X[0], observer))
    with pytest.raises(ValueError, match="lam_up"):
        LMSettings(lam_up=0.5)
    with pytest.raises(ValueError, match="lam_down"):
        LMSettings(lam_down=2.0)
    with pytest.raises(ValueError, match="F_tol"):
        LMSettings(F_tol=0.0)


def test_iteration_cap_is_reported_as_not_converged():
    theta, times, observer, X, prior = scenario_data(1, 0.5, seed=3)
    problem = BearingsProblem(times, X[0], observer, initial=prior)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solution = LevenbergMarquardt(LMSettings(max_iterations=2)).solve(problem)
    assert not solution.converged and solution.iterations == 2 and "max_iterations" in solution.message
    batch = BatchLevenbergMarquardt(LMSettings(max_iterations=2)).solve(problem)
    assert not batch.converged and batch.iterations == 2
