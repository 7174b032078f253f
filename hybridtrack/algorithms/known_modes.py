"""The filter told the true schedule: the "optimal KF" of seed 001 (Table 2), composed from a Pipeline per segment."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.plugins import resolve_registry
from hybridtrack.core.registry import Registry
from hybridtrack.core.types import Gaussian
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.simulate import build_models
from hybridtrack.recording import log_estimate
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_times


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


def run_known_modes_batch(
    schedule,
    *,
    estimator: Any,
    sensors: SensorNetwork | Sequence[Sensor],
    measurements: Mapping[str, np.ndarray],
    prior,
    tau: float | None = None,
    times=None,
    noise_cov=None,
    registry: Registry | None = None,
) -> list[ScheduleRun]:
    """:func:`run_known_modes` on R runs at once (measurements (R, K+1, m) per sensor), one stacked bank of R filters.

    ``times`` (K+1,) shared or (R, K+1) per run; ``prior`` one Gaussian or
    per-run (means (R, n), covs (n, n) or (R, n, n)).  As the per-run path: at
    each switch every run's filter restarts from its own estimate (x̂_s, P_s)
    with the new mode's transition fixed at x̂_s.  Equal to the per-run runs to
    rounding (1e-12).
    """
    from hybridtrack.core.plugins import resolve
    from hybridtrack.engine.run_bank import RunBank, batch_measurements, batch_prior, batch_times

    registry = resolve_registry(registry)
    models = build_models(schedule, registry, noise_cov)
    network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
    z = batch_measurements(network, measurements)
    R, steps = z.shape[:2]
    if steps != schedule.total_steps + 1:
        raise ValueError(f"measurements: expected {schedule.total_steps + 1} steps for the schedule, got {steps}")
    t, dt = batch_times(times, tau, R, steps)
    layout = models[0].layout
    n = len(layout)
    x, P = batch_prior(prior, R, n)
    filters = resolve("estimator", estimator, registry)
    bank = RunBank(filters, layout, network.sensors)
    means, covs, nis = np.zeros((R, steps, n)), np.zeros((R, steps, n, n)), np.zeros((R, steps))
    runs = np.arange(R)
    start = 0
    for model, segment in zip(models, schedule.segments):
        bank.set(filters.initialize(x, P), [model] * R, x, runs)
        if start == 0:  # the first segment updates the prior with z_0 (later switch steps were already updated)
            _, score, m = bank.step(None, z[:, 0])
            nis[:, 0] = np.where(m > 0, score, np.nan)  # NaN: nothing measured (the Pipeline's convention)
            means[:, 0], covs[:, 0] = bank.means, bank.covs
        for k in range(start + 1, start + segment.steps + 1):
            _, score, m = bank.step(dt[:, k - 1], z[:, k])
            nis[:, k] = np.where(m > 0, score, np.nan)
            means[:, k], covs[:, k] = bank.means, bank.covs
        start += segment.steps
        x, P = means[:, start].copy(), covs[:, start].copy()
    return [ScheduleRun(layout, t[r], means[r], covs[r], nis[r]) for r in runs]
