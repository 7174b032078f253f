"""Algorithm 4 maths (seed 000): Riccati and Lyapunov steady states, expected increments, Wald's sample numbers."""

import math

import numpy as np
import pytest

from hybridtrack.algorithms import algorithm4 as wald
from hybridtrack_plugins.motion.linear_modes import RightTurn, Straight

H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
R = 0.01 * np.eye(2)
XS = np.array([0.0, 0.0, 0.0, 2.0])


def fbq(model):
    t = model.transition(0.1, XS)
    return t.F, t.B, t.process_noise


def test_riccati_solution_is_the_fixed_point_of_the_kalman_recursion_and_of_lyapunov():
    F, _, Q = fbq(Straight())
    steady = wald.steady_state_filter(F, H, Q, R)
    P = np.eye(4)
    for _ in range(2000):
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        P = F @ (P - K @ H @ P) @ F.T + Q
    np.testing.assert_allclose(steady.P_predicted, P, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(wald.steady_error_covariance(F, H, Q, R, steady.K), steady.P_predicted, rtol=1e-8, atol=1e-14)


def test_a_filter_on_its_own_data_has_actual_equal_to_own_innovation_covariance():
    model = fbq(Straight())
    steady = wald.steady_state_filter(model[0], H, model[2], R)
    own, actual = wald.innovation_moments(model, [model], H, R, XS, steady.P_posterior, 50)
    np.testing.assert_allclose(actual[0, -1], own[0, -1], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(actual[0, 0], own[0, 0], rtol=1e-9, atol=1e-15)  # started in steady state: exact at every step


def test_identical_hypotheses_have_zero_drift():
    model = fbq(Straight())
    pair = wald.wald_pair(model, model, H, R, XS, 0.05, 0.05, horizon=40)
    np.testing.assert_allclose(pair.mu_0p, 0.0, atol=1e-12)
    assert math.isinf(pair.n_0p_transient) and math.isinf(pair.n_p0_transient)


def test_drifts_have_the_right_signs_and_the_sample_numbers_follow_wald():
    pair = wald.wald_pair(fbq(Straight()), fbq(RightTurn(radius=5.0)), H, R, XS, 0.05, 0.05, horizon=60)
    assert np.all(pair.mu_0p[1:] < 0) and np.all(pair.mu_p0[1:] > 0)
    low, high = wald.wald_boundary_terms(0.05, 0.05)
    A, B = math.log(0.95 / 0.05), math.log(0.05 / 0.95)
    assert low == pytest.approx(0.05 * A + 0.95 * B) and high == pytest.approx(0.95 * A + 0.05 * B)
    n = int(pair.n_p0_transient)
    assert pair.mu_p0[:n].sum() >= high > pair.mu_p0[: n - 1].sum()
    assert pair.bank_size >= max(pair.n_0p_transient, pair.n_p0_transient)


def test_steady_sample_numbers_when_the_drift_has_a_limit():
    pair = wald.WaldPair(np.full(10, -0.5), np.full(10, 0.25), -0.5, 0.25, 2.0 / 0.5, 2.0 / 0.25, 4.0, 8.0)
    assert pair.n_0p == 4.0 and pair.n_p0 == 8.0 and pair.bank_size == 8
    assert wald._limit(np.full(20, 0.25)) == 0.25 and wald._limit(np.arange(20.0)) is None
    with pytest.raises(ValueError, match="alternative"):
        wald.algorithm4_bank_size([])
