"""A small tracking experiment with and without ``run_batch``, loaded by path like a user's script (runner tests).

Each run simulates a short straight-then-turn trajectory from its own generator
(irregular times drawn from it too, and a random dropout of sensor b), runs a
two-model Kalman bank with a signal-function detector and returns the bank's
mean NIS, the per-filter squared position error, the first decision step (−1
for none) and the log-likelihood series.  ``run_batch`` draws each run from its
own generator exactly as ``run_one`` does and runs the chunk with
``Pipeline.run_batch``.  ``interrupt_at`` (with ``marker``) makes the batch
holding that run act as a Ctrl-C once, ``fail_at`` makes ``run_batch`` raise for
a chunk holding that run (``run_one`` still works: the runner reports it), and
``log`` gets a line per batch ("batch FIRST LAST") and per single run ("one INDEX").
"""

from pathlib import Path

import numpy as np

from hybridtrack import Gaussian, Schedule
from hybridtrack.apps.experiment import Experiment
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.simulate import simulate_measurements, simulate_trajectory
from hybridtrack_plugins.sensors.position import PositionSensor

STEPS = 20
SENSORS = [PositionSensor(name="a", noise_cov=np.eye(2) * 0.05), PositionSensor(name="b", components="x", noise_cov=[[0.04]])]
OPTIONS = {
    "models": ["straight", ("left_turn", {"radius": 3.0, "noise_cov": np.diag([1e-3, 1e-3])})],
    "estimator": "kalman",
    "sensors": SENSORS,
    "detectors": [("signal_function", {"window": 5})],
}
PRIOR = Gaussian(np.array([0.0, 0.0, 0.0, 2.0]), np.eye(4))


def draw(rng):
    """(times, measurements, truth) of one run from its generator."""
    times = np.cumsum(rng.uniform(0.05, 0.15, STEPS + 1))
    schedule = Schedule.from_rows([("straight", STEPS // 2), ("left_turn", STEPS - STEPS // 2, 3.0)])
    truth = simulate_trajectory(schedule, PRIOR.mean, times=times, seed=rng, noise_cov=np.diag([1e-3, 1e-3]))
    z = simulate_measurements(truth, SENSORS, seed=rng)
    z["b"][rng.uniform(size=STEPS + 1) < 0.2] = np.nan
    return times, z, truth


def summary(result, truth):
    error = result.means[:, :, [0, 2]] - truth.positions[:, None, :]
    first = [d.step for d in result.decisions]
    return {
        "mean_nis": np.nanmean(result.nis, axis=0),
        "squared_error": np.sum(error**2, axis=(0, 2)),
        "first_decision": first[0] if first else -1,
        "loglik": result.loglik[:, 0],
    }


def _log(log, line):
    if log:
        with open(log, "a") as handle:
            handle.write(line + "\n")


def run_one(index, rng, *, log="", marker="", interrupt_at=-1, fail_at=-1):
    _log(log, f"one {index}")
    times, z, truth = draw(rng)
    return summary(Pipeline(measurements=z, prior=PRIOR, times=times, **OPTIONS).run(), truth)


def run_batch(indices, rngs, *, log="", marker="", interrupt_at=-1, fail_at=-1):
    _log(log, f"batch {indices[0]} {indices[-1]}")
    if interrupt_at in indices and not Path(marker).exists():
        Path(marker).write_text("interrupted once")
        raise KeyboardInterrupt
    if fail_at in indices:
        raise RuntimeError(f"planned batch failure (run {fail_at})")
    drawn = [draw(rng) for rng in rngs]
    z = {name: np.stack([d[1][name] for d in drawn]) for name in drawn[0][1]}
    results = Pipeline.run_batch(z, PRIOR, times=np.stack([d[0] for d in drawn]), **OPTIONS)
    return [summary(result, d[2]) for result, d in zip(results, drawn)]


PARAMETERS = {"log": "", "marker": "", "interrupt_at": -1, "fail_at": -1}
BATCHED = Experiment("tracking_batched", run_one, PARAMETERS, run_batch=run_batch, batch_size=4)
PER_RUN = Experiment("tracking_per_run", run_one, PARAMETERS)
