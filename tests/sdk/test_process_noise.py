"""Process noise per second (hybridtrack.sdk.process_noise and the linear modes' ``noise_density``) against
FilterPy's ``Q_continuous_white_noise`` and Stone Soup's ConstantVelocity / ConstantAcceleration to 1e-12, the
hand-derived stop random walk, and the defining property of a continuous model: two steps of Δt/2 add up to
one step of Δt."""

from datetime import timedelta

import numpy as np
import pytest
from filterpy.common import Q_continuous_white_noise
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel
from stonesoup.models.transition.linear import ConstantAcceleration as StoneSoupCA
from stonesoup.models.transition.linear import ConstantVelocity as StoneSoupCV

from hybridtrack.sdk.process_noise import white_noise_covariance, white_noise_root, white_noise_unit
from hybridtrack.testing import check_motion_model
from hybridtrack_plugins.motion.linear_modes import ConstantAcceleration, LeftTurn, RightTurn, Stop, Straight

STEPS = (1e-3, 0.37, 2.0, 10.0, 200.0)


def _rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("dt", STEPS)
def test_block_equals_filterpy(order, dt):
    assert _rel(white_noise_covariance(dt, 0.7, order), Q_continuous_white_noise(order, dt, 0.7)) < 1e-12
    root = white_noise_root(dt, order)
    assert _rel(root @ root.T, white_noise_unit(dt, order)) < 1e-12


def test_order_one_is_a_random_walk_and_arrays_of_steps_stack():
    assert white_noise_covariance(4.0, 0.5, 1).tolist() == [[2.0]]
    stacked = white_noise_unit(np.array(STEPS), 2)
    assert stacked.shape == (len(STEPS), 2, 2)
    for k, dt in enumerate(STEPS):
        assert np.array_equal(stacked[k], white_noise_unit(dt, 2))


@pytest.mark.parametrize("dt", STEPS)
def test_modes_equal_filterpy_and_stone_soup(dt):
    q = 0.05
    for model, order, peer in ((Straight(noise_density=q), 2, StoneSoupCV), (ConstantAcceleration(noise_density=q), 3, StoneSoupCA)):
        Q = model.transition(dt).process_noise
        assert _rel(Q, Q_continuous_white_noise(order, dt, q, block_size=2)) < 1e-12, model
        stone = CombinedLinearGaussianTransitionModel([peer(q), peer(q)]).covar(time_interval=timedelta(seconds=dt))
        assert _rel(Q, np.asarray(stone, dtype=float)) < 1e-12, model
    for turn in (LeftTurn(radius=300.0, noise_density=q), RightTurn(radius=300.0, noise_density=q)):  # the CV Q (docstring)
        Q = turn.transition(dt, np.array([0.0, 3.0, 0.0, 4.0])).process_noise
        assert _rel(Q, Q_continuous_white_noise(2, dt, q, block_size=2)) < 1e-12


@pytest.mark.parametrize("dt", STEPS)
def test_stop_is_a_position_random_walk(dt):
    """p⁺ = p + w, v⁺ = w/Δt, w ~ N(0, q Δt): Q_axis = q [[Δt, 1], [1, 1/Δt]], the velocity forgotten."""
    q = 0.02
    T = Stop(noise_density=q).transition(dt)
    axis = q * np.array([[dt, 1.0], [1.0, 1.0 / dt]])
    expected = np.zeros((4, 4))
    expected[:2, :2] = expected[2:, 2:] = axis
    assert _rel(T.process_noise, expected) < 1e-12
    assert np.array_equal(T.F @ np.array([5.0, 1.0, 7.0, -2.0]), [5.0, 0.0, 7.0, 0.0])


@pytest.mark.parametrize("model", [Straight(noise_density=0.3), ConstantAcceleration(noise_density=0.3), Stop(noise_density=0.3)])
def test_two_half_steps_make_one_step(model):
    """Q(Δt) = F(Δt/2) Q(Δt/2) F(Δt/2)ᵀ + Q(Δt/2): the noise of a step depends on its length only, not on how
    the reports cut it (what a per-step Q gets wrong on irregular reports)."""
    half, whole = model.transition(5.0), model.transition(10.0)
    if isinstance(model, Stop):  # the walk forgets the velocity: position variances add, q Δt
        assert half.process_noise[0, 0] * 2 == pytest.approx(whole.process_noise[0, 0], rel=1e-12)
        return
    two = half.F @ half.process_noise @ half.F.T + half.process_noise
    assert _rel(two, whole.process_noise) < 1e-12


def test_per_step_noise_stays_the_seed_default():
    assert np.array_equal(Straight().noise_cov, [[0.01, 0.0], [0.0, 0.01]])
    T = Straight().transition(3.0)
    assert np.array_equal(T.process_noise, np.diag([0.0, 0.01, 0.0, 0.01]))


def test_density_models_meet_the_contract():
    for model in (
        Straight(noise_density=0.1),
        ConstantAcceleration(noise_density=0.1),
        Stop(noise_density=0.1),
        LeftTurn(noise_density=0.1),
    ):
        check_motion_model(model)
        assert np.array_equal(model.noise_cov, 0.1 * np.eye(len(model.noise_cov)))  # w ~ N(0, q I), G(Δt) the rest


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise_cov": np.eye(2) * 0.01, "noise_density": 0.1}, "not both"),
        ({"noise_density": -1.0}, r"noise_density: expected a noise density .* got -1.0"),
        ({"noise_density": float("nan")}, "noise_density"),
        ({"noise_density": "fast"}, "noise_density.*'fast'"),
    ],
)
def test_bad_noise_is_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Straight(**kwargs)


@pytest.mark.parametrize(("dt", "order"), [(0.0, 2), (-1.0, 2), (float("inf"), 2), (1.0, 4)])
def test_bad_steps_and_orders_are_named(dt, order):
    with pytest.raises(ValueError, match="dt|order"):
        white_noise_unit(dt, order)
