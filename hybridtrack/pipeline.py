"""Compose and run: measurements → estimator bank → detectors → recorder.

A :class:`Pipeline` runs one bank of M filters, filter j using motion model j,
on the stacked measurements of a sensor network:

* step 0: each filter starts from the prior and is updated with z_0 (when row 0
  has data);
* step k ≥ 1: predict with the model's transition, then update with z_k.

A linear model's transition is fixed from the prior mean, the state at the
switching moment (SPEC §1: a turn's ω and centre are fixed at the switch); a
nonlinear model is relinearized at each filter's own estimate every step
(EKF).  Measurements are a mapping sensor name → array (steps, m_i), row k
holding step k, NaN rows meaning no measurement; see
:mod:`hybridtrack.measurements_io` for the CSV/NPZ layouts.  In clutter they
are instead ``candidates``, sensor name → :class:`~hybridtrack.clutter.ScanSequence`
(a variable number of candidate measurements per step), for an estimator that
associates them (``nearest_neighbour``, ``pda``: ``accepts_scans = True``).

Components are given as objects or by registered name (``"kalman"``,
``("left_turn", {"radius": 3.0})``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.interfaces import Detector, DetectorStep, Estimator, Innovation, MotionModel, Sensor, TransitionBank
from hybridtrack.network import SensorNetwork
from hybridtrack.recording import NullRecorder, log_estimate, log_measurements
from hybridtrack.registry import Registry
from hybridtrack.types import Decision, Gaussian


def _registry(registry: Registry | None) -> Registry:
    if registry is None:
        from hybridtrack.plugins import get_registry

        registry = get_registry()
    return registry


def resolve(kind: str, spec, base: type, registry: Registry | None = None):
    """An instance of ``base`` from an object, a registered name, or ``(name, parameters)``."""
    if isinstance(spec, base):
        return spec
    if isinstance(spec, str):
        return _registry(registry).create(kind, spec)
    if isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], str) and isinstance(spec[1], Mapping):
        return _registry(registry).create(kind, spec[0], **spec[1])
    raise TypeError(f"{kind}: expected a {base.__name__}, a registered name or (name, parameters), got {spec!r}")


@attrs.frozen(eq=False)
class StepResult:
    """One step of a pipeline: the bank's posterior, its innovations and the detectors' outputs."""

    step: int
    mean: np.ndarray  # (M, n)
    cov: np.ndarray  # (M, n, n)
    innovation: Innovation
    detectors: dict[str, DetectorStep]


@attrs.frozen(eq=False)
class RunResult:
    """A whole run: means (K+1, M, n), covs (K+1, M, n, n), nis and loglik (K+1, M), innovations
    (K+1, M, Σm) (NaN where a step lacked some measurement), detector statistics name → series →
    array over steps, and the decisions."""

    layout: tuple[str, ...]
    filters: tuple[str, ...]
    means: np.ndarray
    covs: np.ndarray
    nis: np.ndarray
    loglik: np.ndarray
    innovations: np.ndarray
    statistics: dict[str, dict[str, np.ndarray]]
    decisions: tuple[Decision, ...]


class Pipeline:
    """A bank of filters (one per motion model) on a network's measurements, with detectors and a recorder.

    Parameters: ``models`` (motion models, names or (name, parameters)); ``estimator``;
    ``sensors`` (a :class:`SensorNetwork` or a list of sensors); ``measurements``
    (sensor name → (steps, m_i)); ``prior`` (a :class:`Gaussian` or (mean, cov),
    in the models' layout); ``tau``; ``detectors``; ``recorder`` (defaults to
    :class:`NullRecorder`); ``truth`` (an optional trajectory to record beside
    the estimates); ``filter_names`` to label the bank; ``record_measurements``
    (False when another pipeline on the same recorder already logs them);
    ``candidates`` (sensor name → :class:`~hybridtrack.clutter.ScanSequence`, one
    per sensor) in place of ``measurements`` when tracking in clutter: each step
    passes the sensors' :class:`~hybridtrack.clutter.Scan` list to an estimator
    with ``accepts_scans``; clutter, gates and association weights are recorded.
    """

    def __init__(
        self,
        *,
        models: Sequence[Any],
        estimator: Any,
        sensors: SensorNetwork | Sequence[Sensor],
        measurements: Mapping[str, np.ndarray] | None = None,
        prior: Gaussian | tuple,
        tau: float,
        detectors: Sequence[Any] = (),
        recorder=None,
        truth=None,
        filter_names: Sequence[str] | None = None,
        registry: Registry | None = None,
        record_measurements: bool = True,
        candidates: Mapping[str, Any] | None = None,
    ):
        self.models = [resolve("motion_model", m, MotionModel, registry) for m in models]
        if not self.models:
            raise ValueError("models: a bank needs at least one motion model")
        layouts = {m.layout for m in self.models}
        if len(layouts) != 1:
            raise ValueError(f"models: every filter of a bank must share one state layout, got {sorted(layouts)}")
        self.layout = self.models[0].layout
        self.estimator: Estimator = resolve("estimator", estimator, Estimator, registry)
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.candidates = self._check_candidates(candidates, measurements)
        if self.candidates is not None:
            measurements = {name: seq.target_measurements() for name, seq in self.candidates.items()}
        elif measurements is None:
            raise ValueError("measurements: required (sensor name → (steps, m_i)) unless candidates are given")
        self.z = self.network.stack(measurements)
        self.tau = float(tau)
        if not (np.isfinite(self.tau) and self.tau > 0):
            raise ValueError(f"tau: expected a positive sampling period, got {tau!r}")
        self.detectors: list[Detector] = [resolve("detector", d, Detector, registry) for d in detectors]
        names = [d.name for d in self.detectors]
        if len(set(names)) != len(names):
            raise ValueError(f"detectors: names must be unique, got {names}")
        self.recorder = recorder if recorder is not None else NullRecorder()
        self.record_measurements = record_measurements
        self.truth = truth
        self.filter_names = tuple(filter_names) if filter_names is not None else self._default_names()
        if len(self.filter_names) != len(self.models):
            raise ValueError(f"filter_names: expected {len(self.models)} names, got {len(self.filter_names)}")

        prior = prior if isinstance(prior, Gaussian) else Gaussian(*prior)
        if prior.dim != len(self.layout):
            raise ValueError(f"prior: expected a state of the layout {self.layout}, got dimension {prior.dim}")
        self.prior = prior
        M = len(self.models)
        self._state = self.estimator.initialize(np.tile(prior.mean, (M, 1)), np.tile(prior.cov, (M, 1, 1)))
        self._transitions = None
        if all(m.linear for m in self.models):
            self._transitions = TransitionBank.stack([m.transition(self.tau, prior.mean) for m in self.models])
        self._results: list[StepResult] = []
        self._decisions: list[Decision] = []
        self._recorded = False

    def _check_candidates(self, candidates, measurements):
        """Validate ``candidates`` (one ScanSequence per network sensor) against the estimator."""
        if candidates is None:
            return None
        from hybridtrack.clutter import ScanSequence

        if measurements is not None:
            raise ValueError("candidates: give either measurements or candidates, not both")
        if not getattr(self.estimator, "accepts_scans", False):
            raise ValueError(
                f"candidates: estimator {self.estimator.name!r} does not associate candidate measurements; use 'nearest_neighbour' or 'pda'"
            )
        names = set(self.network.names)
        if set(candidates) != names:
            raise ValueError(f"candidates: expected one ScanSequence per sensor {sorted(names)}, got {sorted(candidates)}")
        for name, seq in candidates.items():
            if not isinstance(seq, ScanSequence) or seq.sensor != name:
                raise ValueError(f"candidates[{name!r}]: expected a ScanSequence of sensor {name!r}, got {seq!r}")
        return {name: candidates[name] for name in self.network.names}

    def _default_names(self) -> tuple[str, ...]:
        names = []
        for model in self.models:
            radius = getattr(model, "radius", None)
            names.append(model.name if radius is None else f"{model.name}_r{radius:g}")
        # make repeated names unique
        return tuple(n if names.count(n) == 1 else f"{n}_{i}" for i, n in enumerate(names))

    @property
    def steps(self) -> int:
        """Number of steps in the measurements (0..steps−1)."""
        return self.z.shape[0]

    @property
    def done(self) -> bool:
        return len(self._results) >= self.steps

    def step(self) -> StepResult:
        """Process the next step and return its result."""
        k = len(self._results)
        if k >= self.steps:
            raise StopIteration(f"all {self.steps} steps processed")
        state = self._state
        if k > 0:
            transitions = self._transitions
            if transitions is None:
                means = self.estimator.mean(state)
                transitions = TransitionBank.stack([m.transition(self.tau, x) for m, x in zip(self.models, means)])
            state = self.estimator.predict(state, transitions)
        z = self.z[k] if self.candidates is None else [seq.scan(k) for seq in self.candidates.values()]
        state, innovation = self.estimator.update(state, z, self.network.sensors, self.layout)
        self._state = state
        outputs = {}
        for detector in self.detectors:
            output = detector.step(k, innovation)
            outputs[detector.name] = output
            if output.decision is not None:
                self._decisions.append(output.decision)
        result = StepResult(k, self.estimator.mean(state), self.estimator.covariance(state), innovation, outputs)
        self._results.append(result)
        return result

    def run(self) -> RunResult:
        """Process the remaining steps, record the run and return it.

        If a step raises, what was processed before is still recorded.
        """
        try:
            while not self.done:
                self.step()
        finally:
            self.record()
        return self.result()

    def result(self) -> RunResult:
        """The steps processed so far as arrays."""
        if not self._results:
            raise RuntimeError("no step has been processed yet")
        M = len(self.models)
        statistics: dict[str, dict[str, list]] = {}
        for r in self._results:
            for name, output in r.detectors.items():
                series = statistics.setdefault(name, {})
                for key, value in {**output.statistics, **output.thresholds}.items():
                    series.setdefault(key, []).append(value)

        full = self.network.measurement_dim
        missing = np.full(M, np.nan)
        nis, loglik, innovations = [], [], []
        for r in self._results:
            complete = r.innovation.measurement_dim > 0
            nis.append(r.innovation.nis if complete else missing)
            loglik.append(r.innovation.loglik if complete else missing)
            innovations.append(r.innovation.nu if r.innovation.measurement_dim == full else np.full((M, full), np.nan))
        return RunResult(
            layout=self.layout,
            filters=self.filter_names,
            means=np.stack([r.mean for r in self._results]),
            covs=np.stack([r.cov for r in self._results]),
            nis=np.stack(nis).astype(float),
            loglik=np.stack(loglik).astype(float),
            innovations=np.stack(innovations).astype(float),
            statistics={n: {k: np.asarray(v, dtype=float) for k, v in s.items()} for n, s in statistics.items()},
            decisions=tuple(self._decisions),
        )

    def record(self) -> None:
        """Log the truth, measurements, estimates, NIS, detector series and decisions (once)."""
        if self._recorded or not self._results:
            return
        self._recorded = True
        rec = self.recorder
        result = self.result()
        steps = np.arange(len(self._results))
        times = steps * self.tau
        if self.truth is not None:
            positions = self.truth.positions[: len(steps)]
            rec.log_path("world/truth", steps, positions, times)
        if self.record_measurements and self.candidates is not None:
            from hybridtrack.clutter import log_scans

            log_scans(rec, list(self.candidates.values()), steps, times)
        elif self.record_measurements:
            log_measurements(rec, self.network.sensors, self.network.split(self.z[: len(steps)]), steps, times)
        position = [self.layout.index("x"), self.layout.index("y")]
        for j, name in enumerate(self.filter_names):
            log_estimate(rec, name, steps, result.means[:, j], result.covs[:, j], position, times)
            rec.log_scalars(f"estimator/{name}/nis", steps, result.nis[:, j], times)
            rec.log_scalars(f"estimator/{name}/loglik", steps, result.loglik[:, j], times)
            rec.log_scalars(f"estimator/{name}/innovation", steps, result.innovations[:, j], times)
        if self.candidates is not None:
            from hybridtrack.clutter import log_associations

            log_associations(rec, self.filter_names, steps, [r.innovation for r in self._results], times)
        for detector, series in result.statistics.items():
            for key, values in series.items():
                rec.log_scalars(f"detector/{detector}/{key}", steps, values, times)
        for decision in result.decisions:
            rec.log_event(decision.step, f"{decision.detector}: {decision.mode} ({decision.message})", decision.step * self.tau)


@attrs.frozen(eq=False)
class ScheduleRun:
    """Estimates of a filter told the true modes: means (K+1, n), covs (K+1, n, n), nis (K+1,)."""

    layout: tuple[str, ...]
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
    tau: float,
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
    """
    from hybridtrack.simulate import build_models

    models = build_models(schedule, _registry(registry), noise_cov)
    network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
    z = network.stack(measurements)
    if z.shape[0] != schedule.total_steps + 1:
        raise ValueError(f"measurements: expected {schedule.total_steps + 1} steps for the schedule, got {z.shape[0]}")
    prior = prior if isinstance(prior, Gaussian) else Gaussian(*prior)
    means, covs, nis = [], [], []
    start = 0
    for model, segment in zip(models, schedule.segments):
        rows = z[start : start + segment.steps + 1].copy()
        if start > 0:
            rows[0] = np.nan  # the switch step was already updated by the previous segment
        pipeline = Pipeline(
            models=[model], estimator=estimator, sensors=network, measurements=network.split(rows), prior=prior, tau=tau, registry=registry
        )
        result = pipeline.run()
        skip = 0 if start == 0 else 1
        means.append(result.means[skip:, 0])
        covs.append(result.covs[skip:, 0])
        nis.append(result.nis[skip:, 0])
        prior = Gaussian(result.means[-1, 0], (result.covs[-1, 0] + result.covs[-1, 0].T) / 2)
        start += segment.steps
    run = ScheduleRun(models[0].layout, np.concatenate(means), np.concatenate(covs), np.concatenate(nis))
    if recorder is not None:
        steps = np.arange(run.means.shape[0])
        position = [run.layout.index("x"), run.layout.index("y")]
        log_estimate(recorder, name, steps, run.means, run.covs, position, steps * tau)
        recorder.log_scalars(f"estimator/{name}/nis", steps, run.nis, steps * tau)
    return run
