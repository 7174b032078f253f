"""The filter told the true schedule: the "optimal KF" of seed 001 (Table 2), on R runs of one bank.

One filter per run runs segment by segment with the true mode; at each
switch the new model's transition is built from the filter's own estimate at
the switching moment (a turn's ω and centre from x̂_s, as SPEC §7 found to
reproduce seed 001's figures) and the filter restarts from (x̂_s, P_s).
:class:`KnownModes` is the algorithm (registered as ``known_modes``; its ``run`` is
``run_batch`` of one run), :func:`run_known_modes` its run as a function.
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
from hybridtrack.engine.schedule import Schedule
from hybridtrack.engine.simulate import build_models
from hybridtrack.sdk.network import SensorNetwork


@attrs.frozen(eq=False, kw_only=True)
class ScheduleRun(RunResult):
    """Estimates of a filter told the true modes: ``modes`` the schedule's modes, ``mode`` (K+1,) the true mode
    per step, and the NIS of each update (K+1,; NaN where nothing was measured)."""

    nis: np.ndarray


class KnownModes:
    """The filter told the true schedule: one filter in the true mode of each segment (seed 001's "optimal KF").

    The ``schedule`` (a Schedule or its rows; all modes in one state layout)
    is given when it is built, the measurements and the prior when it runs;
    ``times`` (seconds, one per measurement step) or ``tau`` give the sampling.
    """

    def __init__(
        self,
        *,
        schedule,
        sensors: SensorNetwork | Sequence[Sensor],
        estimator: Any = "kalman",
        tau: float | None = None,
        noise_cov=None,
        name: str = "known_modes",
        registry: Registry | None = None,
    ):
        self.schedule = schedule if isinstance(schedule, Schedule) else Schedule.from_rows(schedule)
        self.registry = registry_or_default(registry)
        self.models = build_models(self.schedule, self.registry, noise_cov)
        self.layout = self.models[0].layout
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.estimator, self.tau, self.name = estimator, tau, name

    def run(self, measurements: Mapping[str, np.ndarray], prior, *, times=None, recorder=None) -> ScheduleRun:
        """:meth:`run_batch` of one run (measurements sensor name → (K+1, m)); ``recorder`` gets the finished run."""
        z = self.network.stack(measurements)
        run = self.run_batch(self.network.split(z[None]), prior, times=times)[0]
        if recorder is not None:
            recorder.log_result(run, name=self.name)
        return run

    def run_batch(self, measurements: Mapping[str, np.ndarray], prior, *, times=None) -> list[ScheduleRun]:
        """R runs at once (measurements (R, K+1, m) per sensor), one bank of R filters.

        ``times`` (K+1,) shared or (R, K+1) per run; ``prior`` one Gaussian or
        per-run (means (R, n), covs (n, n) or (R, n, n)).  At each switch every
        run's filter restarts from its own estimate (x̂_s, P_s) with the new mode's
        transition fixed at x̂_s.  Each run equals the run alone to rounding (1e-12);
        runs of a decentralized or sampling estimator each form their own batch of one.
        """
        schedule = self.schedule
        z = stacked_measurements(self.network, measurements)
        R, steps = z.shape[:2]
        if steps != schedule.total_steps + 1:
            raise ValueError(f"measurements: expected {schedule.total_steps + 1} steps for the schedule, got {steps}")
        t, dt = batch_times(times, self.tau, R, steps)
        x0, P0 = prior_arrays(prior, R, len(self.layout))
        filters = resolve("estimator", self.estimator, self.registry)
        labels = [mode_label(m) for m in self.models]
        modes = tuple(dict.fromkeys(labels))
        mode = np.concatenate([[modes.index(labels[0])]] + [np.full(s.steps, modes.index(x)) for x, s in zip(labels, schedule.segments)])
        runs = []
        for g in run_groups(filters, R):
            bank = FilterBank(filters, self.layout, self.network.sensors)
            means, covs, nis = _filter(bank, self.models, schedule, z[g], dt[g], x0[g], P0[g])
            runs += [
                ScheduleRun(layout=self.layout, modes=modes, times=t[r], means=means[u], covs=covs[u], mode=mode, nis=nis[u])
                for u, r in enumerate(g)
            ]
        return runs


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
    """The filter that knows the schedule (the "optimal KF" of seed 001, Table 2): :meth:`KnownModes.run`."""
    known = KnownModes(schedule=schedule, sensors=sensors, estimator=estimator, tau=tau, noise_cov=noise_cov, name=name, registry=registry)
    return known.run(measurements, prior, times=times, recorder=recorder)


def _filter(bank: FilterBank, models, schedule, z, dt, x, P) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The told filter of R runs on ``bank``: x̂ (R, K+1, n), P (R, K+1, n, n), NIS (R, K+1)."""
    R, steps = z.shape[:2]
    n = x.shape[1]
    means, covs, nis = np.zeros((R, steps, n)), np.zeros((R, steps, n, n)), np.zeros((R, steps))
    runs = np.arange(R)
    start = 0
    for model, segment in zip(models, schedule.segments):
        bank.start(x, P, [model] * R, x, runs)
        # the first segment updates the prior with z_0 (later switch steps were already updated)
        for k in range(start + (start > 0), start + segment.steps + 1):
            scores = bank.step(dt[:, k - 1] if k else None, z[:, k])
            nis[:, k] = np.where(scores.m > 0, scores.nis, np.nan)  # NaN: nothing measured (the Pipeline's convention)
            means[:, k], covs[:, k] = bank.means, bank.covs
        start += segment.steps
        x, P = means[:, start].copy(), covs[:, start].copy()
    return means, covs, nis
