"""The bearing-only sensor plugin: conventions, Jacobian, wrapping, moving observer, contract."""

import numpy as np
import pytest

from hybridtrack.core.plugins import load_plugins
from hybridtrack.testing import check_sensor
from hybridtrack_plugins.sensors.bearing import BearingSensor, angle_difference, wrap_angle

CV = ("x", "vx", "y", "vy")


def test_registered_as_bearing():
    registry = load_plugins(strict=True).registry
    assert registry.get("sensor", "bearing") is BearingSensor


@pytest.mark.parametrize(
    "convention, target, expected",
    [
        ("north", (0.0, 100.0), 0.0),  # due north
        ("north", (100.0, 0.0), np.pi / 2),  # east, clockwise from north
        ("north", (-100.0, 0.0), -np.pi / 2),
        ("north", (0.0, -100.0), np.pi),  # south maps to +π, inside (−π, π]
        ("math", (100.0, 0.0), 0.0),
        ("math", (0.0, 100.0), np.pi / 2),  # counter-clockwise from +x
    ],
)
def test_conventions(convention, target, expected):
    sensor = BearingSensor(sigma=0.01, observer=(10.0, -5.0), convention=convention)
    x = np.array([10.0 + target[0], 1.0, -5.0 + target[1], 2.0])
    assert sensor.measure(x, CV)[0] == pytest.approx(expected, abs=1e-12)


def test_default_convention_is_the_seeds_north():
    assert BearingSensor().convention == "north"


@pytest.mark.parametrize("convention", ["north", "math"])
@pytest.mark.parametrize("layout", [CV, ("x", "y"), ("vx", "y", "x", "vy", "ax")])
def test_jacobian_matches_finite_differences(convention, layout):
    rng = np.random.default_rng(3)
    sensor = BearingSensor(sigma=0.01, observer=(3.0, 4.0), convention=convention)
    x = rng.uniform(-500, 500, len(layout))
    J = sensor.jacobian(x, layout)
    assert J.shape == (1, len(layout))
    h = 1e-4
    numeric = np.array([(sensor.measure(x + h * e, layout) - sensor.measure(x - h * e, layout))[0] / (2 * h) for e in np.eye(len(layout))])
    np.testing.assert_allclose(J[0], numeric, rtol=1e-6, atol=1e-12)
    for name, j in zip(layout, J[0]):
        if name not in ("x", "y"):
            assert j == 0.0


def test_residual_and_wrap_stay_in_half_open_interval():
    sensor = BearingSensor(sigma=0.01)
    assert sensor.residual(np.pi - 0.01, -np.pi + 0.01) == pytest.approx(-0.02)
    angles = np.array([np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 7.0, -7.0, 0.0])
    wrapped = wrap_angle(angles)
    assert np.all((wrapped > -np.pi) & (wrapped <= np.pi))
    np.testing.assert_allclose(np.cos(wrapped), np.cos(angles), atol=1e-12)
    np.testing.assert_allclose(np.sin(wrapped), np.sin(angles), atol=1e-12)
    a, b = np.array([3.0, -3.0, 0.5]), np.array([-3.0, 3.0, 0.25])
    np.testing.assert_allclose(angle_difference(a, b), wrap_angle(a - b))


def test_simulate_wraps_and_has_noise_sigma():
    sigma = np.deg2rad(2.0)
    sensor = BearingSensor(sigma=sigma, observer=(0.0, 0.0))
    south = np.broadcast_to([0.0, 0.0, -1000.0, 0.0], (4000, 4))  # bearing π: noise crosses ±π
    z = sensor.simulate(south, CV, np.random.default_rng(0))[:, 0]
    assert np.all((z > -np.pi) & (z <= np.pi))
    noise = sensor.residual(z, np.pi)
    assert abs(noise.std() - sigma) < 0.05 * sigma
    assert abs(noise.mean()) < 4 * sigma / np.sqrt(len(z))


def test_moving_observer_per_step_equals_trajectory_broadcast():
    rng = np.random.default_rng(1)
    observer = rng.uniform(-100, 100, (6, 2))
    states = rng.uniform(1000, 2000, (6, 4))
    sensor = BearingSensor(sigma=0.01, observer=observer)
    whole = sensor.measure(states, CV)
    jac = sensor.jacobian(states, CV)
    base = BearingSensor(sigma=0.01)
    for k in range(6):
        step = base.at(observer[k])
        np.testing.assert_allclose(step.measure(states[k], CV), whole[k])
        np.testing.assert_allclose(step.jacobian(states[k], CV), jac[k])


def test_contract():
    check_sensor(BearingSensor(sigma=0.02, observer=(1.0, 2.0)))
    check_sensor(BearingSensor(sigma=0.02, convention="math"), layout=("x", "y"))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"sigma": 0.0}, "sigma"),
        ({"sigma": float("nan")}, "sigma"),
        ({"convention": "south"}, "convention"),
        ({"observer": (1.0, 2.0, 3.0)}, "observer"),
        ({"observer": (np.nan, 0.0)}, "observer"),
    ],
)
def test_bad_parameters(kwargs, message):
    with pytest.raises(ValueError, match=message):
        BearingSensor(**kwargs)


def test_layout_without_position():
    with pytest.raises(ValueError, match="'x' and 'y'"):
        BearingSensor().measure(np.zeros(2), ("vx", "vy"))
