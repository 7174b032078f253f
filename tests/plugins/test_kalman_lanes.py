"""The compiled lanes of the ``kalman`` estimator (``engine="auto"``: axis-separable and dense kernels of
``_kalman_kernel`` on a bank and measurement model already seen) against its numpy reference (``engine="numpy"``):
equal to 1e-12 relative over every update form, structure on and off, NaN components, per-filter z, two sensors
and irregular Δt; and the reference's errors, unchanged, when a lane meets a bad step."""

import numpy as np
import pytest
from _filters_support import LAYOUT, bank_of, position_sensor, straight, turn

from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters.kalman import AxisState, CovarianceState, KalmanFilter

pytestmark = pytest.mark.skipif(not cov_form.NUMBA_AVAILABLE, reason="numba not installed: no compiled lanes")
X0 = np.array([0.0, 0.0, 0.0, 2.0])
M = 5


def _bank(tau=0.1):
    return bank_of([straight(tau)] + [turn(X0, r, left, tau) for r in (2.0, 5.0) for left in (True, False)])


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


def _measurements(rng, steps, dim, nan_steps=(), per_filter=False):
    Z = 0.3 * rng.standard_normal((steps, M, dim) if per_filter else (steps, dim))
    for k, cols in nan_steps:
        Z[k, ..., cols] = np.nan
    return Z


def _run(estimator, banks, Z, sensors):
    """Predict + update over the steps; every output the state and the innovation expose."""
    state = estimator.initialize(np.tile(X0, (M, 1)), np.stack([np.eye(4)] * M))
    out = []
    for bank, z in zip(banks, Z):
        state = estimator.predict(state, bank)
        state, innovation = estimator.update(state, z, sensors, LAYOUT)
        out.append((state.x_predicted, state.P_predicted, state.x, state.P, innovation.nu, innovation.S, innovation.loglik, innovation.nis))
    return out, state


def _assert_equal_runs(got, ref, form):
    for step_got, step_ref in zip(got, ref):
        for what, a, b in zip(("x-", "P-", "x", "P", "nu", "S", "loglik", "nis"), step_got, step_ref):
            assert a.shape == b.shape, what
            if a.size:
                assert _rel(a, b) < 1e-12, (form, what, _rel(a, b))


class _Spy:
    """Counts the calls of the lane kernels (wrapped on the kernel module)."""

    def __init__(self, monkeypatch):
        module = cov_form.kernel_module()
        self.calls = {}
        for name in ("axis_predict", "axis_update", "predict_bank_checked", "update_bank_blocked"):
            function = getattr(module, name)

            def counted(*args, _f=function, _name=name):
                self.calls[_name] = self.calls.get(_name, 0) + 1
                return _f(*args)

            monkeypatch.setattr(module, name, counted)


@pytest.mark.parametrize("structure", [True, False], ids=["separable", "dense"])
@pytest.mark.parametrize("form", cov_form.UPDATE_FORMS)
def test_lanes_equal_the_numpy_reference(form, structure, monkeypatch):
    """30 steps of one bank, a NaN y at step 7 and a fully missing z at step 12 (the reference takes those)."""
    spy = _Spy(monkeypatch)
    rng = np.random.default_rng(1)
    Z = _measurements(rng, 30, 2, nan_steps=[(7, [1]), (12, [0, 1])])
    bank = _bank()
    sensor = position_sensor(np.diag([0.01, 0.02]))
    got, last = _run(KalmanFilter(form, structure), [bank] * 30, Z, [sensor])
    ref, _ = _run(KalmanFilter(form, structure, engine="numpy"), [bank] * 30, Z, [sensor])
    _assert_equal_runs(got, ref, form)
    separable = structure and form != "conventional"
    assert isinstance(last, AxisState if separable else CovarianceState)
    lanes = ("axis_predict", "axis_update") if separable else ("predict_bank_checked", "update_bank_blocked")
    assert all(spy.calls.get(name, 0) >= 20 for name in lanes), spy.calls


@pytest.mark.parametrize("structure", [True, False], ids=["separable", "dense"])
def test_lanes_equal_the_reference_with_per_filter_z_and_irregular_dt(structure, monkeypatch):
    """Per-filter rows (M, 2) of the position sensor, Δt alternating between two banks and new banks at some
    steps (irregular sampling), a NaN y at step 5."""
    spy = _Spy(monkeypatch)
    rng = np.random.default_rng(2)
    Z = _measurements(rng, 24, 2, nan_steps=[(5, [1])], per_filter=True)
    banks_by_dt = {0.1: _bank(0.1), 0.25: _bank(0.25)}
    banks = [banks_by_dt[0.1 if k % 3 else 0.25] if k % 7 else _bank(0.05 + 0.01 * k) for k in range(24)]
    sensors = [position_sensor(np.diag([0.01, 0.03]))]
    got, _ = _run(KalmanFilter(structure=structure), banks, Z, sensors)
    ref, _ = _run(KalmanFilter(structure=structure, engine="numpy"), banks, Z, sensors)
    _assert_equal_runs(got, ref, "joseph")
    lanes = ("axis_predict", "axis_update") if structure else ("predict_bank_checked", "update_bank_blocked")
    assert all(spy.calls.get(name, 0) >= 10 for name in lanes), spy.calls


def test_dense_lane_with_two_sensors_equals_the_reference(monkeypatch):
    """Two sensors measuring x twice (no axis separation: the dense lane under structure=True too), per-filter rows,
    a NaN component of the second sensor at step 4."""
    spy = _Spy(monkeypatch)
    rng = np.random.default_rng(4)
    Z = _measurements(rng, 20, 3, nan_steps=[(4, [2])], per_filter=True)
    sensors = [position_sensor(np.array([[0.02, 0.004], [0.004, 0.03]])), position_sensor(np.array([[0.02]]), components=("x",), name="x2")]
    for structure in (True, False):
        got, _ = _run(KalmanFilter(structure=structure), [_bank()] * 20, Z, sensors)
        ref, _ = _run(KalmanFilter(structure=structure, engine="numpy"), [_bank()] * 20, Z, sensors)
        _assert_equal_runs(got, ref, "joseph")
    assert spy.calls.get("update_bank_blocked", 0) >= 15, spy.calls  # m = 3: the Cholesky lanes


def test_lane_hands_a_bad_step_to_the_reference_and_its_errors():
    """An indefinite S, a too large z and an overflowing covariance raise as on the reference path; the lane
    goes on afterwards."""
    bank = _bank()
    sensor = position_sensor()
    for structure in (True, False):
        est = KalmanFilter(structure=structure)
        state = est.initialize(np.tile(X0, (M, 1)), np.stack([np.eye(4)] * M))
        for _ in range(3):  # learn the lanes
            state = est.predict(state, bank)
            state, _ = est.update(state, np.zeros(2), [sensor], LAYOUT)
        with pytest.raises(ValueError, match="z"):
            est.update(est.predict(state, bank), np.array([1e200, 0.0]), [sensor], LAYOUT)
        bad = est.predict(state, bank)
        if isinstance(bad, AxisState):
            Pa = bad.Pa.copy()
            Pa[0, 0, 0, 1] = -10.0  # s = P_xx + r < 0 for filter 1
            bad = AxisState(bad.axes, bad.n, bad.xa, Pa, bad.xa, Pa, None)
        else:
            P = bad.P.copy()
            P[1, 0, 0] = -10.0
            bad = CovarianceState(bad.x, P, bad.x, P, None)
        with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
            est.update(bad, np.zeros(2), [sensor], LAYOUT)
        if isinstance(state, AxisState):  # P = 1.79e308 I: F P Fᵀ overflows (a state no prior gives, made by hand)
            huge = AxisState(state.axes, state.n, state.xa, state.Pa * 0 + 1.79e308, state.xa, state.Pa, None)
        else:
            huge = CovarianceState(state.x, state.P * 0 + 1.79e308 * np.eye(4), state.x, state.P, None)
        with pytest.raises(ValueError, match=r"^predict: the predicted covariance of 'kalman' has value (inf|nan)"):
            est.predict(huge, bank)
        state = est.predict(state, bank)
        state, innovation = est.update(state, np.zeros(2), [sensor], LAYOUT)
        assert np.isfinite(innovation.loglik).all()


def test_engine_numpy_takes_no_lane(monkeypatch):
    spy = _Spy(monkeypatch)
    rng = np.random.default_rng(3)
    _run(KalmanFilter(engine="numpy"), [_bank()] * 5, _measurements(rng, 5, 2), [position_sensor()])
    _run(KalmanFilter(structure=False, engine="numpy"), [_bank()] * 5, _measurements(rng, 5, 2), [position_sensor()])
    assert spy.calls == {}


def _update_outputs(M, n, m):
    """x⁺, P⁺, ν, S, ℓ, NIS buffers of an update kernel (flattened like the lanes pass them)."""
    return [np.empty((M, n)), np.empty((M, n * n)), np.empty((M, m)), np.empty((M, m * m)), np.empty(M), np.empty(M)]


@pytest.mark.slow  # ≈ 12 s on a fresh checkout (one numba compile per (n, m, form)), ≈ 0.5 s from numba's cache
@pytest.mark.parametrize("M_blocked", [1, 16, 37])
def test_blocked_kernels_equal_the_filter_by_filter_ones_bitwise(M_blocked):
    """The blocked (vectorized) lane kernels against themselves with 1-wide blocks (the filter-by-filter loop) on random
    SPD systems, n = 4 with m = 2 and every form, m = 1 and m = 3 (Joseph), shared and per-filter z, M a partial, a whole
    and several blocks: bitwise equal (same operations in the same order per filter), and the update equal to
    update_bank with H the selection to 1e-12.  A non-finite output or an indefinite S in the last (partial) block is
    reported."""
    kernel = cov_form.kernel_module()
    W = kernel.LANE_WIDTH
    rng = np.random.default_rng(7)
    for n, m_sizes, forms in ((4, (2,), range(3)), (4, (1, 3), (0,))):  # a few (n, m, form): each compiles
        A = rng.standard_normal((M_blocked, n, n))
        P = (A @ np.swapaxes(A, 1, 2) + np.eye(n)).reshape(M_blocked, n * n)
        x = rng.standard_normal((M_blocked, n))
        F, B = rng.standard_normal((M_blocked, n * n)), rng.standard_normal((M_blocked, n))
        Q = (A @ np.swapaxes(A, 1, 2)).reshape(M_blocked, n * n)
        got = [np.empty((M_blocked, n)), np.empty((M_blocked, n * n))]
        ref = [np.empty((M_blocked, n)), np.empty((M_blocked, n * n))]
        blocks = [kernel.lane_blocks(a) for a in (F, B, Q)]
        assert kernel.predict_bank_checked(x, P, *blocks, *got, (0,) * n, (0,) * W) == 0
        assert kernel.predict_bank_checked(x, P, *(kernel.lane_blocks(a, 1) for a in (F, B, Q)), *ref, (0,) * n, (0,)) == 0
        assert all(np.array_equal(a, b) for a, b in zip(got, ref))
        P_bad = P.copy()
        P_bad[-1, 0] = np.inf
        assert kernel.predict_bank_checked(x, P_bad, *blocks, *got, (0,) * n, (0,) * W) == 1
        for m in m_sizes:
            sel = np.sort(rng.choice(n, m, replace=False)).astype(np.intp)
            C = rng.standard_normal((m, m))
            R = (C @ C.T + np.eye(m)).reshape(-1)
            for z in (rng.standard_normal((1, m)), rng.standard_normal((M_blocked, m))):
                for form in forms:
                    got, ref = _update_outputs(M_blocked, n, m), _update_outputs(M_blocked, n, m)
                    sizes = ((0,) * n, (0,) * m)
                    assert kernel.update_bank_blocked(x, P, z, sel, R, 1e12, *got, *sizes, (0,) * (form + 1), (0,) * W) == 0
                    assert kernel.update_bank_blocked(x, P, z, sel, R, 1e12, *ref, *sizes, (0,) * (form + 1), (0,)) == 0
                    assert all(np.array_equal(a, b) for a, b in zip(got, ref)), (n, m, form)
                    H, general = np.eye(n)[sel].reshape(1, -1), _update_outputs(M_blocked, n, m)
                    nu = np.broadcast_to(z, (M_blocked, m)) - x[:, sel]
                    assert kernel.update_bank(x, P, nu, H, R.reshape(1, -1), form, *general[:2], *general[3:], *sizes) == -1
                    for a, b in zip(got[:2] + got[3:], general[:2] + general[3:]):
                        assert _rel(a, b) < 1e-12, (n, m, form)
            P_bad = P.copy()
            P_bad[-1, sel[0] * n + sel[0]] = -10.0 - R[0]  # S of the last filter not positive definite
            assert kernel.update_bank_blocked(x, P_bad, z, sel, R, 1e12, *_update_outputs(M_blocked, n, m), *sizes, (0,), (0,) * W) == 1
            assert (
                kernel.update_bank_blocked(
                    x, P, np.full_like(z, 2e12), sel, R, 1e12, *_update_outputs(M_blocked, n, m), *sizes, (0,), (0,) * W
                )
                == 1
            )
