"""The compiled dense KF step (numba, ``_kalman_kernel``) against the numpy path of ``_covariance`` (the reference):
random SPD systems, n = 2 … 6, m = 1 … 3, every update form, shared and per-filter H and R."""

import numpy as np
import pytest
from _filters_support import LAYOUT, bank_of, position_sensor, random_spd, straight, turn

from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters.kalman import KalmanFilter

needs_numba = pytest.mark.skipif(not cov_form.NUMBA_AVAILABLE, reason="numba not installed: the numpy path is used")


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


def _system(rng, M, n, m, per_filter):
    """x, P (SPD, scales 1e-3 … 1e3), F, B, Q (SPD), H (m, n) or (M, m, n), R (SPD, (m, m) or (M, m, m)), ν."""
    x = rng.standard_normal((M, n))
    P = np.stack([random_spd(rng, n, 10.0 ** rng.uniform(-3, 3)) for _ in range(M)])
    F = np.eye(n) + 0.3 * rng.standard_normal((M, n, n))
    B = rng.standard_normal((M, n))
    Q = np.stack([random_spd(rng, n, 1e-2) for _ in range(M)])
    H = rng.standard_normal((M, m, n) if per_filter else (m, n))
    R = np.stack([random_spd(rng, m, 0.1) for _ in range(M)]) if per_filter else random_spd(rng, m, 0.1)
    return x, P, F, B, Q, H, R, rng.standard_normal((M, m))


@needs_numba
@pytest.mark.parametrize("per_filter", [False, True])
@pytest.mark.parametrize("m", [1, 2, 3])
@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
def test_compiled_step_equals_numpy(n, m, per_filter):
    rng = np.random.default_rng(100 * n + 10 * m + per_filter)
    x, P, F, B, Q, H, R, nu = _system(rng, 17, n, m, per_filter)
    got = cov_form.predict(x, P, F, B, Q, engine="numba")
    ref = cov_form.predict(x, P, F, B, Q, engine="numpy")
    for a, b in zip(got, ref):
        assert _rel(a, b) < 1e-12
    np.testing.assert_array_equal(got[1], np.swapaxes(got[1], 1, 2))
    x_pred, P_pred = ref
    for form in cov_form.UPDATE_FORMS:
        got = cov_form.update_scored(x_pred, P_pred, nu, H, R, None, form, engine="numba")
        ref = cov_form.update_scored(x_pred, P_pred, nu, H, R, None, form, engine="numpy")
        for what, a, b in zip(("x", "P", "S", "loglik", "nis"), got, ref):
            if what == "P" and form != "joseph":
                # P⁻ − K S Kᵀ cancels (P⁺ ≪ P⁻ when m ≥ n): both engines' rounding is relative to P⁻
                assert np.max(np.abs(a - b)) / np.max(np.abs(P_pred)) < 1e-12, (form, what)
            else:
                assert _rel(a, b) < 1e-12, (form, what, _rel(a, b))
        if form != "conventional":
            np.testing.assert_array_equal(got[1], np.swapaxes(got[1], 1, 2))


@needs_numba
@pytest.mark.parametrize("selection", [(0,), (0, 2), (3, 1), (0, 0, 2)])
def test_compiled_update_with_a_selection_h_equals_the_indexed_numpy_path(selection):
    """The numpy path indexes P for a selection H; the kernel multiplies by H's zeros and ones (exact)."""
    rng = np.random.default_rng(len(selection))
    x, P, *_ = _system(rng, 9, 4, 1, False)
    m = len(selection)
    H = np.zeros((m, 4))
    H[np.arange(m), selection] = 1.0
    R, nu = random_spd(rng, m, 0.05), rng.standard_normal((9, m))
    got = cov_form.update_scored(x, P, nu, H, R, None, "joseph", engine="numba")
    ref = cov_form.update_scored(x, P, nu, H, R, selection, "joseph", engine="numpy")
    for a, b in zip(got, ref):
        assert _rel(a, b) < 1e-12


@needs_numba
def test_compiled_kernel_takes_larger_systems():
    """engine="numba" runs the kernel at any size (m > 4: the numpy path's LAPACK factor)."""
    rng = np.random.default_rng(7)
    x, P, F, B, Q, H, R, nu = _system(rng, 5, 8, 5, False)
    for a, b in zip(cov_form.predict(x, P, F, B, Q, engine="numba"), cov_form.predict(x, P, F, B, Q)):
        assert _rel(a, b) < 1e-12
    got = cov_form.update_scored(x, P, nu, H, R, None, "joseph", engine="numba")
    for a, b in zip(got, cov_form.update_scored(x, P, nu, H, R, None, "joseph")):
        assert _rel(a, b) < 1e-12


@needs_numba
@pytest.mark.parametrize("m", [1, 2, 3])
@pytest.mark.parametrize("bad", [-1.0, np.nan])
def test_compiled_update_rejects_an_indefinite_s_like_numpy(m, bad):
    x, P = np.zeros((3, 4)), np.stack([np.eye(4)] * 3)
    H, nu = np.eye(m, 4), np.zeros((3, m))
    R = np.stack([np.eye(m)] * 3)
    R[1, -1, -1] = bad if np.isnan(bad) else -5.0
    for engine in ("numba", "numpy"):
        with pytest.raises(np.linalg.LinAlgError, match=r"innovation covariance S is not positive definite \(stack index \(1,\)\)"):
            cov_form.update_scored(x, P, nu, H, R, None, "joseph", engine=engine)


@needs_numba
@pytest.mark.parametrize("sensor_R", [np.diag([0.01, 0.02]), np.array([[0.02, 0.005], [0.005, 0.03]])])
def test_kalman_estimator_engines_agree(sensor_R):
    """The dense path of the ``kalman`` estimator, compiled and numpy, over a bank of turns (30 steps)."""
    x0 = np.array([0.0, 0.0, 0.0, 2.0])
    bank = bank_of([straight()] + [turn(x0, r, left) for r in (2.0, 5.0) for left in (True, False)])
    sensor = position_sensor(sensor_R)
    runs = {}
    for engine in ("numba", "numpy"):
        est = KalmanFilter(structure=False, engine=engine)
        state = est.initialize(np.tile(x0, (5, 1)), np.stack([np.eye(4)] * 5))
        out, z_rng = [], np.random.default_rng(3)
        for _ in range(30):
            state = est.predict(state, bank)
            state, innovation = est.update(state, z_rng.standard_normal(2), [sensor], LAYOUT)
            out.append((state.x_predicted, state.P_predicted, state.x, state.P, innovation.S, innovation.loglik, innovation.nis))
        runs[engine] = out
    for got, ref in zip(runs["numba"], runs["numpy"]):
        for a, b in zip(got, ref):
            assert _rel(a, b) < 1e-12


def test_engine_choice():
    with pytest.raises(ValueError, match="engine: expected one of"):
        KalmanFilter(engine="fortran")
    assert cov_form.resolve_engine("numpy", 4, 2) == "numpy"
    assert cov_form.resolve_engine("auto", 8, 2) == "numpy"  # larger systems: BLAS-sized products
    assert cov_form.resolve_engine("auto", 4, 4) == "numpy"
    assert cov_form.resolve_engine("auto", 6, 3) == ("numba" if cov_form.NUMBA_AVAILABLE else "numpy")
