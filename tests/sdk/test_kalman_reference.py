"""The readable reference Kalman step (hybridtrack.sdk.kalman_reference) against FilterPy, and the fast paths
against it: the numpy covariance form, the compiled numba kernels, and the ``kalman`` estimator's compiled lanes
(shared and per-filter matrices, m = 1 … 3, several sensors, irregular Δt, banks large enough for the blocked
kernels)."""

import sys
from pathlib import Path

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FilterPyKF

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.sdk import kalman_reference as ref
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters.kalman import KalmanFilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "plugins"))
from _filters_support import LAYOUT, position_sensor, radii_bank  # noqa: E402


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


def _spd(rng, n, scale):
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T + n * np.eye(n))


def test_reference_step_equals_filterpy():
    rng = np.random.default_rng(0)
    n, m = 4, 2
    F = np.eye(n) + 0.1 * rng.standard_normal((n, n))
    B, Q, H, R = rng.standard_normal(n), _spd(rng, n, 1e-2), rng.standard_normal((m, n)), _spd(rng, m, 0.1)
    x, P = rng.standard_normal(n), _spd(rng, n, 1.0)
    peer = FilterPyKF(dim_x=n, dim_z=m)
    peer.x, peer.P, peer.F, peer.Q, peer.H, peer.R, peer.B = x[:, None].copy(), P.copy(), F, Q, H, R, B[:, None]
    for _ in range(5):
        z = rng.standard_normal(m)
        x, P = ref.predict(x, P, F, B, Q)
        peer.predict(u=np.ones((1, 1)))
        np.testing.assert_allclose(x, peer.x[:, 0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(P, peer.P, rtol=1e-12, atol=1e-12)
        x, P, nu, S, loglik, nis = ref.update(x, P, z, H, R)
        peer.update(z[:, None])
        np.testing.assert_allclose(x, peer.x[:, 0], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(P, peer.P, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(nu, peer.y[:, 0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(S, peer.S, rtol=1e-12)
        np.testing.assert_allclose(loglik, peer.log_likelihood, rtol=1e-10)
        np.testing.assert_allclose(nis, peer.mahalanobis**2, rtol=1e-10)


@pytest.mark.parametrize(
    "engine", ["numpy", pytest.param("numba", marks=pytest.mark.skipif(not cov_form.NUMBA_AVAILABLE, reason="no numba"))]
)
@pytest.mark.parametrize(("n", "m"), [(2, 1), (4, 2), (6, 3)])
def test_covariance_form_engines_equal_the_reference(engine, n, m):
    rng = np.random.default_rng(10 * n + m)
    M = 9
    x = rng.standard_normal((M, n))
    P = np.stack([_spd(rng, n, 10.0 ** rng.uniform(-2, 2)) for _ in range(M)])
    F = np.eye(n) + 0.3 * rng.standard_normal((M, n, n))
    B, Q = rng.standard_normal((M, n)), np.stack([_spd(rng, n, 1e-2) for _ in range(M)])
    H, R, z = rng.standard_normal((m, n)), _spd(rng, m, 0.1), rng.standard_normal((M, m))
    x_ref, P_ref = ref.predict(x, P, F, B, Q)
    x_got, P_got = cov_form.predict(x, P, F, B, Q, engine=engine)
    assert _rel(x_got, x_ref) < 1e-12 and _rel(P_got, P_ref) < 1e-12
    x_post, P_post, nu, S, loglik, nis = ref.update(x_ref, P_ref, z, H, R)
    got = cov_form.update_scored(x_ref, P_ref, nu, H, R, None, "joseph", engine=engine)
    for a, b in zip(got, (x_post, P_post, S, loglik, nis)):
        assert _rel(a, b) < 1e-12


@pytest.mark.parametrize("engine", ["auto", "numpy"])
@pytest.mark.parametrize("radii", [2, 10])  # banks of 5 and 21 filters (21: the blocked lanes)
def test_kalman_estimator_equals_the_reference_over_steps(engine, radii):
    """The ``kalman`` estimator (compiled lanes with engine "auto") over 30 steps of a bank of turn models, two
    sensors (x–y and x only), irregular Δt and a step with the second sensor missing, against the reference step."""
    rng = np.random.default_rng(radii)
    sensors = [position_sensor(np.diag([0.02, 0.03]), name="a"), position_sensor(np.array([[0.05]]), components=("x",), name="b")]
    H = np.concatenate([s.H for s in sensors])
    R = np.diag([0.02, 0.03, 0.05])
    x0 = np.array([1.0, 0.5, -2.0, 1.5])
    estimator = KalmanFilter(engine=engine)
    M = 1 + 2 * radii
    state = estimator.initialize(np.tile(x0, (M, 1)), np.tile(np.eye(4), (M, 1, 1)))
    x, P = np.tile(x0, (M, 1)), np.tile(np.eye(4), (M, 1, 1))
    for k in range(30):
        tau = rng.uniform(0.05, 0.3)
        bank = TransitionBank.stack(radii_bank(x0, n_radii=radii, tau=tau))
        z = rng.standard_normal(3) + np.array([x0[0], x0[2], x0[0]])
        if k % 7 == 3:
            z[2] = np.nan
        state = estimator.predict(state, bank)
        state, innovation = estimator.update(state, z, sensors, LAYOUT)
        x, P = ref.predict(x, P, bank.F, bank.B, bank.Q)
        used = np.isfinite(z)
        x, P, nu, S, loglik, nis = ref.update(x, P, z[used], H[used], R[np.ix_(used, used)])
        assert _rel(estimator.mean(state), x) < 1e-12
        assert _rel(estimator.covariance(state), P) < 1e-11
        assert _rel(innovation.loglik, loglik) < 1e-12
        assert _rel(innovation.nis, nis) < 1e-11
