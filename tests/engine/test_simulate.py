"""Simulator: reproducibility, schedules, measurements, bad input."""

import numpy as np
import pytest

from hybridtrack import SEED001_TABLE1, Schedule
from hybridtrack.engine.simulate import simulate, simulate_measurements, simulate_trajectory
from hybridtrack.sdk.linalg import psd_square_root
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = [0, 0, 0, 2]


def network():
    return [PositionSensor(name="a"), PositionSensor(name="b", components="x", noise_cov=[[0.5]])]


def test_same_seed_gives_identical_arrays():
    first = simulate(SEED001_TABLE1, X0, 0.1, network(), seed=7, noise_cov=np.diag([1e-3, 1e-3]))
    second = simulate(SEED001_TABLE1, X0, 0.1, network(), seed=7, noise_cov=np.diag([1e-3, 1e-3]))
    assert np.array_equal(first[0].states, second[0].states)
    for name in ("a", "b"):
        assert np.array_equal(first[1][name], second[1][name])
    third = simulate(SEED001_TABLE1, X0, 0.1, network(), seed=8, noise_cov=np.diag([1e-3, 1e-3]))
    assert not np.array_equal(first[0].states, third[0].states)


def test_a_generator_seeds_simulate_reproducibly():
    first = simulate(SEED001_TABLE1, X0, 0.1, network(), seed=np.random.default_rng(11))
    second = simulate(SEED001_TABLE1, X0, 0.1, network(), seed=np.random.default_rng(11))
    assert np.array_equal(first[0].states, second[0].states) and np.array_equal(first[1]["a"], second[1]["a"])
    assert not np.array_equal(first[0].states, simulate(SEED001_TABLE1, X0, 0.1, network(), seed=12)[0].states)


def test_table1_shapes_segments_and_modes():
    trajectory = simulate_trajectory(SEED001_TABLE1, X0, 0.1, process_noise=False)
    assert trajectory.states.shape == (361, 4)
    assert trajectory.layout == ("x", "vx", "y", "vy")
    assert trajectory.modes[1:51] == ["left_turn"] * 50 and trajectory.modes[51] == "right_turn"
    np.testing.assert_allclose(trajectory.times[-1], 36.0)
    # noise-free: the speed of x0 is kept by every mode of the table
    np.testing.assert_allclose(np.hypot(trajectory.states[:, 1], trajectory.states[:, 3]), 2.0, atol=1e-9)


def test_process_noise_statistics():
    """The velocity increments of a straight run have covariance τ-independent Q (G selects velocities)."""
    Q = np.array([[0.04, 0.01], [0.01, 0.09]])
    trajectory = simulate_trajectory(Schedule.from_rows([("straight", 20000)]), X0, 0.1, seed=3, noise_cov=Q)
    increments = np.diff(trajectory.states_in(("vx", "vy")), axis=0)
    np.testing.assert_allclose(np.cov(increments.T), Q, atol=0.004)


def test_measurement_noise_statistics_and_shapes():
    trajectory = simulate_trajectory(Schedule.from_rows([("straight", 5000)]), X0, 0.1, process_noise=False)
    z = simulate_measurements(trajectory, network(), seed=1)
    assert z["a"].shape == (5001, 2) and z["b"].shape == (5001, 1)
    np.testing.assert_allclose(np.var(z["b"][:, 0] - trajectory.states[:, 0]), 0.5, rtol=0.06)
    np.testing.assert_allclose(np.cov((z["a"] - trajectory.positions).T), np.diag([0.01, 0.01]), atol=1e-3)


def test_psd_square_root_handles_singular_q():
    L = psd_square_root(np.zeros((2, 2)))
    assert np.all(L == 0)
    Q = np.array([[1.0, 1.0], [1.0, 1.0]])
    np.testing.assert_allclose(psd_square_root(Q) @ psd_square_root(Q).T, Q, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"x0": [0, 0, 0]}, "x0"),
        ({"x0": [0, np.nan, 0, 1]}, "x0"),
        ({"tau": 0}, "tau"),
        ({"tau": float("inf")}, "tau"),
        ({"noise_cov": [[1, 2], [0, 1]]}, "noise_cov"),
    ],
)
def test_bad_input_is_named(kwargs, message):
    arguments = {"x0": X0, "tau": 0.1, **kwargs}
    with pytest.raises(ValueError, match=message):
        simulate_trajectory(SEED001_TABLE1, arguments.pop("x0"), arguments.pop("tau"), **arguments)


def test_unknown_mode_lists_known_modes():
    with pytest.raises(KeyError, match="known: .*left_turn"):
        simulate_trajectory(Schedule.from_rows([("zigzag", 3)]), X0, 0.1)


def test_turn_without_radius_uses_model_default_and_bad_radius_is_named():
    with pytest.raises(ValueError, match="radius"):
        Schedule.from_rows([("left_turn", 3, -1.0)])


def test_network_stacks_and_splits():
    net = SensorNetwork(network())
    assert net.measurement_dim == 3
    H = net.jacobian(np.zeros(4), ("x", "vx", "y", "vy"))
    np.testing.assert_array_equal(H, [[1, 0, 0, 0], [0, 0, 1, 0], [1, 0, 0, 0]])
    np.testing.assert_array_equal(net.noise_cov(), np.diag([0.01, 0.01, 0.5]))
    z = net.stack({"a": np.ones((4, 2)), "b": np.zeros((4, 1))})
    assert z.shape == (4, 3)
    assert np.array_equal(net.split(z)["b"], np.zeros((4, 1)))
    with pytest.raises(ValueError, match="unique"):
        SensorNetwork([PositionSensor(name="a"), PositionSensor(name="a")])
    with pytest.raises(ValueError, match="no data for sensors \\['b'\\]"):
        net.stack({"a": np.ones((4, 2))})
    with pytest.raises(ValueError, match=r"measurements\['a'\]: expected shape \(\*, 2\)"):
        net.stack({"a": np.ones((4, 3)), "b": np.zeros((4, 1))})
    with pytest.raises(ValueError, match="different numbers of steps"):
        net.stack({"a": np.ones((4, 2)), "b": np.zeros((5, 1))})


def test_schedule_from_toml(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[[segment]]\nmode = "straight"\nsteps = 4\n\n[[segment]]\nmode = "left_turn"\nsteps = 3\nradius = 2.5\n')
    schedule = Schedule.from_toml(path)
    assert [s.mode for s in schedule.segments] == ["straight", "left_turn"] and schedule.segments[1].radius == 2.5
    assert schedule.total_steps == 7 and schedule.switch_steps() == [0, 4]
    bad = tmp_path / "bad.toml"
    bad.write_text('[[segment]]\nmode = "straight"\nsteps = 0\n')
    with pytest.raises(ValueError, match="row 0"):
        Schedule.from_toml(bad)


def test_times_propagate_each_step_with_its_own_interval():
    schedule = Schedule.from_rows([("straight", 6), ("left_turn", 8, 3.0), ("constant_acceleration", 5)])
    times = np.concatenate([[0.0], np.cumsum(np.random.default_rng(2).uniform(0.05, 2.0, schedule.total_steps))])
    trajectory = simulate_trajectory(schedule, X0, times=times, process_noise=False)
    assert np.array_equal(trajectory.times, times) and trajectory.tau is None
    assert trajectory.states.shape == (20, 6) and list(trajectory.segment) == [0] * 7 + [1] * 8 + [2] * 5
    # noise-free straight: x, y move by v·Δt_k; the turn keeps the speed
    assert trajectory.layout == ("x", "vx", "y", "vy", "ax", "ay")
    np.testing.assert_allclose(trajectory.positions[:7, 1], 2.0 * times[:7], rtol=1e-12)
    velocity = trajectory.states_in(("vx", "vy"))
    np.testing.assert_allclose(np.hypot(*velocity[6:15].T), 2.0, rtol=1e-12)
    # a turn of radius r covers the arc |v|·(t_end − t_switch): the chord from the switch point follows
    angle = 2.0 * (times[14] - times[6]) / 3.0
    chord = np.hypot(*(trajectory.positions[14] - trajectory.positions[6]))
    np.testing.assert_allclose(chord, 2 * 3.0 * np.sin(angle / 2), rtol=1e-10)


def test_regular_times_agree_with_tau_and_keep_the_reproducibility():
    tau_run = simulate(SEED001_TABLE1, X0, 0.1, network(), seed=5, noise_cov=np.diag([1e-3, 1e-3]))
    times = np.arange(SEED001_TABLE1.total_steps + 1) * 0.1
    times_run = simulate(SEED001_TABLE1, X0, sensors=network(), times=times, seed=5, noise_cov=np.diag([1e-3, 1e-3]))
    np.testing.assert_allclose(times_run[0].states, tau_run[0].states, rtol=0, atol=1e-9)
    np.testing.assert_allclose(times_run[1]["a"], tau_run[1]["a"], rtol=0, atol=1e-9)
    assert np.array_equal(times_run[0].times, times) and np.array_equal(tau_run[0].times, times)
    again = simulate(SEED001_TABLE1, X0, sensors=network(), times=times, seed=5, noise_cov=np.diag([1e-3, 1e-3]))
    assert np.array_equal(again[0].states, times_run[0].states)


def test_times_trajectory_saves_nan_tau(tmp_path):
    times = [0.0, 0.5, 0.6, 2.0]
    simulate_trajectory(Schedule.from_rows([("straight", 3)]), X0, times=times).save_npz(tmp_path / "t.npz")
    with np.load(tmp_path / "t.npz") as data:
        assert np.isnan(data["tau"]) and np.array_equal(data["times"], times)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"times": [0.0, 1.0, 1.0, 2.0]}, r"times: time at index 2 \(.*1.0\)+ is a duplicate of the time at index 1"),
        ({"times": [0.0, 1.0, 0.5, 2.0]}, r"times: time at index 2 \(.*0.5\)+ is earlier than"),
        ({"times": [0.0, np.nan, 1.0, 2.0]}, "times: time at index 1 is nan"),
        ({"times": [0.0, 1.0, 2.0, np.inf]}, "times: time at index 3 is inf"),
        ({"times": [0.0, 1.0, 2.0]}, "times: expected 4 times .* got 3"),
        ({"times": [0.0, 1.0, 2.0, 3.0], "tau": 0.1}, "either"),
        ({}, "tau"),
    ],
)
def test_bad_times_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        simulate_trajectory(Schedule.from_rows([("straight", 3)]), X0, **kwargs)
    with pytest.raises(ValueError, match=message):
        simulate(Schedule.from_rows([("straight", 3)]), X0, sensors=network(), **kwargs)
