"""The filter told the true schedule: the "optimal KF" of seed 001 (Table 2), on R runs of one bank.

One filter per run runs segment by segment with the true mode; at each
switch the new model's transition is built from the filter's own estimate at
the switching moment (a turn's ω and centre from x̂_s, as SPEC §7 found to
reproduce seed 001's figures) and the filter restarts from (x̂_s, P_s).
:func:`run_known_modes` is :func:`run_known_modes_batch` of one run.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.plugins import resolve
from hybridtrack.core.registry import Registry, registry_or_default
from hybridtrack.core.types import Gaussian
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.batch import batch_times, prior_arrays, run_groups, stacked_measurements
from hybridtrack.engine.pipeline import mode_label
from hybridtrack.engine.results import RunResult
from hybridtrack.engine.simulate import build_models
from hybridtrack.sdk.network import SensorNetwork


@attrs.frozen(eq=False, kw_only=True)
class ScheduleRun(RunResult):
    """Estimates of a filter told the true modes: ``modes`` the schedule's modes, ``mode`` (K+1,) the true mode
    per step, and the NIS of each update (K+1,; NaN where nothing was measured)."""

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
    """The filter that knows the schedule (the "optimal KF" of seed 001, Table 2): :func:`run_known_modes_batch`
    of one run.  All modes must share one state layout; ``times`` (seconds, one per measurement step) or
    ``tau`` give the sampling."""
    network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
    z = network.stack(measurements)
    kwargs = dict(estimator=estimator, sensors=network, prior=prior, tau=tau, times=times, noise_cov=noise_cov, registry=registry)
    run = run_known_modes_batch(schedule, measurements=network.split(z[None]), **kwargs)[0]
    if recorder is not None:
        recorder.log_result(run, name=name)
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
    """:func:`run_known_modes` on R runs at once (measurements (R, K+1, m) per sensor), one bank of R filters.

    ``times`` (K+1,) shared or (R, K+1) per run; ``prior`` one Gaussian or
    per-run (means (R, n), covs (n, n) or (R, n, n)).  At each switch every
    run's filter restarts from its own estimate (x̂_s, P_s) with the new mode's
    transition fixed at x̂_s.  Each run equals the run alone to rounding (1e-12);
    runs of a decentralized or sampling estimator each form their own batch of one.
    """
    registry = registry_or_default(registry)
    models = build_models(schedule, registry, noise_cov)
    network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
    z = stacked_measurements(network, measurements)
    R, steps = z.shape[:2]
    if steps != schedule.total_steps + 1:
        raise ValueError(f"measurements: expected {schedule.total_steps + 1} steps for the schedule, got {steps}")
    t, dt = batch_times(times, tau, R, steps)
    layout = models[0].layout
    x0, P0 = prior_arrays(prior, R, len(layout))
    filters = resolve("estimator", estimator, registry)
    labels = [mode_label(m) for m in models]
    modes = tuple(dict.fromkeys(labels))
    mode = np.concatenate([[modes.index(labels[0])]] + [np.full(s.steps, modes.index(x)) for x, s in zip(labels, schedule.segments)])
    runs = []
    for g in run_groups(filters, R):
        means, covs, nis = _filter(FilterBank(filters, layout, network.sensors), models, schedule, z[g], dt[g], x0[g], P0[g])
        runs += [
            ScheduleRun(layout=layout, modes=modes, times=t[r], means=means[u], covs=covs[u], mode=mode, nis=nis[u])
            for u, r in enumerate(g)
        ]
    return runs


def _filter(bank: FilterBank, models, schedule, z, dt, x, P) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The told filter of R runs on ``bank``: x̂ (R, K+1, n), P (R, K+1, n, n), NIS (R, K+1)."""
    R, steps = z.shape[:2]
    n = x.shape[1]
    means, covs, nis = np.zeros((R, steps, n)), np.zeros((R, steps, n, n)), np.zeros((R, steps))
    runs = np.arange(R)
    start = 0
    for model, segment in zip(models, schedule.segments):
        bank.start(x, P, [model] * R, x, runs)
        if start == 0:  # the first segment updates the prior with z_0 (later switch steps were already updated)
            scores = bank.step(None, z[:, 0])
            nis[:, 0] = np.where(scores.m > 0, scores.nis, np.nan)  # NaN: nothing measured (the Pipeline's convention)
            means[:, 0], covs[:, 0] = bank.means, bank.covs
        for k in range(start + 1, start + segment.steps + 1):
            scores = bank.step(dt[:, k - 1], z[:, k])
            nis[:, k] = np.where(scores.m > 0, scores.nis, np.nan)
            means[:, k], covs[:, k] = bank.means, bank.covs
        start += segment.steps
        x, P = means[:, start].copy(), covs[:, start].copy()
    return means, covs, nis
