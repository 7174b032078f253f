"""FilterBank.restart_step (start + step in one compiled call over every layout) against start then step."""

from __future__ import annotations

import numpy as np
import pytest

from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.layouts import union_layout
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters.information import InformationFilter
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.motion.linear_modes import ConstantAcceleration, LeftTurn, Stop, Straight
from hybridtrack_plugins.motion.real_motion import CoordinatedTurn
from hybridtrack_plugins.motion.ship import ShipTurn
from hybridtrack_plugins.sensors.position import PositionSensor
from hybridtrack_plugins.sensors.velocity import VelocitySensor

needs_numba = pytest.mark.skipif(not cov_form.NUMBA_AVAILABLE, reason="numba not installed: no compiled lane")
SENSORS = [PositionSensor(noise_cov=np.diag([4.0, 9.0])), VelocitySensor(speed_sigma=0.3, course_sigma=0.05)]


def bank_inputs(models, runs, seed):
    """Starts (F, n) and SPD covariances in the union layout, filter r·M + j of run r running models[j], Δt per run
    and measurements per run with missing components (velocity, one position axis, all) in different rows."""
    rng = np.random.default_rng(seed)
    layout = union_layout([m.layout for m in models])
    F, n = runs * len(models), len(layout)
    x = rng.normal(size=(F, n)) * 10.0
    x[:, layout.index("vx")] += 8.0
    if "omega" in layout:
        x[:, layout.index("omega")] = rng.normal(size=F) * 0.05
    A = rng.normal(size=(F, n, n)) * 0.3
    scale = np.array([{"x": 10.0, "y": 10.0, "omega": 0.01}.get(c, 1.0) for c in layout])  # m, m/s, rad/s
    P = (A @ np.swapaxes(A, 1, 2) + np.eye(n)) * scale[:, None] * scale[None, :]
    z = rng.normal(size=(runs, 4)) * 5.0
    z[1::3, 2:] = np.nan  # no velocity
    z[2::5, 0] = np.nan  # one position component
    z[4::7] = np.nan  # nothing measured
    return layout, x, P, np.repeat(np.arange(runs), len(models)), rng.uniform(0.5, 12.0, runs), z


def start_then_step(estimator, layout, filter_models, x, P, run, dt, z):
    bank = FilterBank(estimator, layout, SENSORS, missing_variance={"omega": 1e-4} if "omega" in layout else 1.0)
    bank.start(x, P, filter_models, x, run)
    step = bank.step(dt, z)
    return bank.means, bank.covs, step.loglik, step.nis, step.m


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


@needs_numba
@pytest.mark.parametrize(
    "models",
    [
        [Straight(noise_density=1e-3), CoordinatedTurn(noise_density=1e-3), Stop(noise_density=0.01)],  # ships.toml's modes
        [Straight(noise_cov=np.eye(2) * 0.05), ConstantAcceleration(noise_cov=np.eye(2) * 0.05), LeftTurn(radius=300.0)],
        [CoordinatedTurn()],
    ],
    ids=["cv-ct-stop", "cv-ca-turn", "ct-alone"],
)
@pytest.mark.parametrize("dt_kind", ["per_run", "shared", "none"])
def test_restart_step_equals_start_then_step(models, dt_kind):
    layout, x, P, run, dt, z = bank_inputs(models, runs=23, seed=len(models))
    dt = {"per_run": dt, "shared": float(dt[0]), "none": None}[dt_kind]
    filter_models = [models[i % len(models)] for i in range(len(run))]
    estimator = KalmanFilter()
    bank = FilterBank(estimator, layout, SENSORS, missing_variance={"omega": 1e-4} if "omega" in layout else 1.0)
    done = bank.restart_step(x, P, filter_models, x, run, dt, z)
    assert done is not None
    means, covs, loglik, nis, m = start_then_step(KalmanFilter(), layout, filter_models, x, P, run, dt, z)
    assert _rel(done.means, means) < 1e-12
    assert np.max(np.abs(done.covs - covs)) / np.max(np.abs(covs)) < 1e-12
    assert np.max(np.abs(done.loglik - loglik)) < 1e-9
    assert np.max(np.abs(done.nis - nis)) < 1e-9
    np.testing.assert_array_equal(done.m, m)
    np.testing.assert_array_equal(done.covs, np.swapaxes(done.covs, 1, 2))
    assert bank.restart_step(x, P, filter_models, x, run, dt, z).means.tobytes() == done.means.tobytes()  # the kept plan


@needs_numba
def test_a_model_in_another_order_of_its_components_is_embedded_by_name():
    """The ship turn's (x, y, vx, vy, ω) beside the coordinated turn's (x, vx, y, vy, ω): the same components, reordered."""
    models = [CoordinatedTurn(), ShipTurn(sigma_velocity=0.05, sigma_rate=1e-3), Straight(noise_density=1e-3)]
    layout, x, P, run, dt, z = bank_inputs(models, runs=9, seed=5)
    filter_models = [models[i % 3] for i in range(len(run))]
    bank = FilterBank(KalmanFilter(), layout, SENSORS, missing_variance={"omega": 1e-4})
    done = bank.restart_step(x, P, filter_models, x, run, float(dt[0]), z)
    means, covs, loglik, _, _ = start_then_step(KalmanFilter(), layout, filter_models, x, P, run, float(dt[0]), z)
    assert _rel(done.means, means) < 1e-12 and _rel(done.covs, covs) < 1e-12 and np.max(np.abs(done.loglik - loglik)) < 1e-9


def test_no_lane_without_the_estimator_s_restart_step_or_its_embedding():
    models = [Straight(noise_density=1e-3), CoordinatedTurn(noise_density=1e-3)]
    layout, x, P, run, dt, z = bank_inputs(models, runs=4, seed=1)
    filter_models = [models[i % 2] for i in range(len(run))]
    assert FilterBank(InformationFilter(), layout, SENSORS).restart_step(x, P, filter_models, x, run, dt, z) is None

    class NoEmbedding(KalmanFilter):
        restart_embeds_layouts = False

    assert FilterBank(NoEmbedding(), layout, SENSORS).restart_step(x, P, filter_models, x, run, dt, z) is None
    assert FilterBank(KalmanFilter(engine="numpy"), layout, SENSORS).restart_step(x, P, filter_models, x, run, dt, z) is None


@needs_numba
def test_the_lane_declines_what_the_reference_refuses_so_the_reference_raises_it():
    """A prior that is not positive definite, a measurement beyond the arithmetic, a sensor measuring what a model
    lacks: restart_step gives None, and start + step raise their usual errors."""
    models = [Straight(noise_density=1e-3), CoordinatedTurn(noise_density=1e-3)]
    layout, x, P, run, dt, z = bank_inputs(models, runs=4, seed=2)
    filter_models = [models[i % 2] for i in range(len(run))]
    bank = FilterBank(KalmanFilter(), layout, SENSORS)
    bad_P = P.copy()
    bad_P[3] = -np.eye(len(layout))
    assert bank.restart_step(x, bad_P, filter_models, x, run, dt, z) is None
    with pytest.raises(ValueError, match="positive definite"):
        start_then_step(KalmanFilter(), layout, filter_models, x, bad_P, run, dt, z)
    big = z.copy()
    big[0, 0] = 1e200
    assert bank.restart_step(x, P, filter_models, x, run, dt, big) is None
    with pytest.raises(ValueError, match="exceeds the float64 arithmetic"):
        start_then_step(KalmanFilter(), layout, filter_models, x, P, run, dt, big)
    omega = FilterBank(KalmanFilter(), layout, [PositionSensor(components=("x", "omega"), noise_cov=np.eye(2))])
    assert omega.restart_step(x, P, filter_models, x, run, dt, z[:, :2]) is None
