"""The compiled batched LM (numba kernel, seed 002 §4.3): its atan2 and sin/cos, its sums, and equality with the numpy path."""

import warnings

import numpy as np
import pytest

from hybridtrack_plugins.sensors.bearing import bearing_gradient
from hybridtrack_plugins.solvers import _tma_kernel as kernel
from hybridtrack_plugins.solvers import levenberg_marquardt
from hybridtrack_plugins.solvers.levenberg_marquardt import BatchLevenbergMarquardt, LMSettings
from hybridtrack_plugins.solvers.observer import Seed002Scenario, simulate_bearings
from hybridtrack_plugins.solvers.tma_model import BearingsBatch, ScaledProblem, UnobservabilityWarning, normal_equations, time_powers

needs_numba = pytest.mark.skipif(not kernel.AVAILABLE, reason="numba not installed: the numpy path is used")


def ulps(value, reference):
    return np.abs(value - reference) / np.spacing(np.maximum(np.abs(reference), np.finfo(float).tiny))


@needs_numba
def test_atan2_is_within_two_ulp_of_numpy():
    rng = np.random.default_rng(1)
    y = rng.standard_normal(5000) * np.exp(rng.uniform(-30, 30, 5000))
    x = rng.standard_normal(5000) * np.exp(rng.uniform(-30, 30, 5000))
    got = np.array([kernel.atan2(a, b) for a, b in zip(y, x)])
    assert ulps(got, np.arctan2(y, x)).max() <= 2
    special = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan])
    for a in special:
        for b in special:
            got, want = kernel.atan2(a, b), np.arctan2(a, b)
            if np.isnan(want):
                assert np.isnan(got), (a, b)
            elif not (a == 0 and b == 0):  # atan2(±0, ±0): only the value 0 or ±π matters to nobody here
                assert ulps(got, want) <= 2, (a, b, got, want)
    assert kernel.atan2(0.0, 0.0) == 0.0


def fit_atan_polynomial(degree=10, nodes=200):
    """The derivation of ``_tma_kernel.ATAN_P``: P(u) = (atan(√u)/√u − 1)/u on [0, tan²(π/8)].

    P(u) = Σ_{k≥1} (−1)^k u^{k−1}/(2k+1) is summed in 50-digit decimals at
    ``nodes`` Chebyshev nodes, fitted by least squares in the Chebyshev basis of
    the given degree, and returned as monomial coefficients in u (u⁰ first).
    """
    from decimal import Decimal, localcontext

    with localcontext() as context:
        context.prec = 50
        tan_pi_8 = Decimal(2).sqrt() - 1
        u_max = float(tan_pi_8 * tan_pi_8)

        def series(u):
            u, total, power, k = Decimal(u), Decimal(0), Decimal(1), 1
            while True:
                term = power / (2 * k + 1)
                total += -term if k % 2 else term
                if term < Decimal(10) ** -40:
                    return float(total)
                power *= u
                k += 1

        x = np.cos(np.pi * (np.arange(nodes) + 0.5) / nodes)  # Chebyshev nodes on [−1, 1], u = (x + 1) u_max / 2
        values = np.array([series(float(v)) for v in (x + 1) / 2 * u_max])
    chebyshev = np.linalg.lstsq(np.polynomial.chebyshev.chebvander(x, degree), values, rcond=None)[0]
    in_x = np.polynomial.Polynomial(np.polynomial.chebyshev.cheb2poly(chebyshev))
    return in_x(np.polynomial.Polynomial([-1.0, 2.0 / u_max])).coef


def test_atan_polynomial_is_reproduced_by_its_derivation():
    u = np.linspace(0.0, kernel.TAN_PI_8**2, 1001)
    fitted = np.polynomial.polynomial.polyval(u, fit_atan_polynomial())
    assert np.abs(fitted - np.polynomial.polynomial.polyval(u, kernel.ATAN_P)).max() < 1e-15


@needs_numba
def test_unit_vectors_match_sin_and_cos():
    rng = np.random.default_rng(2)
    for X in (
        rng.uniform(-np.pi, np.pi, 100_000),
        rng.uniform(-1e4, 1e4, 100_000),
        np.array([0.0, -0.0, np.pi, -np.pi, np.pi / 2, -np.pi / 2, np.pi / 4, 3 * np.pi / 4, 1e-300]),
    ):
        sx, cx = np.empty_like(X), np.empty_like(X)
        kernel.unit_vectors(X, sx, cx)
        assert np.abs(sx - np.sin(X)).max() <= 2.3e-16
        assert np.abs(cx - np.cos(X)).max() <= 2.3e-16


def _sums_numpy(scaled, s):
    """F and the kernel's 13 sums from the numpy model (tma_model.normal_equations)."""
    F, r = scaled.cost(s)
    dx = s[0] + s[2] * scaled.tau - scaled.ox
    dy = s[1] + s[3] * scaled.tau - scaled.oy
    p, q = bearing_gradient(dx, dy, scaled.convention)
    H, g = normal_equations(p, q, r, time_powers(scaled.tau))
    return F, H, g


@needs_numba
@pytest.mark.parametrize("far", [False, True])  # at the truth (small residuals) and behind the observer (general pass)
def test_both_passes_give_the_model_sums(far):
    scenario = Seed002Scenario(interval=4.0)
    theta = np.array([3000.0, 20000.0, 3.0, -6.0])
    times, observer = scenario.times(), scenario.observer()
    X = simulate_bearings(theta, times, observer, np.deg2rad(0.5), np.random.default_rng(5))
    scaled = ScaledProblem.build(times, X, observer, theta, times[0], "north")
    s = scaled.scaling.to_scaled(theta) * (np.array([-1.0, -1.0, 2.0, 2.0]) if far else 1.0)
    F, H, g = _sums_numpy(scaled, s)
    sx, cx = np.sin(scaled.X), np.cos(scaled.X)
    passes = [kernel.pass_general] + ([] if far else [kernel.pass_small])
    for one_pass in passes:
        out = np.empty(14)
        bad = one_pass(s, scaled.tau, scaled.ox, scaled.oy, sx, cx, out)
        Hk, gk = np.empty((4, 4)), np.empty(4)
        kernel.normal_from_sums(out, Hk, gk)
        assert out[0] == pytest.approx(F, rel=1e-12)
        np.testing.assert_allclose(Hk, H, rtol=1e-12, atol=1e-12 * np.abs(H).max())
        np.testing.assert_allclose(gk, g, rtol=1e-9, atol=1e-12 * np.abs(g).max())
        assert (bad > 0) == far


def _batch(count, sigma_deg, seed, convention, per_problem_observer=False):
    scenario = Seed002Scenario(interval=4.0, convention=convention)
    rng = np.random.default_rng(seed)
    theta = scenario.draw_targets(rng, count)
    times, observer = scenario.times(), scenario.observer()
    X = simulate_bearings(theta, times, observer, np.deg2rad(sigma_deg), rng, convention)
    prior = scenario.prior_theta()
    if per_problem_observer:  # each problem its own (shifted) observer track and start: per-row scaling
        shift = rng.normal(scale=500.0, size=(count, 2))
        observer = observer[None] + shift[:, None, :]
        X = np.stack([simulate_bearings(theta[i], times, observer[i], np.deg2rad(sigma_deg), rng, convention) for i in range(count)])
        prior = prior + np.concatenate([shift, np.zeros((count, 2))], axis=1)
    return BearingsBatch(times, X, observer, sigma=np.deg2rad(sigma_deg), initial=prior, convention=convention)


def _solve(batch, engine, settings=None, chunk_size=1024):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnobservabilityWarning)
        return BatchLevenbergMarquardt(settings or LMSettings(), chunk_size=chunk_size, engine=engine).solve_batch(batch)


def _assert_same(compiled, reference):
    np.testing.assert_array_equal(compiled.iterations, reference.iterations)
    np.testing.assert_array_equal(compiled.evaluations, reference.evaluations)
    np.testing.assert_array_equal(compiled.converged, reference.converged)
    assert compiled.messages == reference.messages
    scale = np.abs(reference.parameters).max(axis=-1, keepdims=True)
    assert np.max(np.abs(compiled.parameters - reference.parameters) / scale) < 1e-10
    np.testing.assert_allclose(compiled.cost, reference.cost, rtol=1e-12)
    finite = np.isfinite(reference.covariance)
    np.testing.assert_array_equal(np.isfinite(compiled.covariance), finite)
    np.testing.assert_allclose(compiled.covariance[finite], reference.covariance[finite], rtol=1e-8, atol=0)


@needs_numba
@pytest.mark.parametrize("convention", ["north", "math"])
@pytest.mark.parametrize("sigma_deg", [0.5, 2.0])
def test_compiled_engine_equals_numpy_engine(convention, sigma_deg):
    batch = _batch(40, sigma_deg, seed=11, convention=convention)
    compiled = _solve(batch, "numba", chunk_size=16)
    _assert_same(compiled, _solve(batch, "numpy"))
    assert BatchLevenbergMarquardt().compiled
    np.testing.assert_array_equal(_solve(batch, "auto").parameters, compiled.parameters)  # chunks do not matter


@needs_numba
def test_compiled_engine_with_per_problem_observers_and_starts():
    batch = _batch(12, 0.5, seed=12, convention="north", per_problem_observer=True)
    assert batch.observer.ndim == 3
    _assert_same(_solve(batch, "numba", chunk_size=5), _solve(batch, "numpy"))


@needs_numba
@pytest.mark.parametrize(
    "settings", [LMSettings(max_iterations=2), LMSettings(lam0=1e-3, lam_up=1e4, lam_max=1.0), LMSettings(F_tol=1e-6, lam0=1e-2)]
)
def test_compiled_engine_stops_like_the_numpy_engine(settings):
    batch = _batch(30, 1.0, seed=13, convention="north")
    compiled, reference = _solve(batch, "numba", settings), _solve(batch, "numpy", settings)
    _assert_same(compiled, reference)


@needs_numba
def test_compiled_engine_on_a_singular_geometry():
    """Constant bearings (maneuver along the line of sight): both engines end alike, unobservable."""
    times = np.arange(40) * 10.0
    speed = np.where(times < 200, 5.0, 10.0)
    y = np.concatenate([[0.0], np.cumsum(speed[:-1] * 10.0)])
    observer = np.stack([np.zeros_like(y), y], axis=1)
    X = simulate_bearings(np.array([0.0, 30000.0, 0.0, 4.0]), times, observer, 0.0, np.random.default_rng(0))
    batch = BearingsBatch(times, X[None], observer, sigma=np.deg2rad(0.5), initial=np.array([0.0, 20000.0, 0.0, 1.0]))
    compiled, reference = _solve(batch, "numba"), _solve(batch, "numpy")
    np.testing.assert_array_equal(compiled.iterations, reference.iterations)
    assert compiled.messages == reference.messages and not compiled.converged[0]


def test_engine_choice(monkeypatch):
    with pytest.raises(ValueError, match="engine"):
        BatchLevenbergMarquardt(engine="fortran")
    assert not BatchLevenbergMarquardt(engine="numpy").compiled
    assert levenberg_marquardt.NUMBA_AVAILABLE == kernel.AVAILABLE
    monkeypatch.setattr(levenberg_marquardt, "NUMBA_AVAILABLE", False)
    assert not BatchLevenbergMarquardt().compiled  # "auto" falls back to numpy without numba
    with pytest.raises(ValueError, match="numba is not installed"):
        BatchLevenbergMarquardt(engine="numba")
