"""Vectorized helpers equal their per-item forms to 1e-12: a motion model's transition bank against its stacked
transitions, and simulate_trajectories against simulate_trajectory of each seed."""

import numpy as np
import pytest

from hybridtrack import Schedule

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
TOL = dict(rtol=0, atol=1e-12)


MODES = [
    "straight",
    "stop",
    ("left_turn", {"radius": 3.0}),
    ("right_turn", {"radius": 7.0}),
    "constant_acceleration",
    ("straight", {"noise_density": 0.5}),
    ("stop", {"noise_density": 0.01}),
    ("left_turn", {"radius": 300.0, "noise_density": 0.1}),
    ("constant_acceleration", {"noise_density": 0.2}),
    "coordinated_turn",
    "speed_change",
]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("steps", [0.1, [0.1, 2.0, 0.5, 10.0, 0.1, 3.0]], ids=["one step", "a step per row"])
def test_vectorized_transition_bank_equals_the_stacked_transitions(mode, steps):
    """One Δt for all rows, or one per row (runs of irregular time stamps stepping together)."""
    from hybridtrack.core.interfaces import MotionModel, TransitionBank
    from hybridtrack.core.plugins import resolve

    model = resolve("motion_model", mode)
    states = np.random.default_rng(5).normal(size=(6, model.state_dim))
    states[0, [1, model.layout.index("vy")]] = 0.0  # zero speed: ω = 0, the straight motion
    fast = model.transition_bank(steps, states)
    reference = MotionModel.transition_bank(model, steps, states)
    taus = np.broadcast_to(steps, (6,))
    stacked = TransitionBank.stack([model.transition(float(t), x) for t, x in zip(taus, states)])
    for name in ("F", "B", "Q"):
        np.testing.assert_allclose(getattr(fast, name), getattr(stacked, name), **TOL, err_msg=name)
        np.testing.assert_allclose(getattr(reference, name), getattr(stacked, name), **TOL, err_msg=name)
    if fast.noise_root is not None:  # a factor of Q (the stacked one is G chol(Q_w), the same for these models)
        np.testing.assert_allclose(fast.noise_root @ np.swapaxes(fast.noise_root, -1, -2), stacked.Q, rtol=0, atol=1e-12)


def test_a_bad_step_in_a_per_row_bank_is_named():
    from hybridtrack.core.plugins import resolve

    states = np.zeros((3, 4))
    with pytest.raises(ValueError, match=r"tau: expected step lengths in seconds, finite and > 0, got tau\[1\] = -1.0"):
        resolve("motion_model", "straight").transition_bank([0.1, -1.0, 0.1], states)
    with pytest.raises(ValueError, match="tau: a step of 1e\\+80 s gives the 'constant_acceleration' transition"):
        resolve("motion_model", "constant_acceleration").transition_bank([0.1, 1e80], np.zeros((2, 6)))


def test_simulate_trajectories_draw_what_each_run_draws():
    from hybridtrack.engine.simulate import simulate_trajectories, simulate_trajectory

    schedule = Schedule.from_rows([("straight", 6), ("left_turn", 7, 3.0), ("right_turn", 5, 4.0)])
    seeds = [np.random.SeedSequence(7, spawn_key=(i,)) for i in range(3)]
    batch = simulate_trajectories(schedule, X0, 0.1, seeds=[np.random.default_rng(s) for s in seeds], noise_cov=NOISE)
    for s, b in zip(seeds, batch):
        single = simulate_trajectory(schedule, X0, 0.1, seed=np.random.default_rng(s), noise_cov=NOISE)
        np.testing.assert_allclose(b.states, single.states, **TOL)
        np.testing.assert_array_equal(b.segment, single.segment)
        assert b.layout == single.layout
    with pytest.raises(ValueError, match="seeds"):
        simulate_trajectories(schedule, X0, 0.1, seeds=[])
