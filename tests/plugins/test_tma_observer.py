"""Observer simulator and the seed 002 scenario."""

import numpy as np
import pytest

from hybridtrack_plugins.solvers.observer import Leg, ObserverPath, Seed002Scenario, Turn, simulate_bearings
from hybridtrack_plugins.solvers.tma_model import kinematics


def test_seed_scenario_timeline():
    scenario = Seed002Scenario()
    path = scenario.observer_path()
    assert path.duration == pytest.approx(1200.0)
    assert [p.duration for p in path.pieces] == pytest.approx([180, 180, 300, 360, 180])
    times = scenario.times()
    assert len(times) == 600 and times[0] == 0 and times[-1] == 1198
    # the first turn 0° → 270° goes left (decreasing course): the shortest way
    assert path.pieces[1].rate < 0
    assert np.rad2deg(path.course(np.array([270.0]))[0]) == pytest.approx(-45.0)
    assert np.rad2deg(path.course(np.array([500.0]))[0]) == pytest.approx(-90.0)
    assert np.rad2deg(path.course(np.array([1100.0]))[0]) == pytest.approx(90.0)


def test_speed_and_continuity():
    scenario = Seed002Scenario()
    path = scenario.observer_path()
    t = np.linspace(0, 1199, 50_001)
    xy = path.position(t)
    speed = np.linalg.norm(np.diff(xy, axis=0), axis=1) / np.diff(t)
    np.testing.assert_allclose(speed, 5.0, rtol=1e-6)
    # heading of the displacement equals the course (north convention: atan2(dx, dy))
    mid = 0.5 * (t[1:] + t[:-1])
    heading = np.arctan2(*np.diff(xy, axis=0).T)
    np.testing.assert_allclose(np.angle(np.exp(1j * (heading - path.course(mid)))), 0.0, atol=1e-4)
    # legs: 900 m north first
    np.testing.assert_allclose(path.position(np.array([180.0]))[0], [0.0, 900.0], atol=1e-9)


def test_tie_breaking_of_a_half_turn():
    right = Seed002Scenario(tie="right").observer_path()
    left = Seed002Scenario(tie="left").observer_path()
    assert right.pieces[3].rate > 0 > left.pieces[3].rate
    assert right.position(np.array([840.0]))[0, 1] > left.position(np.array([840.0]))[0, 1]  # right passes north


def test_explicit_turn_directions_and_errors():
    path = ObserverPath.build([Leg(10, 10), Turn(350, 1.0, "right")], speed=1.0)
    assert path.pieces[1].duration == pytest.approx(340.0)
    with pytest.raises(ValueError, match="insert a Turn"):
        ObserverPath.build([Leg(0, 10), Leg(90, 10)], speed=1.0)
    with pytest.raises(ValueError, match="start with a Leg"):
        ObserverPath.build([Turn(90)], speed=1.0)
    with pytest.raises(ValueError, match="rate"):
        ObserverPath.build([Leg(0, 10), Turn(90, 0.0)], speed=1.0)


def test_targets_drawn_as_the_seed_says():
    scenario = Seed002Scenario()
    theta = scenario.draw_targets(np.random.default_rng(0), 2000)
    bearing, rng_, course, speed = kinematics(theta, 0.0, 0.0, scenario.observer()[0])
    np.testing.assert_allclose(bearing, 0.0, atol=1e-12)
    assert rng_.min() >= 5000 and rng_.max() <= 50000
    assert np.rad2deg(course).min() >= 0 and np.rad2deg(course).max() <= 180
    assert speed.min() >= 5 and speed.max() <= 15
    prior = kinematics(scenario.prior_theta(), 0.0, 0.0, scenario.observer()[0])
    np.testing.assert_allclose([prior[0], prior[1], np.rad2deg(prior[2]), prior[3]], [0, 25000, 90, 10], atol=1e-9)


def test_simulated_bearings_noise():
    scenario = Seed002Scenario()
    theta = scenario.draw_targets(np.random.default_rng(0), 1)[0]
    times, observer = scenario.times(), scenario.observer()
    exact = simulate_bearings(theta, times, observer, 0.0, np.random.default_rng(1))
    noisy = simulate_bearings(theta, times, observer, np.deg2rad(1.0), np.random.default_rng(1))
    residual = np.angle(np.exp(1j * (noisy - exact)))
    assert np.rad2deg(residual.std()) == pytest.approx(1.0, rel=0.1)
    with pytest.raises(ValueError, match="sigma"):
        simulate_bearings(theta, times, observer, -1.0, np.random.default_rng(1))
