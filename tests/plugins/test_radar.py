"""Radar sensors (SPEC §2, seed 003): Cartesian pseudo-measurements with converted covariance, and the polar form."""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack.sdk.linalg import wrap_angle as wrap_to_pi
from hybridtrack_plugins.sensors.radar import PolarRadarSensor, RadarSensor

LAYOUT = ("x", "y", "vx", "vy", "omega")


def test_registered():
    registry = ht.load_plugins(strict=True).registry
    assert isinstance(registry.create("sensor", "radar"), RadarSensor)
    assert isinstance(registry.create("sensor", "radar_polar"), PolarRadarSensor)


def test_angle_convention_and_round_trip():
    radar = RadarSensor(site=(100.0, -50.0))
    x = np.array([100.0, 950.0, 0, 0, 0])  # due +y from the site: θ = π/2
    np.testing.assert_allclose(radar.polar(x, LAYOUT), [1000.0, np.pi / 2])
    z = radar.to_cartesian([1000.0, np.pi / 2])
    np.testing.assert_allclose(z, [100.0, 950.0], atol=1e-9)
    np.testing.assert_allclose(radar.to_polar(z), [1000.0, np.pi / 2])
    np.testing.assert_array_equal(radar.jacobian(x, LAYOUT), [[1, 0, 0, 0, 0], [0, 1, 0, 0, 0]])


def test_converted_covariance_matches_monte_carlo():
    radar = RadarSensor(range_std=20.0, azimuth_std=np.deg2rad(0.5))
    x = np.array([3000.0, 4000.0, 0, 0, 0])
    rng = np.random.default_rng(0)
    Z = radar.simulate(np.broadcast_to(x, (200_000, 5)), LAYOUT, rng)
    empirical = np.cov(Z.T)
    R = radar.measurement_noise(radar.measure(x, LAYOUT))
    np.testing.assert_allclose(empirical, R, rtol=0.02, atol=2.0)
    assert np.allclose(R, R.T) and np.linalg.eigvalsh(R).min() > 0
    # at θ = 0 it is diag(σ_ρ², (ρ σ_θ)²)
    np.testing.assert_allclose(radar.converted_covariance([1000.0, 0.0]), np.diag([400.0, (1000 * np.deg2rad(0.5)) ** 2]), atol=1e-9)


def test_polar_jacobian_and_wrapped_residual():
    radar = PolarRadarSensor(site=(10.0, 20.0))
    x = np.array([-500.0, 300.0, 1, 2, 0.01])
    J = radar.jacobian(x, LAYOUT)
    h = 1e-4
    for j in range(5):
        e = np.zeros(5)
        e[j] = h
        np.testing.assert_allclose(J[:, j], (radar.measure(x + e, LAYOUT) - radar.measure(x - e, LAYOUT)) / (2 * h), atol=1e-9)
    nu = radar.residual(np.array([100.0, np.pi - 0.01]), np.array([90.0, -np.pi + 0.01]))
    np.testing.assert_allclose(nu, [10.0, -0.02], atol=1e-12)
    assert wrap_to_pi(np.pi) == pytest.approx(np.pi) and wrap_to_pi(-np.pi) == pytest.approx(np.pi)


def test_layout_without_positions_raises():
    with pytest.raises(ValueError, match="layout: radar needs components"):
        RadarSensor().measure(np.zeros(2), ("a", "b"))
    with pytest.raises(ValueError, match="range_std"):
        RadarSensor(range_std=0.0)
