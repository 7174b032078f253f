"""One FilterBank holding filters of 4-, 5- and 6-state layouts, grouped by layout, against one bank per layout."""

from __future__ import annotations

import numpy as np
import pytest

from hybridtrack.engine.bank import FilterBank, LayoutBank
from hybridtrack.engine.layouts import LayoutFill, union_layout
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.motion.linear_modes import LAYOUT_4, LAYOUT_6, ConstantAcceleration, LeftTurn, Straight
from hybridtrack_plugins.motion.ship import ShipTurn
from hybridtrack_plugins.sensors.position import PositionSensor

SENSORS = [PositionSensor(noise_cov=np.diag([4.0, 9.0]))]
NOISE = np.eye(2) * 0.05


def models():
    """A 4-state straight and left turn, the 6-state constant acceleration and the 5-state ship turn (ω in the state)."""
    return [Straight(noise_cov=NOISE), ConstantAcceleration(noise_cov=NOISE), LeftTurn(radius=300.0, noise_cov=NOISE), ShipTurn()]


def starts(layout, F, seed=0):
    rng = np.random.default_rng(seed)
    n = len(layout)
    x = rng.normal(size=(F, n)) * 10.0
    x[:, layout.index("vx")] += 8.0
    A = rng.normal(size=(F, n, n)) * 0.3
    return x, A @ np.swapaxes(A, 1, 2) + np.eye(n)


def reference(model, layout, x, P, run, dt, z):
    """The filters of one model alone in a LayoutBank of the model's layout, started at the marginal of (x, P)."""
    fill = LayoutFill(layout)
    pos = fill.positions(model.layout)
    bank = LayoutBank(KalmanFilter(), model.layout, SENSORS)
    bank.start(x[:, pos], P[:, pos[:, None], pos], [model] * len(x), x[:, pos], run)
    step = bank.step(dt, z)
    return fill.expand(bank.means, bank.covs, pos), step.loglik


def test_union_of_the_four_layouts():
    layout = union_layout([m.layout for m in models()])
    assert layout == LAYOUT_4 + ("ax", "ay", "omega")  # the ordered union: no model's layout holds every other


def test_a_step_of_mixed_layouts_equals_one_bank_per_layout():
    mixed = models()
    layout = union_layout([m.layout for m in mixed])
    R, F = 3, 8
    run = np.repeat(np.arange(R), F // R + 1)[:F]
    chosen = [mixed[i % len(mixed)] for i in range(F)]
    x, P = starts(layout, F)
    bank = FilterBank(KalmanFilter(), layout, SENSORS)
    bank.start(x, P, chosen, x, run)
    assert len(bank.groups) == 3 and bank.means.shape == (F, len(layout))
    z = np.random.default_rng(1).normal(size=(R, 2)) * 5.0
    z[1, 1] = np.nan  # run 1 measures x only: the groups update by missing pattern
    dt = np.array([1.0, 2.5, 0.5])
    step = bank.step(dt, z)
    for model in mixed:
        rows = np.flatnonzero([m is model for m in chosen])
        (xr, Pr), loglik = reference(model, layout, x[rows], P[rows], run[rows], dt, z)
        np.testing.assert_allclose(bank.means[rows], xr, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(bank.covs[rows], Pr, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(step.loglik[rows], loglik, rtol=1e-12, atol=1e-12)
    assert step.innovation is None and len(step.updates) >= 4
    lacking = layout.index("ax")
    straight = np.flatnonzero([m is mixed[0] for m in chosen])
    assert np.all(bank.means[straight, lacking] == 0.0) and np.all(bank.covs[straight, lacking, lacking] == 1.0)


def test_take_add_and_assign_across_layouts():
    mixed = models()
    layout = union_layout([m.layout for m in mixed])
    x, P = starts(layout, 4, seed=3)
    bank = FilterBank(KalmanFilter(), layout, SENSORS, missing_variance=2.0)
    bank.start(x, P, [mixed[0], mixed[1], mixed[0], mixed[3]], x, [0, 0, 1, 1])
    bank.step(1.0, np.array([[1.0, 2.0], [3.0, 4.0]]))
    means, covs = bank.means.copy(), bank.covs.copy()
    bank.take([3, 0, 0, 1])  # reordered, one copied, one dropped
    np.testing.assert_array_equal(bank.means, means[[3, 0, 0, 1]])
    np.testing.assert_array_equal(bank.covs, covs[[3, 0, 0, 1]])
    bank.take([1, 2, 3, 0])  # back to run order: runs 0, 0, 0, 1
    np.testing.assert_array_equal(bank.run, [0, 0, 0, 1])
    # filter 1 moves from the straight (4) to the 6-state group: restarted from its estimate in the bank's layout
    bank.assign([1], [mixed[1]], means[0])
    assert bank.models[1] is mixed[1]
    np.testing.assert_allclose(bank.means[1], means[0], rtol=0, atol=1e-12)
    pos6 = LayoutFill(layout).positions(LAYOUT_6)
    np.testing.assert_allclose(bank.covs[1][np.ix_(pos6, pos6)], covs[0][np.ix_(pos6, pos6)], atol=1e-12)
    added = bank.add([3], [mixed[2]], means[3])  # a left turn (4) started from the ship turn's filter
    np.testing.assert_array_equal(added, [4])
    np.testing.assert_array_equal(bank.run, [0, 0, 0, 1, 1])
    np.testing.assert_allclose(bank.means[4][:4], means[3][[0, 1, 2, 3]], atol=1e-12)
    step = bank.step(1.0, np.array([[1.5, 2.5], [3.5, 4.5]]))
    assert np.all(np.isfinite(step.loglik)) and step.loglik.shape == (5,)


def test_one_layout_is_forwarded_to_its_layout_bank():
    x, P = starts(LAYOUT_4, 3)
    bank = FilterBank(KalmanFilter(), LAYOUT_4, SENSORS)
    bank.start(x, P, [Straight(noise_cov=NOISE)] * 3, x)
    single = bank.groups[LAYOUT_4]
    step = bank.step(1.0, np.array([1.0, 2.0]))
    assert step.innovation is not None and bank.state is single.state and bank.means is single.means


def test_errors_name_the_input():
    bank = FilterBank(KalmanFilter(), LAYOUT_4, SENSORS)
    with pytest.raises(ValueError, match="model 'constant_acceleration'.*not in the bank's layout"):
        bank.start(np.zeros(4), np.eye(4), [ConstantAcceleration(noise_cov=NOISE)], np.zeros(4))
    mixed = FilterBank(KalmanFilter(), LAYOUT_6, SENSORS)
    mixed.start(np.zeros(6), np.eye(6), [Straight(noise_cov=NOISE), ConstantAcceleration(noise_cov=NOISE)], np.zeros(6))
    with pytest.raises(ValueError, match="state: the bank holds filters of layouts"):
        _ = mixed.state
    with pytest.raises(ValueError, match="transitions"):
        mixed.transitions(1.0)
    with pytest.raises(ValueError, match="missing_variance"):
        FilterBank(KalmanFilter(), LAYOUT_6, SENSORS, missing_variance=0.0)
