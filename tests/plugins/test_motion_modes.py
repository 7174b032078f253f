"""The five linear motion modes against hand-derived geometry (SPEC §1)."""

import numpy as np
import pytest

from hybridtrack import Schedule
from hybridtrack.engine.simulate import simulate_trajectory
from hybridtrack_plugins.motion.linear_modes import ConstantAcceleration, LeftTurn, RightTurn, Stop, Straight

TAU = 0.1


def run(model, x0, steps=400, tau=TAU):
    transition = model.transition(tau, np.asarray(x0, float))
    xs = [np.asarray(x0, float)]
    for _ in range(steps):
        xs.append(transition.apply(xs[-1]))
    return np.array(xs)


@pytest.mark.parametrize("cls, sign", [(LeftTurn, 1), (RightTurn, -1)])
@pytest.mark.parametrize("x0", [[0, 0, 0, 2], [3, -1.5, -2, 0.7], [100, 7, -50, -3]])
@pytest.mark.parametrize("radius", [1.0, 5.0, 37.5])
def test_noise_free_turn_keeps_speed_and_radius(cls, sign, x0, radius):
    model = cls(radius=radius)
    xs = run(model, x0)
    speed = np.hypot(xs[:, 1], xs[:, 3])
    centre = model.turn_centre(np.asarray(x0, float))
    distance = np.hypot(xs[:, 0] - centre[0], xs[:, 2] - centre[1])
    np.testing.assert_allclose(speed, speed[0], rtol=0, atol=1e-9 * max(1, speed[0]))
    np.testing.assert_allclose(distance, radius, rtol=0, atol=1e-9 * max(1, radius))
    # the heading turns the right way: cross(v0, v1) has the sign of the direction
    cross = xs[0, 1] * xs[1, 3] - xs[0, 3] * xs[1, 1]
    assert np.sign(cross) == sign


def test_turn_centre_is_on_the_turn_side():
    x0 = np.array([0.0, 0.0, 0.0, 2.0])  # heading north
    np.testing.assert_allclose(LeftTurn(radius=3).turn_centre(x0), [-3, 0])
    np.testing.assert_allclose(RightTurn(radius=3).turn_centre(x0), [3, 0])


def test_turn_matches_seed_000_formula_for_B():
    """B as printed in seed 000 for the left turn: [(x1 − x4/ω)(1 − cos), (ω x1 − x4) sin, (x3 + x2/ω)(1 − cos), (ω x3 + x2) sin]."""
    x = np.array([1.3, 0.4, -2.0, 1.1])
    model = LeftTurn(radius=2.5)
    w = np.hypot(x[1], x[3]) / 2.5
    c, s = np.cos(w * TAU), np.sin(w * TAU)
    expected = [(x[0] - x[3] / w) * (1 - c), (w * x[0] - x[3]) * s, (x[2] + x[1] / w) * (1 - c), (w * x[2] + x[1]) * s]
    np.testing.assert_allclose(model.transition(TAU, x).B, expected, rtol=1e-12)
    right = RightTurn(radius=2.5).transition(TAU, x).B
    expected_right = [(x[0] + x[3] / w) * (1 - c), (w * x[0] + x[3]) * s, (x[2] - x[1] / w) * (1 - c), (w * x[2] - x[1]) * s]
    np.testing.assert_allclose(right, expected_right, rtol=1e-12)


def test_turn_at_zero_speed_is_finite_and_still():
    transition = LeftTurn(radius=2).transition(TAU, np.array([1.0, 0.0, 2.0, 0.0]))
    assert np.all(np.isfinite(transition.F)) and np.all(np.isfinite(transition.B))
    np.testing.assert_allclose(transition.apply(np.array([1.0, 0.0, 2.0, 0.0])), [1, 0, 2, 0])


def test_straight_and_constant_acceleration_kinematics():
    xs = run(Straight(), [1, 2, 3, -1], steps=10)
    np.testing.assert_allclose(xs[-1], [1 + 2 * 10 * TAU, 2, 3 - 10 * TAU, -1])
    x0 = np.array([0, 1, 0.5, 0, 0, -0.2])
    xs = run(ConstantAcceleration(), x0, steps=20)
    t = 20 * TAU
    np.testing.assert_allclose(xs[-1], [t + 0.25 * t * t, 1 + 0.5 * t, 0.5, -0.1 * t * t, -0.2 * t, -0.2], atol=1e-12)


def test_stop_holds_position_and_zeroes_velocity():
    xs = run(Stop(), [4, 3, -1, 2], steps=3)
    np.testing.assert_allclose(xs[1:], [[4, 0, -1, 0]] * 3)


def test_noise_gain_and_covariance():
    assert Straight().transition(TAU, np.zeros(4)).G.tolist() == [[0, 0], [1, 0], [0, 0], [0, 1]]
    assert ConstantAcceleration().transition(TAU, np.zeros(6)).G[[2, 5]].tolist() == [[1, 0], [0, 1]]
    np.testing.assert_allclose(Straight(noise_cov=np.diag([2.0, 3.0])).transition(TAU, np.zeros(4)).process_noise, np.diag([0, 2, 0, 3]))


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: LeftTurn(radius=0), "radius"),
        (lambda: RightTurn(radius=float("nan")), "radius"),
        (lambda: Straight(noise_cov=[[1, 0.5], [0, 1]]), "noise_cov"),
        (lambda: Straight(noise_cov=[[1, 0], [0, -1]]), "noise_cov"),
        (lambda: Straight(noise_cov=np.eye(3)), "noise_cov"),
        (lambda: Straight().transition(0, np.zeros(4)), "tau"),
        (lambda: LeftTurn().transition(0.1, np.zeros(3)), "switch_state"),
        (lambda: LeftTurn().transition(0.1, [0, np.nan, 0, 1]), "switch_state"),
    ],
)
def test_bad_parameters_are_named(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_mode_switches_keep_position_continuous_including_ca():
    schedule = Schedule.from_rows(
        [
            ("straight", 15),
            {"mode": "constant_acceleration", "steps": 20, "acceleration": (0.4, -0.3)},
            ("left_turn", 25, 2.0),
            {"mode": "constant_acceleration", "steps": 10},
            ("right_turn", 20, 4.0),
            ("stop", 5),
            ("straight", 5),
        ]
    )
    trajectory = simulate_trajectory(schedule, [0, 1, 0, 0.5], TAU, process_noise=False)
    positions = trajectory.positions
    velocities = trajectory.states_in(("vx", "vy"))
    speed = np.hypot(*velocities.T)
    jumps = np.hypot(*np.diff(positions, axis=0).T)
    # a step moves at most (max speed + acceleration) · τ: no teleport at the switches
    assert np.all(jumps <= (speed[:-1].max() + 1.0) * TAU + 1e-12)
    # the position reached at the switch is the starting point of the next mode: the first step
    # of the new mode departs from it by v·τ plus at most ½ a_max τ² (a_max: |a| or v²/r)
    a_max = max(0.5, speed.max() ** 2 / 2.0)
    for k, segment in zip(schedule.switch_steps()[1:], schedule.segments[1:]):
        expected_move = 0 if segment.mode == "stop" else velocities[k] * TAU
        np.testing.assert_allclose(positions[k + 1], positions[k] + expected_move, atol=0.5 * a_max * TAU**2)
    assert trajectory.layout == ("x", "vx", "y", "vy", "ax", "ay")
    ca = np.array(trajectory.segment) == 1
    np.testing.assert_allclose(trajectory.states_in(("ax", "ay"))[ca], [[0.4, -0.3]] * ca.sum())
    # leaving CA drops the acceleration, entering CA without a value starts from zero
    assert np.all(trajectory.states_in(("ax", "ay"))[np.array(trajectory.segment) == 3] == 0)
