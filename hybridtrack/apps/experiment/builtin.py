"""Built-in experiments: ``demo_rmse``, the optimal KF (told the true modes) on the seed 001 schedule.

One run simulates Table 1 of seed 001 (L3 R5 S L3 S L4, 360 steps) from
x0 = [0, 0, 0, 2] with Q = q·I₂ and a position sensor with R = r·I₂, runs the
known-modes filter (:class:`hybridtrack.algorithms.known_modes.KnownModes`, prior
N(x0, I)) and returns, per state component (x, vx, y, vy), the sum over the steps
k = 1 … K of the squared error, K, the run's nRMSE and mean NIS.
Pooling ``squared_error`` over runs gives seed 001's RMSE_i = √(mean over runs
and steps of (x_i − x̂_i)²) exactly (:func:`pooled_rmse`).
"""

from __future__ import annotations

import numpy as np

from hybridtrack.apps.experiment.definition import Experiment
from hybridtrack.core.plugins import resolve
from hybridtrack.core.types import Gaussian
from hybridtrack.core.validation import check_positive
from hybridtrack.engine.schedule import SEED001_TABLE1, Schedule, Segment

X0 = (0.0, 0.0, 0.0, 2.0)


def scaled_schedule(schedule: Schedule, factor: float) -> Schedule:
    """Every segment's length scaled by ``factor`` (at least one step): small runs for tests."""
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"steps_scale: expected a positive number, got {factor!r}")
    return Schedule([Segment(s.mode, max(1, round(s.steps * factor)), s.radius, s.acceleration) for s in schedule.segments])


def seed001_setup(R: float, steps_scale: float = 1.0):
    """(schedule, sensors) of seed 001: Table 1 scaled by ``steps_scale``, one position sensor with R = r·I₂."""
    schedule = scaled_schedule(SEED001_TABLE1, steps_scale)
    sensors = [resolve("sensor", ("position", {"name": "sensor", "noise_cov": float(R) * np.eye(2)}))]
    return schedule, sensors


def seed001_prior():
    """The prior N(x0, I₄) every seed-001 estimator starts from."""
    return Gaussian(np.array(X0), np.eye(4))


def simulate_seed001(rng: np.random.Generator, *, R: float, q: float, tau: float, steps_scale: float = 1.0, recorder=None):
    """(schedule, sensors, trajectory, measurements) of one seed-001 run drawn from ``rng``.

    With a ``recorder`` the truth (``world/truth``) and the measurements (``world/measurements/sensor``) are logged.
    """
    from hybridtrack.engine.simulate import simulate_measurements, simulate_trajectory
    from hybridtrack.recording import log_measurements

    schedule, sensors = seed001_setup(R, steps_scale)
    # two independent streams from the run's generator (simulate() itself takes an int seed only)
    trajectory_rng, measurement_rng = rng.spawn(2)
    truth = simulate_trajectory(schedule, X0, tau, seed=trajectory_rng, noise_cov=float(q) * np.eye(2), recorder=recorder)
    measurements = simulate_measurements(truth, sensors, seed=measurement_rng)
    if recorder is not None:
        log_measurements(recorder, sensors, measurements, truth.steps, truth.times)
    return schedule, sensors, truth, measurements


def simulate_seed001_batch(rngs, *, R: float, q: float, tau: float, steps_scale: float = 1.0):
    """:func:`simulate_seed001` for many runs: the same draws from each run's generator (its two spawned
    streams), the trajectories propagated together (``simulate_trajectories``).

    Returns (schedule, sensors, truths, measurements name → (runs, K+1, m)).
    """
    from hybridtrack.engine.simulate import simulate_measurements, simulate_trajectories

    schedule, sensors = seed001_setup(R, steps_scale)
    streams = [rng.spawn(2) for rng in rngs]
    truths = simulate_trajectories(schedule, X0, tau, seeds=[s[0] for s in streams], noise_cov=float(q) * np.eye(2))
    drawn = [simulate_measurements(truth, sensors, seed=s[1]) for truth, s in zip(truths, streams)]
    return schedule, sensors, truths, {name: np.stack([d[name] for d in drawn]) for name in drawn[0]}


def squared_errors(means: np.ndarray, truth, layout) -> np.ndarray:
    """Σ over steps k = 1 … K of (x_k − x̂_k)² per state component (seed 001 leaves out step 0)."""
    error = means[1:] - truth.states_in(layout)[1:]
    return np.sum(error**2, axis=0)


def _known_modes(schedule: Schedule, sensors, q: float, tau: float, estimator: str):
    """Seed 001's optimal KF (``KnownModes``, Q = q·I₂) on ``schedule``; it runs from :func:`seed001_prior`."""
    from hybridtrack.algorithms.known_modes import KnownModes

    return KnownModes(schedule=schedule, sensors=sensors, estimator=estimator, tau=tau, noise_cov=float(q) * np.eye(2))


def known_modes_estimate(schedule: Schedule, sensors, measurements, *, q: float, tau: float, estimator: str = "kalman", recorder=None):
    """The optimal KF of seed 001 (told the modes; prior N(x0, I)) on one run's measurements."""
    return _known_modes(schedule, sensors, q, tau, estimator).run(measurements, seed001_prior(), recorder=recorder)


def known_modes_estimate_batch(schedule: Schedule, sensors, measurements, *, q: float, tau: float, estimator: str = "kalman"):
    """:func:`known_modes_estimate` of many runs at once (``measurements`` name → (runs, K+1, m)) as one stacked
    bank (``KnownModes.run_batch``): one run result per run, equal to the per-run ones to rounding."""
    return _known_modes(schedule, sensors, q, tau, estimator).run_batch(measurements, seed001_prior())


def pooled_rmse(squared_error: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """RMSE per component pooled over runs: √(Σ_runs squared_error / Σ_runs steps)."""
    return np.sqrt(np.sum(squared_error, axis=0) / np.sum(steps))


def _demo_rmse(index: int, rng: np.random.Generator, *, R: float, q: float, tau: float, steps_scale: float, recorder=None) -> dict:
    """Squared errors (steps 1 … K) of the known-modes KF on one simulated seed-001 trajectory (logged to ``recorder``)."""
    schedule, sensors, truth, measurements = simulate_seed001(rng, R=R, q=q, tau=tau, steps_scale=steps_scale, recorder=recorder)
    run = known_modes_estimate(schedule, sensors, measurements, q=q, tau=tau, recorder=recorder)
    squared = squared_errors(run.means, truth, run.layout)
    steps = schedule.total_steps
    return {
        "squared_error": squared,
        "steps": steps,
        "nrmse": float(np.linalg.norm(np.sqrt(squared / steps))),
        "mean_nis": float(np.mean(run.nis)),
    }


def check_seed001_parameters(parameters: dict) -> None:
    """R, τ and ``steps_scale`` positive finite numbers, q a finite number ≥ 0 (a ValueError naming the first that is not)."""
    for name, what in (
        ("R", "the measurement noise variance"),
        ("tau", "the sampling period in seconds"),
        ("steps_scale", "the schedule's length factor"),
    ):
        check_positive(parameters[name], name, what=what)
    q = parameters["q"]
    if not (np.isfinite(q) and q >= 0):
        raise ValueError(f"q: expected a finite number ≥ 0 (the process noise variance), got {q!r}")


DEMO_RMSE = Experiment(
    name="demo_rmse",
    run_one=_demo_rmse,
    parameters={"R": 0.01, "q": 0.001, "tau": 0.1, "steps_scale": 1.0},
    description="optimal (known-modes) KF on the seed 001 schedule: squared error per component, nRMSE, mean NIS",
    locator="hybridtrack.apps.experiment.builtin:DEMO_RMSE",
    check_parameters=check_seed001_parameters,
)
