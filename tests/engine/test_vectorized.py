"""Vectorized helpers equal their per-item forms to 1e-12: a motion model's transition bank against its stacked
transitions, and simulate_trajectories against simulate_trajectory of each seed."""

import numpy as np
import pytest

from hybridtrack import Schedule

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
TOL = dict(rtol=0, atol=1e-12)


@pytest.mark.parametrize("mode", ["straight", "stop", ("left_turn", {"radius": 3.0}), ("right_turn", {"radius": 7.0})])
def test_vectorized_transition_bank_equals_the_stacked_transitions(mode):
    from hybridtrack.core.interfaces import MotionModel, TransitionBank
    from hybridtrack.core.plugins import resolve

    model = resolve("motion_model", mode)
    states = np.random.default_rng(5).normal(size=(6, 4))
    states[0, [1, 3]] = 0.0  # zero speed: ω = 0, the straight motion
    fast = model.transition_bank(0.1, states)
    reference = MotionModel.transition_bank(model, 0.1, states)
    stacked = TransitionBank.stack([model.transition(0.1, x) for x in states])
    for name in ("F", "B", "Q", "noise_root"):
        np.testing.assert_allclose(getattr(fast, name), getattr(stacked, name), **TOL, err_msg=name)
        np.testing.assert_allclose(getattr(reference, name), getattr(stacked, name), **TOL, err_msg=name)


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
