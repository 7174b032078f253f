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
``("left_turn", {"radius": 3.0})``, ``("signal_function", {"window": 10}, "sf10")``
with a label).  Measurement times are ``times`` (seconds, strictly increasing,
any spacing: real data) or ``tau`` (regular sampling); each step's transition
is built for its own Δt, and the recording's ``time`` timeline holds the times.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.interfaces import Detector, DetectorStep, Estimator, Innovation, MotionModel, Sensor, TransitionBank
from hybridtrack.network import SensorNetwork
from hybridtrack.plugins import resolve
from hybridtrack.recording import NullRecorder, log_estimate, log_measurements
from hybridtrack.registry import Registry
from hybridtrack.timestamps import step_intervals
from hybridtrack.types import Decision, Gaussian


@attrs.frozen(eq=False)
class StepResult:
    """One step of a pipeline: its time, the bank's posterior, its innovation and the detectors' outputs (by label).

    With candidates in clutter ``innovation`` is a
    :class:`~hybridtrack.interfaces.ClutterInnovation` holding the associations.
    """

    step: int
    time: float
    mean: np.ndarray  # (M, n)
    cov: np.ndarray  # (M, n, n)
    innovation: Innovation
    detectors: dict[str, DetectorStep]


@attrs.frozen(eq=False)
class RunResult:
    """A whole run: times (K+1,), means (K+1, M, n), covs (K+1, M, n, n), nis and loglik (K+1, M), innovations
    (K+1, M, Σm) (NaN where a step lacked some measurement), detector statistics label → series →
    array over steps, and the decisions."""

    layout: tuple[str, ...]
    filters: tuple[str, ...]
    times: np.ndarray
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
    in the models' layout); ``times`` (seconds, one per measurement step) or
    ``tau`` (regular sampling); ``detectors`` (labels must be unique); ``recorder`` (defaults to
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
        tau: float | None = None,
        times=None,
        detectors: Sequence[Any] = (),
        recorder=None,
        truth=None,
        filter_names: Sequence[str] | None = None,
        registry: Registry | None = None,
        record_measurements: bool = True,
        candidates: Mapping[str, Any] | None = None,
    ):
        self.models: list[MotionModel] = [resolve("motion_model", m, registry) for m in models]
        if not self.models:
            raise ValueError("models: a bank needs at least one motion model")
        layouts = {m.layout for m in self.models}
        if len(layouts) != 1:
            raise ValueError(f"models: every filter of a bank must share one state layout, got {sorted(layouts)}")
        self.layout = self.models[0].layout
        self.estimator: Estimator = resolve("estimator", estimator, registry)
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.candidates = self._check_candidates(candidates, measurements)
        if self.candidates is not None:
            measurements = {name: seq.target_measurements() for name, seq in self.candidates.items()}
        elif measurements is None:
            raise ValueError("measurements: required (sensor name → (steps, m_i)) unless candidates are given")
        self.z = self.network.stack(measurements)
        self.times, self.intervals = step_intervals(times, tau, self.z.shape[0])
        self.detectors: list[Detector] = [resolve("detector", d, registry) for d in detectors]
        labels = [d.label for d in self.detectors]
        if len(set(labels)) != len(labels):
            raise ValueError(
                f"detectors: labels must be unique, got {labels}; give each instance a label, e.g. ('glr', {{...}}, 'glr_fast')"
            )
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
        self.state = self.estimator.initialize(np.tile(prior.mean, (M, 1)), np.tile(prior.cov, (M, 1, 1)))
        self.linear = all(m.linear for m in self.models)
        self._transitions: tuple[float, TransitionBank] | None = None
        self.results: list[StepResult] = []
        self.decisions: list[Decision] = []
        self._result: RunResult | None = None
        self._recorded = False

    def _check_candidates(self, candidates, measurements):
        """Validate ``candidates`` (one ScanSequence per network sensor) against the estimator."""
        if candidates is None:
            return None
        from hybridtrack.clutter import ScanSequence

        if measurements is not None:
            raise ValueError("candidates: give either measurements or candidates, not both")
        if not self.estimator.accepts_scans:
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
        names = [model.name if model.radius is None else f"{model.name}_r{model.radius:g}" for model in self.models]
        # make repeated names unique
        return tuple(n if names.count(n) == 1 else f"{n}_{i}" for i, n in enumerate(names))

    @property
    def steps(self) -> int:
        """Number of steps in the measurements (0..steps−1)."""
        return self.z.shape[0]

    @property
    def done(self) -> bool:
        return len(self.results) >= self.steps

    def transitions(self, dt: float) -> TransitionBank:
        """The bank's transitions over ``dt`` seconds.

        Linear models: fixed at the prior mean (the switch state) and rebuilt
        only when Δt changes; nonlinear models: relinearized at each filter's
        current mean every step (EKF).
        """
        if not self.linear:
            means = self.estimator.mean(self.state)
            return TransitionBank.stack([m.transition(dt, x) for m, x in zip(self.models, means)])
        if self._transitions is None or self._transitions[0] != dt:
            self._transitions = (dt, TransitionBank.stack([m.transition(dt, self.prior.mean) for m in self.models]))
        return self._transitions[1]

    def step(self) -> StepResult:
        """Process the next step and return its result."""
        k = len(self.results)
        if k >= self.steps:
            raise StopIteration(f"all {self.steps} steps processed")
        state = self.state
        if k > 0:
            state = self.estimator.predict(state, self.transitions(float(self.intervals[k - 1])))
        z = self.z[k] if self.candidates is None else [seq.scan(k) for seq in self.candidates.values()]
        state, innovation = self.estimator.update(state, z, self.network.sensors, self.layout)
        self.state = state
        outputs = {}
        for detector in self.detectors:
            output = detector.step(k, innovation)
            outputs[detector.label] = output
            if output.decision is not None:
                self.decisions.append(attrs.evolve(output.decision, time=float(self.times[k])))
        result = StepResult(k, float(self.times[k]), self.estimator.mean(state), self.estimator.covariance(state), innovation, outputs)
        self.results.append(result)
        self._result = None
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
        """The steps processed so far as arrays (built once per number of steps processed)."""
        if not self.results:
            raise RuntimeError("no step has been processed yet")
        if self._result is None:
            self._result = self._build_result()
        return self._result

    def _build_result(self) -> RunResult:
        M = len(self.models)
        statistics: dict[str, dict[str, list]] = {}
        for r in self.results:
            for name, output in r.detectors.items():
                series = statistics.setdefault(name, {})
                for key, value in {**output.statistics, **output.thresholds}.items():
                    series.setdefault(key, []).append(value)

        full = self.network.measurement_dim
        missing = np.full(M, np.nan)
        nis, loglik, innovations = [], [], []
        for r in self.results:
            complete = r.innovation.measurement_dim > 0
            nis.append(r.innovation.nis if complete else missing)
            loglik.append(r.innovation.loglik if complete else missing)
            innovations.append(r.innovation.nu if r.innovation.measurement_dim == full else np.full((M, full), np.nan))
        return RunResult(
            layout=self.layout,
            filters=self.filter_names,
            times=self.times[: len(self.results)],
            means=np.stack([r.mean for r in self.results]),
            covs=np.stack([r.cov for r in self.results]),
            nis=np.stack(nis).astype(float),
            loglik=np.stack(loglik).astype(float),
            innovations=np.stack(innovations).astype(float),
            statistics={n: {k: np.asarray(v, dtype=float) for k, v in s.items()} for n, s in statistics.items()},
            decisions=tuple(self.decisions),
        )

    def record(self) -> None:
        """Log the truth, measurements, estimates, NIS, detector series and decisions (once)."""
        if self._recorded or not self.results:
            return
        self._recorded = True
        rec = self.recorder
        result = self.result()
        steps = np.arange(len(self.results))
        times = result.times
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

            log_associations(rec, self.filter_names, steps, [r.innovation for r in self.results], times)
        for detector, series in result.statistics.items():
            for key, values in series.items():
                rec.log_scalars(f"detector/{detector}/{key}", steps, values, times)
        for decision in result.decisions:
            rec.log_event(decision.step, f"{decision.detector}: {decision.mode} ({decision.message})", decision.time)
