"""The dense covariance-KF kernels against textbook references: the factored innovation covariance, and the
measurement update for every kind of H and R (selection, general, per filter) and every update form."""

import numpy as np
import pytest
from _filters_support import random_spd

from hybridtrack.sdk.linalg import CholeskyFactor, cholesky
from hybridtrack_plugins.filters import _covariance as cov_form

LOG_2PI = np.log(2.0 * np.pi)


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


@pytest.mark.parametrize("m", [1, 2, 3, 4, 5, 6])  # closed forms (1, 2), entry recurrences (3, 4), LAPACK (5, 6)
def test_cholesky_factor_equals_lapack(m):
    rng = np.random.default_rng(m)
    S = np.stack([random_spd(rng, m, scale=10.0 ** rng.uniform(-3, 3)) for _ in range(7)])
    nu = rng.standard_normal((7, m))
    factor = CholeskyFactor(S, "S")
    assert _rel(factor.L, np.linalg.cholesky(S)) < 1e-13
    assert _rel(factor.inverse() @ S, np.broadcast_to(np.eye(m), S.shape)) < 1e-12
    loglik, nis = factor.scores(nu)
    ref_nis = np.einsum("mi,mi->m", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    ref_loglik = -0.5 * (m * LOG_2PI + np.linalg.slogdet(S)[1] + ref_nis)
    np.testing.assert_allclose(nis, ref_nis, rtol=1e-12)
    np.testing.assert_allclose(loglik, ref_loglik, rtol=1e-12)


@pytest.mark.parametrize("m", [1, 2, 3, 5])
@pytest.mark.parametrize("bad", [-1.0, np.nan])
def test_cholesky_factor_rejects_indefinite(m, bad):
    S = np.stack([np.eye(m)] * 3)
    S[1, -1, -1] = bad
    with pytest.raises(np.linalg.LinAlgError, match="innovation covariance S is not positive definite"):
        CholeskyFactor(S, "innovation covariance S")
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        cholesky(S, "innovation covariance S")


def _textbook(x, P, nu, H, R, form):
    """One filter at a time: S = H P Hᵀ + R, K = P Hᵀ S⁻¹ by solve, A = I − K H, P⁺ by the printed formula."""
    out_x, out_P, out_S = [], [], []
    M, n = x.shape
    for i in range(M):
        Hi = H if H.ndim == 2 else H[i]
        Ri = R if R.ndim == 2 else R[i]
        S = Hi @ P[i] @ Hi.T + Ri
        S = 0.5 * (S + S.T)
        K = np.linalg.solve(S, Hi @ P[i]).T
        A = np.eye(n) - K @ Hi
        if form == "joseph":
            P_new = A @ P[i] @ A.T + K @ Ri @ K.T
        else:
            P_new = P[i] - K @ S @ K.T
        out_x.append(x[i] + K @ nu[i])
        out_P.append(0.5 * (P_new + P_new.T))
        out_S.append(S)
    return np.array(out_x), np.array(out_P), np.array(out_S)


CASES = {
    "selection_xy": dict(selection=(0, 2)),
    "selection_x": dict(selection=(0,)),
    "selection_mixed_3": dict(selection=(0, 0, 2)),  # a sensor on x beside one on (x, y)
    "selection_unordered": dict(selection=(3, 1)),
    "general_h": dict(H=np.array([[1.0, 0.1, 0.0, 0.0], [0.2, 0.0, 1.0, 0.05]])),
    "general_h_per_filter": dict(H="per_filter"),
    "per_filter_r": dict(selection=(0, 2), R="per_filter"),
    "six_rows": dict(selection=(0, 1, 2, 3, 0, 2)),  # m > 4: the LAPACK factor
}


@pytest.mark.parametrize("form", ["joseph", "symmetric"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_dense_update_equals_textbook(case, form):
    rng = np.random.default_rng(sorted(CASES).index(case))
    spec = CASES[case]
    M, n = 9, 4
    selection = spec.get("selection")
    if selection is not None:
        H = np.zeros((len(selection), n))
        H[np.arange(len(selection)), selection] = 1.0
    elif isinstance(spec["H"], str):
        H = rng.standard_normal((M, 2, n))
    else:
        H = spec["H"]
    m = H.shape[-2]
    R = np.stack([random_spd(rng, m, 0.05) for _ in range(M)]) if spec.get("R") == "per_filter" else random_spd(rng, m, 0.05)
    x = rng.standard_normal((M, n))
    P = np.stack([random_spd(rng, n) for _ in range(M)])
    P = 0.5 * (P + np.swapaxes(P, 1, 2))
    nu = rng.standard_normal((M, m))
    x_new, P_new, S, loglik, nis = cov_form.update_scored(x, P, nu, H, R, selection, form)
    ref_x, ref_P, ref_S = _textbook(x, P, nu, H, R, form)
    assert _rel(x_new, ref_x) < 1e-12
    assert _rel(P_new, ref_P) < 1e-12
    assert _rel(S, ref_S) < 1e-13
    np.testing.assert_array_equal(P_new, np.swapaxes(P_new, 1, 2))
    ref_nis = np.einsum("mi,mi->m", nu, np.linalg.solve(ref_S, nu[..., None])[..., 0])
    np.testing.assert_allclose(nis, ref_nis, rtol=1e-11)
    np.testing.assert_allclose(loglik, -0.5 * (m * LOG_2PI + np.linalg.slogdet(ref_S)[1] + ref_nis), rtol=1e-11)
    # the plain update returns the same numbers and the factor of S
    x2, P2, S2, L2, K2 = cov_form.update(x, P, nu, H, R, selection, form)
    np.testing.assert_array_equal(P2, P_new)
    assert _rel(L2 @ np.swapaxes(L2, 1, 2), S) < 1e-13
    assert _rel(K2 @ S, P @ (np.swapaxes(H, -1, -2))) < 1e-12


def test_joseph_is_the_two_sided_product_for_the_gain_used():
    """P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ with the returned K, also for a badly scaled bank (1e-12 … 1e12)."""
    rng = np.random.default_rng(11)
    M, n = 5, 4
    P = np.stack([random_spd(rng, n, 10.0**e) for e in (-12, -6, 0, 6, 12)])
    R = np.diag([1e-3, 4e-3])
    H = np.zeros((2, n))
    H[0, 0] = H[1, 2] = 1.0
    x, nu = rng.standard_normal((M, n)), rng.standard_normal((M, 2))
    _, P_new, _, _, K = cov_form.update(x, P, nu, H, R, (0, 2), "joseph")
    A = np.eye(n) - K @ H
    ref = A @ P @ np.swapaxes(A, 1, 2) + K @ R @ np.swapaxes(K, 1, 2)
    for i in range(M):
        assert _rel(P_new[i], ref[i]) < 1e-11
        assert np.linalg.eigvalsh(P_new[i]).min() > 0


def test_cached_measurement_step_still_checks_z():
    """After a step has cached the sensors' model, inf in z still raises and NaN still means 'not measured'."""
    from _filters_support import LAYOUT, bank_of, position_sensor, straight

    from hybridtrack_plugins.filters.kalman import KalmanFilter

    est = KalmanFilter(structure=False)
    sensor = position_sensor(np.array([[0.02, 0.005], [0.005, 0.03]]))
    bank = bank_of([straight()] * 3)
    state = est.predict(est.initialize(np.zeros((3, 4)), np.stack([np.eye(4)] * 3)), bank)
    state, _ = est.update(state, np.array([0.1, -0.2]), [sensor], LAYOUT)  # caches the step's model
    with pytest.raises(ValueError, match="z: contains inf"):
        est.update(state, np.array([np.inf, 0.0]), [sensor], LAYOUT)
    with pytest.raises(ValueError, match=r"z: expected shape \(2,\) or \(3, 2\)"):
        est.update(state, np.zeros(4), [sensor], LAYOUT)
    same, innovation = est.update(state, np.array([np.nan, np.nan]), [sensor], LAYOUT)
    assert innovation.nu.shape == (3, 0)
    np.testing.assert_array_equal(same.covariance, state.covariance)
