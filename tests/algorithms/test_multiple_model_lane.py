"""The multiple-model estimators through the bank's compiled restart lane (FilterBank.restart_step) against the
same runs through start and step: the ships configuration's modes (4- and 5-state, a nonlinear turn), per-run Δt,
runs of different lengths and missing velocity reports."""

from __future__ import annotations

import numpy as np
import pytest

from hybridtrack.algorithms.bank_runs import run_ragged
from hybridtrack.algorithms.multiple_model import MultipleModelEstimator
from hybridtrack.engine.bank import FilterBank
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.motion.linear_modes import Stop, Straight
from hybridtrack_plugins.motion.real_motion import CoordinatedTurn
from hybridtrack_plugins.sensors.position import PositionSensor
from hybridtrack_plugins.sensors.velocity import VelocitySensor

needs_numba = pytest.mark.skipif(not cov_form.NUMBA_AVAILABLE, reason="numba not installed: no compiled lane")


def estimator(method):
    models = [Straight(noise_density=1e-3), CoordinatedTurn(noise_density=1e-3), Stop(noise_density=0.01)]
    sensors = [PositionSensor(noise_cov=np.eye(2) * 100.0), VelocitySensor(speed_sigma=0.2, course_sigma=np.radians(2.0))]
    return MultipleModelEstimator(models, sensors=sensors, sojourn=120.0, method=method, missing_variance={"omega": 1e-4})


def runs(seed=0, count=5):
    """Ragged runs of a ship turning and stopping, reported every 2–12 s, some velocity reports missing."""
    rng = np.random.default_rng(seed)
    out = []
    for r in range(count):
        K = 30 + 17 * r
        t = np.cumsum(rng.uniform(2.0, 12.0, K))
        heading = 0.3 + np.cumsum(np.where(np.arange(K) > K // 2, 0.02, 0.0) * np.diff(t, prepend=t[0]))
        speed = np.where(np.arange(K) > 3 * K // 4, 0.05, 6.0)
        v = speed[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
        p = np.cumsum(v * np.diff(t, prepend=t[0])[:, None], axis=0)
        velocity = v + rng.normal(size=(K, 2)) * 0.2
        velocity[rng.random(K) < 0.3] = np.nan
        out.append(({"position": p + rng.normal(size=(K, 2)) * 10.0, "velocity": velocity}, t))
    priors = [
        (np.array([z["position"][0, 0], 0.0, z["position"][0, 1], 0.0, 0.0]), np.diag([250.0**2, 56.0, 250.0**2, 56.0, 1e-3]))
        for z, _ in out
    ]
    return [z for z, _ in out], priors, [t for _, t in out]


@needs_numba
@pytest.mark.parametrize("method", ["imm", "gpb2"])
def test_runs_through_the_lane_equal_runs_through_start_and_step(method, monkeypatch):
    measurements, priors, times = runs()
    lane = run_ragged(estimator(method), measurements, priors, times)
    monkeypatch.setattr(FilterBank, "restart_step", lambda self, *args: None)
    reference = run_ragged(estimator(method), measurements, priors, times)
    for a, b in zip(lane, reference):
        scale = np.abs(b.means).max(axis=0)
        assert np.max(np.abs(a.means - b.means) / scale) < 1e-10
        d = np.sqrt(np.diagonal(b.covs, axis1=1, axis2=2))
        assert np.max(np.abs(a.covs - b.covs) / (d[:, :, None] * d[:, None, :])) < 1e-10
        assert np.max(np.abs(a.mode_probabilities - b.mode_probabilities)) < 1e-10
        assert np.max(np.abs(a.loglik - b.loglik)) < 1e-8
