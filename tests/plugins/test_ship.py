"""Nonlinear ship turn (SPEC §1, seed 003): f, its Jacobian, the ω → 0 limit, the MotionModel contract."""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack_plugins.motion.ship import ShipTurn

TAU = 1.0


def _numeric_jacobian(x, tau, h=1e-6):
    J = np.zeros((5, 5))
    for j in range(5):
        e = np.zeros(5)
        e[j] = h * max(1.0, abs(x[j]))
        J[:, j] = (ShipTurn.f(x + e, tau) - ShipTurn.f(x - e, tau)) / (2 * e[j])
    return J


def test_registered_and_nonlinear():
    model = ht.load_plugins(strict=True).registry.create("motion_model", "ship_turn", sigma_velocity=0.2, sigma_rate=1e-3)
    assert isinstance(model, ShipTurn) and model.linear is False
    assert model.layout == ("x", "y", "vx", "vy", "omega")


def test_zero_rate_is_constant_velocity_without_division():
    x = np.array([10.0, -5.0, 3.0, 4.0, 0.0])
    with np.errstate(all="raise"):
        out = ShipTurn.f(x, TAU)
        J = ShipTurn.jacobian(x, TAU)
    np.testing.assert_allclose(out, [13.0, -1.0, 3.0, 4.0, 0.0])
    np.testing.assert_allclose(J, _numeric_jacobian(x, TAU), atol=1e-6)


@pytest.mark.parametrize("omega", [1e-12, 1e-7, 1e-3, 9.9e-3, 1.01e-2, 0.05, -0.3])
def test_continuous_in_omega_and_jacobian_matches_differences(omega):
    x = np.array([100.0, 50.0, 7.0, -3.0, omega])
    np.testing.assert_allclose(ShipTurn.jacobian(x, TAU), _numeric_jacobian(x, TAU), rtol=1e-6, atol=1e-6)
    closed = np.array(
        [
            x[0] + (x[2] * np.sin(omega * TAU) - x[3] * (1 - np.cos(omega * TAU))) / omega,
            x[1] + (x[2] * (1 - np.cos(omega * TAU)) + x[3] * np.sin(omega * TAU)) / omega,
        ]
    )
    np.testing.assert_allclose(ShipTurn.f(x, TAU)[:2], closed, rtol=1e-9)


def test_turn_keeps_speed_and_circle():
    """Noise-free turning: |v| constant, distance to the centre (x − vy/ω, y + vx/ω) equal to |v|/|ω|."""
    x = np.array([0.0, 0.0, 5.0, 0.0, 0.1])
    centre = np.array([x[0] - x[3] / x[4], x[1] + x[2] / x[4]])
    for _ in range(50):
        x = ShipTurn.f(x, TAU)
        assert np.hypot(x[2], x[3]) == pytest.approx(5.0, rel=1e-12)
        assert np.hypot(x[0] - centre[0], x[1] - centre[1]) == pytest.approx(50.0, rel=1e-10)


def test_transition_contract_and_bank():
    model = ShipTurn(sigma_velocity=0.3, sigma_rate=2e-3)
    xs = np.array([1.0, 2.0, 3.0, -1.0, 0.02])
    t = model.transition(2.0, xs)
    np.testing.assert_allclose(t.apply(xs), model.propagate(xs, 2.0, xs), rtol=1e-12)
    np.testing.assert_allclose(t.G, [[2, 0, 0], [0, 2, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2]])
    np.testing.assert_allclose(t.Q, np.diag([0.09, 0.09, 4e-6]))
    X = np.stack([xs, xs * 2, xs * 0])
    bank = model.linearize(2.0, X)
    np.testing.assert_allclose(np.einsum("mij,mj->mi", bank.F, X) + bank.B, ShipTurn.f(X, 2.0), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(bank.noise_root @ np.swapaxes(bank.noise_root, -1, -2), bank.Q)
    np.testing.assert_allclose(bank.Q[0], t.process_noise)


def test_bad_parameters():
    with pytest.raises(ValueError, match="sigma_velocity"):
        ShipTurn(sigma_velocity=-1.0)
    with pytest.raises(ValueError, match=r"switch_state: expected shape \(5,\)"):
        ShipTurn().transition(1.0, np.zeros(4))
