"""NEES and NIS averages inside their 95 % χ² bounds over seeded Monte Carlo runs (Bar-Shalom et al. 2001 §5.4).

The N runs are stacked as the bank (M = N filters, one row of z per filter),
so each Monte Carlo experiment is one vectorized filter.  For the average over
N runs and K steps: N K · mean(NIS) ~ χ²(m N K) (innovations are white); for
NEES the per-step average N · mean_k ~ χ²(n N), and its average over steps is
checked against the same (wider, conservative) per-step bounds; at least 85 %
of the individual steps must also lie inside them.
"""

import numpy as np
import pytest
from scipy.stats import chi2

import hybridtrack as ht
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack_plugins.motion.ship import ShipTurn
from hybridtrack_plugins.sensors.radar import PolarRadarSensor, RadarSensor

RUNS, STEPS = 200, 100


def _bounds(dof, count):
    return chi2.ppf([0.025, 0.975], dof * count) / count


def _check(nees, nis, n, m):
    """nees, nis (K, N)."""
    K, N = nees.shape
    lo, hi = _bounds(m, N * K)
    assert lo <= nis.mean() <= hi, (nis.mean(), lo, hi)
    lo, hi = _bounds(n, N)
    per_step = nees.mean(axis=1)
    assert lo <= per_step.mean() <= hi, (per_step.mean(), lo, hi)
    assert ((per_step >= lo) & (per_step <= hi)).mean() >= 0.85
    return nees.mean(), nis.mean()


def _nees(x_true, x, P):
    e = x_true - x
    return np.einsum("mi,mi->m", e, np.linalg.solve(P, e[..., None])[..., 0])


@pytest.mark.parametrize("mode, kwargs", [("straight", {}), ("left_turn", {"radius": 5.0}), ("right_turn", {"radius": 3.0})])
@pytest.mark.parametrize("estimator", ["kalman", "srif"])
def test_linear_modes(mode, kwargs, estimator):
    registry = ht.load_plugins(strict=True).registry
    model = registry.create("motion_model", mode, noise_cov=np.eye(2) * 1e-3, **kwargs)
    sensor = registry.create("sensor", "position", noise_cov=np.diag([0.1, 0.05]))
    layout = model.layout
    rng = np.random.default_rng(len(mode) * 7 + len(estimator))
    x_switch = np.array([0.0, 0.0, 0.0, 2.0])
    t = model.transition(0.1, x_switch)
    P0 = np.diag([0.5, 0.1, 0.5, 0.1])
    x = x_switch + rng.standard_normal((RUNS, 4)) @ np.linalg.cholesky(P0).T
    est = registry.create("estimator", estimator)
    state = est.initialize(np.tile(x_switch, (RUNS, 1)), np.stack([P0] * RUNS))
    bank = TransitionBank.stack([t] * RUNS)
    Lq = np.linalg.cholesky(t.Q)
    nees, nis = [], []
    for _ in range(STEPS):
        x = t.apply(x) + (rng.standard_normal((RUNS, 2)) @ Lq.T) @ t.G.T
        z = sensor.simulate(x, layout, rng)
        state = est.predict(state, bank)
        state, inn = est.update(state, z, [sensor], layout)
        nees.append(_nees(x, est.mean(state), est.covariance(state)))
        nis.append(inn.nis)
    _check(np.array(nees), np.array(nis), 4, 2)


@pytest.mark.parametrize(
    "estimator, sensor",
    [
        ("ekf", RadarSensor(range_std=10.0, azimuth_std=np.deg2rad(0.1))),
        ("ekf_sqrt", PolarRadarSensor(range_std=10.0, azimuth_std=np.deg2rad(0.1))),
    ],
    ids=["ekf-radar_cartesian", "ekf_sqrt-radar_polar"],
)
def test_ekf_on_ship_model(estimator, sensor):
    tau = 2.0
    model = ShipTurn(sigma_velocity=0.05, sigma_rate=1e-4)
    # seeds: over seeds 0–9 the averages are NEES 4.997 ± 0.077, NIS 2.000 ± 0.015 (both sensors);
    # seed 4 is the one of ten outside the 95 % NIS bound (2.029 > 2.028), as chance allows.
    rng = np.random.default_rng(3 if estimator == "ekf" else 5)
    x_hat0 = np.array([4000.0, 3000.0, 6.0, -2.0, 0.01])
    P0 = np.diag([400.0, 400.0, 1.0, 1.0, 1e-5])
    x = x_hat0 + rng.standard_normal((RUNS, 5)) @ np.linalg.cholesky(P0).T
    est = ht.load_plugins().registry.create("estimator", estimator)
    state = est.initialize(np.tile(x_hat0, (RUNS, 1)), np.stack([P0] * RUNS))
    G, Lq = model.noise_gain(tau), np.linalg.cholesky(model.noise_cov)
    lin = model.linearizer(tau)
    nees, nis = [], []
    for _ in range(STEPS):
        x = model.f(x, tau) + (rng.standard_normal((RUNS, 3)) @ Lq.T) @ G.T
        z = sensor.simulate(x, model.layout, rng)
        state = est.predict(state, lin)
        state, inn = est.update(state, z, [sensor], model.layout)
        nees.append(_nees(x, est.mean(state), est.covariance(state)))
        nis.append(inn.nis)
    _check(np.array(nees), np.array(nis), 5, 2)
