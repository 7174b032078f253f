"""The coordinated turn's compiled linearization (plugins/motion/_turn_kernel.py) against its numpy path, and the
step table of the linear modes (each Δt's transition built once) against fresh transitions."""

from __future__ import annotations

import numpy as np
import pytest

from hybridtrack_plugins.motion import linear_modes
from hybridtrack_plugins.motion.linear_modes import ConstantAcceleration, Stop, Straight
from hybridtrack_plugins.motion.real_motion import NUMBA_AVAILABLE, CoordinatedTurn, _FiveStateMode

needs_numba = pytest.mark.skipif(not NUMBA_AVAILABLE, reason="numba not installed: the numpy path runs")


def states(seed, M=40, max_rate=0.2):
    rng = np.random.default_rng(seed)
    x = np.column_stack([rng.normal(size=M) * 1e4, rng.normal(size=M) * 8, rng.normal(size=M) * 1e4, rng.normal(size=M) * 8, np.zeros(M)])
    x[:, 4] = np.concatenate([rng.normal(size=M // 4) * 1e-5, rng.normal(size=M // 4) * 0.05, rng.uniform(-0.5, 0.5, M - M // 2)])
    x[0, 4], x[1, 4] = max_rate, -max_rate  # on the limit: clipped, no derivative
    return x, rng.uniform(0.5, 30.0, M)


@needs_numba
@pytest.mark.parametrize("shared", [False, True])
def test_compiled_linearization_equals_numpy(shared):
    model = CoordinatedTurn(noise_density=1e-3, rate_density=1e-6, max_rate=0.2)
    x, tau = states(1)
    tau = float(tau[0]) if shared else tau
    got, ref = model.linearize(tau, x), _FiveStateMode.linearize(model, tau, x)
    for what in ("F", "B", "Q", "noise_root"):
        a, b = getattr(got, what), getattr(ref, what)
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13 * np.abs(b).max(), err_msg=what)
    assert (got.F[:2, :, 4] == 0).all() and (got.F[2:, 4, 4] == (np.abs(x[2:, 4]) < 0.2)).all()


def test_a_state_that_is_not_finite_is_the_numpy_path_s_error():
    x, tau = states(2, M=4)
    x[1, 0] = np.nan
    with pytest.raises(ValueError, match="NaN or inf"):
        CoordinatedTurn().linearize(tau, x)


@pytest.mark.parametrize("model", [Straight(noise_density=1e-3), Stop(noise_density=0.01), ConstantAcceleration(noise_density=1e-4)])
def test_the_step_table_gives_the_transitions_of_each_step(model, monkeypatch):
    """Steps seen before, new ones and repeats, across calls and past the table's size: the rows of each step's own
    transition (the table only keeps what it built)."""
    monkeypatch.setattr(linear_modes, "STEP_TABLE_SIZE", 70)
    rng = np.random.default_rng(3)
    model.prepare_steps(rng.uniform(1, 10, 30).round(2))
    for _ in range(4):
        steps = np.concatenate([rng.uniform(1, 10, 25).round(2), [2.5, 2.5]])
        bank = model.transition_bank(steps, np.zeros((steps.size, model.state_dim)))
        for i in (0, 7, 25, 26):
            single = model.transition(float(steps[i]))
            np.testing.assert_array_equal(bank.F[i], single.F)
            np.testing.assert_allclose(bank.Q[i], single.process_noise, rtol=1e-15, atol=0)
    assert len(model.__dict__["_step_table"].row) <= 70
    with pytest.raises(ValueError, match="tau"):
        model.transition_bank(np.array([1.0, -2.0]), np.zeros((2, model.state_dim)))
