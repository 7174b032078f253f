"""The filter told the true schedule: the "optimal KF" of seed 001 (Table 2), composed from a Pipeline per segment."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.interfaces import Sensor
from hybridtrack.network import SensorNetwork
from hybridtrack.pipeline import Pipeline
from hybridtrack.plugins import resolve_registry
from hybridtrack.recording import log_estimate
from hybridtrack.registry import Registry
from hybridtrack.simulate import build_models
from hybridtrack.timestamps import step_times
from hybridtrack.types import Gaussian


@attrs.frozen(eq=False)
class ScheduleRun:
    """Estimates of a filter told the true modes: times (K+1,), means (K+1, n), covs (K+1, n, n), nis (K+1,)."""

    layout: tuple[str, ...]
    times: np.ndarray
    means: np.ndarray
    covs: np.ndarray
    nis: np.ndarray


def run_known_modes(
    schedule,
    *,
    estimator: Any,
    sensors: SensorNetwork | Sequence[Sensor],
    measurements: Mapping[str, np.ndarray],
    prior: Gaussian | tuple,
    tau: float | None = None,
    times=None,
    noise_cov=None,
    recorder=None,
    name: str = "known_modes",
    registry: Registry | None = None,
) -> ScheduleRun:
    """The filter that knows the schedule (the "optimal KF" of seed 001, Table 2).

    One filter runs segment by segment with the true mode; at each switch the
    new model's transition is built from the filter's own estimate at the
    switching moment (a turn's ω and centre from x̂_s, as SPEC §7 found to
    reproduce seed 001's figures).  All modes must share one state layout.
    ``times`` (seconds, one per measurement step) or ``tau`` give the sampling.
    """
    models = build_models(schedule, resolve_registry(registry), noise_cov)
    network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
    z = network.stack(measurements)
    if z.shape[0] != schedule.total_steps + 1:
        raise ValueError(f"measurements: expected {schedule.total_steps + 1} steps for the schedule, got {z.shape[0]}")
    t = step_times(times, tau, z.shape[0])
    prior = prior if isinstance(prior, Gaussian) else Gaussian(*prior)
    means, covs, nis = [], [], []
    start = 0
    for model, segment in zip(models, schedule.segments):
        rows = z[start : start + segment.steps + 1].copy()
        if start > 0:
            rows[0] = np.nan  # the switch step was already updated by the previous segment
        pipeline = Pipeline(
            models=[model],
            estimator=estimator,
            sensors=network,
            measurements=network.split(rows),
            prior=prior,
            times=t[start : start + segment.steps + 1],
            registry=registry,
        )
        result = pipeline.run()
        skip = 0 if start == 0 else 1
        means.append(result.means[skip:, 0])
        covs.append(result.covs[skip:, 0])
        nis.append(result.nis[skip:, 0])
        prior = Gaussian(result.means[-1, 0], (result.covs[-1, 0] + result.covs[-1, 0].T) / 2)
        start += segment.steps
    run = ScheduleRun(models[0].layout, t, np.concatenate(means), np.concatenate(covs), np.concatenate(nis))
    if recorder is not None:
        steps = np.arange(run.means.shape[0])
        position = [run.layout.index("x"), run.layout.index("y")]
        log_estimate(recorder, name, steps, run.means, run.covs, position, t)
        recorder.log_scalars(f"estimator/{name}/nis", steps, run.nis, t)
    return run
