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
:mod:`hybridtrack.io.measurement_files` for the CSV/NPZ layouts.  In clutter they
are instead ``candidates``, sensor name → :class:`~hybridtrack.sdk.scans.ScanSequence`
(a variable number of candidate measurements per step), for an estimator that
associates them (``nearest_neighbour``, ``pda``: ``accepts_scans = True``).

Components are given as objects or by registered name (``"kalman"``,
``("left_turn", {"radius": 3.0})``, ``("signal_function", {"window": 10}, "sf10")``
with a label).  Measurement times are ``times`` (seconds, strictly increasing,
any spacing: real data) or ``tau`` (regular sampling); each step's transition
is built for its own Δt, and the recording's ``time`` timeline holds the times.

Memory: the per-step results live in arrays preallocated for the K steps of the
measurements (means (K, M, n), covariances (K, M, n, n), NIS, ℓ, ν and S, the
detectors' series), not in one object per step; :meth:`Pipeline.result` returns
read-only views of them and ``pipeline.results[k]`` rebuilds the
:class:`StepResult` of step k from them.  Recording is streamed: the rows
processed since the last flush are sent to the recorder every ``record_every``
steps or ``record_seconds`` seconds of wall time, whichever comes first, and the
recorder is flushed to disk, so a killed run loses at most that much work.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any, overload

import attrs
import numpy as np

from hybridtrack.core.interfaces import Detector, DetectorStep, Estimator, Innovation, MotionModel, Sensor, TransitionBank
from hybridtrack.core.plugins import resolve
from hybridtrack.core.registry import Registry
from hybridtrack.core.types import Decision, Gaussian
from hybridtrack.recording import NullRecorder, decision_text, log_estimate, log_measurements, nis_bounds
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_intervals

#: the most steps whose bank states a recording pipeline keeps before it streams them
#: (for estimators that record their states: particle clouds, mixtures, hypotheses)
STATE_CHUNK = 100


def mode_label(model: MotionModel) -> str:
    """The registry name, with the radius for a turn mode (``left_turn_r3``)."""
    return model.name if model.radius is None else f"{model.name}_r{model.radius:g}"


def mode_labels(models: Sequence[MotionModel]) -> tuple[str, ...]:
    """:func:`mode_label` of each model, a repeated one suffixed with its index (``straight_0``, ``straight_2``)."""
    labels = [mode_label(m) for m in models]
    return tuple(x if labels.count(x) == 1 else f"{x}_{i}" for i, x in enumerate(labels))


@attrs.frozen(eq=False)
class StepResult:
    """One step of a pipeline: its time, the bank's posterior, its innovation and the detectors' outputs (by label).

    With candidates in clutter ``innovation`` is a
    :class:`~hybridtrack.core.interfaces.ClutterInnovation` holding the associations.
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


def store_detector_outputs(
    series: dict[str, dict[str, np.ndarray]],
    statistic_keys: dict[str, set[str]],
    threshold_keys: dict[str, set[str]],
    k: int,
    steps: int,
    outputs: Mapping[str, DetectorStep],
) -> None:
    """Write the detectors' outputs of step k (label → DetectorStep) into ``series`` (label → name → (steps, …),
    NaN where a detector did not report that name) and note which names are statistics and which thresholds."""
    for label, output in outputs.items():
        table = series.setdefault(label, {})
        statistic_keys.setdefault(label, set()).update(output.statistics)
        threshold_keys.setdefault(label, set()).update(output.thresholds)
        for key, value in {**output.statistics, **output.thresholds}.items():
            value = np.asarray(value, dtype=float)
            if key not in table:
                table[key] = np.full((steps, *value.shape), np.nan)
            elif table[key].shape[1:] != value.shape:
                raise ValueError(
                    f"detector {label!r}: series {key!r} changed shape at step {k}: "
                    f"got {value.shape}, expected {table[key].shape[1:]} as at its earlier steps"
                )
            table[key][k] = value


class StepResults(Sequence):
    """The steps processed so far, ``pipeline.results``: ``len``, ``results[k]`` (negative k and slices too), iteration.

    Each :class:`StepResult` is rebuilt from the pipeline's preallocated arrays
    (copies, so changing one does not change the pipeline).  The innovation of a
    step with every measurement component is an :class:`Innovation` of the stored
    ν, S, ℓ and NIS; other steps (missing components, clutter associations) keep
    the estimator's own object.  Detector outputs hold every series the detector
    has reported so far (NaN at steps where it did not report one).
    """

    def __init__(self, pipeline: Pipeline):
        self._pipeline = pipeline

    def __len__(self) -> int:
        return self._pipeline._count

    @overload
    def __getitem__(self, k: int) -> StepResult: ...
    @overload
    def __getitem__(self, k: slice) -> list[StepResult]: ...
    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self._pipeline._step_result(i) for i in range(*k.indices(len(self)))]
        if not isinstance(k, (int, np.integer)) or isinstance(k, bool):
            raise TypeError(f"results[{k!r}]: expected an integer step or a slice")
        n = len(self)
        if not -n <= k < n:
            raise IndexError(f"results[{k}]: step out of range, {n} steps processed")
        return self._pipeline._step_result(int(k) % n)


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
    ``candidates`` (sensor name → :class:`~hybridtrack.sdk.scans.ScanSequence`, one
    per sensor) in place of ``measurements`` when tracking in clutter: each step
    passes the sensors' :class:`~hybridtrack.sdk.scans.Scan` list to an estimator
    with ``accepts_scans``; clutter, gates and association weights are recorded;
    ``record_every`` (steps, default 10,000) and ``record_seconds`` (wall-clock
    seconds, default 2.0; None: by steps only, so that two runs with the same seed
    always give the same chunks) bound how much work a killed recorded run loses.
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
        record_every: int = 10_000,
        record_seconds: float | None = 2.0,
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
        bad = [n for n in self.filter_names if not isinstance(n, str) or not n.strip() or "/" in n]
        if bad:
            raise ValueError(f"filter_names: expected non-empty names without '/' (each names recorded entities), got {bad!r}")
        repeated = sorted({n for n in self.filter_names if self.filter_names.count(n) > 1})
        if repeated:
            raise ValueError(f"filter_names: names must be unique (each names the filter's recorded entities), {repeated} repeated")
        for detector in self.detectors:  # decisions and recorded series name the filters, not H0, H1, …
            if getattr(detector, "hypotheses", ()) is None:
                detector.hypotheses = self.filter_names

        prior = prior if isinstance(prior, Gaussian) else Gaussian(*prior)
        if prior.dim != len(self.layout):
            raise ValueError(f"prior: expected a state of the layout {self.layout}, got dimension {prior.dim}")
        self.prior = prior
        M = len(self.models)
        self.state = self.estimator.initialize(np.tile(prior.mean, (M, 1)), np.tile(prior.cov, (M, 1, 1)))
        self.linear = all(m.linear for m in self.models)
        self._transitions: tuple[float, TransitionBank] | None = None
        if isinstance(record_every, bool) or not isinstance(record_every, (int, np.integer)) or record_every < 1:
            raise ValueError(f"record_every: expected a whole number of steps ≥ 1, got {record_every!r}")
        if record_seconds is not None and not (isinstance(record_seconds, (int, float)) and record_seconds > 0):
            raise ValueError(f"record_seconds: expected a positive number of seconds or None, got {record_seconds!r}")
        self.record_every = int(record_every)
        self.record_seconds = record_seconds
        self._allocate(M)
        self.results = StepResults(self)
        self.decisions: list[Decision] = []
        self._result: RunResult | None = None
        self._logged = 0  # steps already sent to the recorder
        #: the states of the steps not yet streamed, for an estimator that records them (Estimator.records_states)
        self._pending_states = (
            [] if getattr(self.estimator, "records_states", False) and not isinstance(self.recorder, NullRecorder) else None
        )
        self._static_logged = 0  # number of steps the static path lines were logged for
        self._last_flush = time.monotonic()

    def _allocate(self, M: int) -> None:
        """Preallocate the per-step arrays for the K measurement steps (pages are touched only as steps fill them)."""
        K, n, m = self.steps, len(self.layout), self.network.measurement_dim
        self._count = 0
        self._means = np.empty((K, M, n))
        self._covs = np.empty((K, M, n, n))
        self._nis = np.empty((K, M))
        self._loglik = np.empty((K, M))
        self._nu = np.empty((K, M, m))  # NaN rows where a step lacked some measurement
        self._S = np.empty((K, M, m, m))
        self._innovation_objects: dict[int, Innovation] = {}  # steps whose innovation is not a complete plain one
        self._series: dict[str, dict[str, np.ndarray]] = {}  # detector label → series → (K, ...) NaN-filled
        self._threshold_keys: dict[str, set[str]] = {}
        self._statistic_keys: dict[str, set[str]] = {}
        self._decision_at: dict[tuple[int, str], Decision] = {}

    def _check_candidates(self, candidates, measurements):
        """Validate ``candidates`` (one ScanSequence per network sensor) against the estimator."""
        if candidates is None:
            return None
        from hybridtrack.sdk.scans import ScanSequence

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
        return mode_labels(self.models)

    @property
    def steps(self) -> int:
        """Number of steps in the measurements (0..steps−1)."""
        return self.z.shape[0]

    @property
    def done(self) -> bool:
        return self._count >= self.steps

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
        """Process the next step, store it, stream the recording when due, and return the step's result."""
        k = self._count
        if k >= self.steps:
            raise StopIteration(f"all {self.steps} steps processed")
        state = self.state
        if k > 0:
            state = self.estimator.predict(state, self.transitions(float(self.intervals[k - 1])))
        z = self.z[k] if self.candidates is None else [seq.scan(k) for seq in self.candidates.values()]
        state, innovation = self.estimator.update(state, z, self.network.sensors, self.layout)
        self.state = state
        if self._pending_states is not None:
            self._pending_states.append(state)
        outputs = {}
        for detector in self.detectors:
            output = detector.step(k, innovation)
            outputs[detector.label] = output
            if output.decision is not None:
                decision = attrs.evolve(output.decision, time=float(self.times[k]))
                self.decisions.append(decision)
                self._decision_at[(k, detector.label)] = decision
        mean, cov = self.estimator.mean(state), self.estimator.covariance(state)
        self._store(k, mean, cov, innovation, outputs)
        self._count = k + 1
        self._result = None
        due = self._count - self._logged
        if (
            due >= self.record_every
            or (self._pending_states is not None and due >= STATE_CHUNK)
            or (self.record_seconds is not None and time.monotonic() - self._last_flush >= self.record_seconds)
        ):
            self._stream()
        return StepResult(k, float(self.times[k]), mean, cov, innovation, outputs)

    def _store(self, k: int, mean, cov, innovation: Innovation, outputs: dict[str, DetectorStep]) -> None:
        """Write step k into the preallocated arrays (see :class:`RunResult` for the NaN conventions)."""
        M, m = self._nu.shape[1:]
        self._means[k] = mean
        self._covs[k] = cov
        dim = innovation.measurement_dim
        self._nis[k] = innovation.nis if dim > 0 else np.nan
        self._loglik[k] = innovation.loglik if dim > 0 else np.nan
        complete = dim == m and np.shape(innovation.nu) == (M, m) and np.shape(innovation.S) == (M, m, m)
        if complete:
            self._nu[k] = innovation.nu
            self._S[k] = innovation.S
        else:
            self._nu[k] = np.nan
            self._S[k] = np.nan
        if not complete or type(innovation) is not Innovation:
            self._innovation_objects[k] = innovation
        store_detector_outputs(self._series, self._statistic_keys, self._threshold_keys, k, self.steps, outputs)

    def _step_result(self, k: int) -> StepResult:
        """The :class:`StepResult` of processed step k, rebuilt from the stored arrays."""
        innovation = self._innovation_objects.get(k)
        if innovation is None:
            innovation = Innovation(self._nu[k].copy(), self._S[k].copy(), self._loglik[k].copy(), self._nis[k].copy())
        outputs = {}
        for detector in self.detectors:
            label = detector.label
            series = self._series.get(label, {})
            value = {key: (float(a[k]) if a.ndim == 1 else a[k].copy()) for key, a in series.items()}
            thresholds = self._threshold_keys.get(label, set())
            statistics = self._statistic_keys.get(label, set())
            outputs[label] = DetectorStep(
                statistics={key: v for key, v in value.items() if key in statistics},
                thresholds={key: v for key, v in value.items() if key in thresholds},
                decision=self._decision_at.get((k, label)),
            )
        return StepResult(k, float(self.times[k]), self._means[k].copy(), self._covs[k].copy(), innovation, outputs)

    def run(self) -> RunResult:
        """Process the remaining steps, record the run and return it.

        If a step raises, what was processed before is still recorded.  While it
        runs, the recording is streamed (see ``record_every``/``record_seconds``).
        """
        try:
            while not self.done:
                self.step()
        finally:
            self.record()
        return self.result()

    @classmethod
    def run_batch(
        cls, measurements: Mapping[str, np.ndarray], prior, *, times=None, truth=None, recorders=None, **options
    ) -> list[RunResult]:
        """Run R measurement sequences as one stacked bank of R × M filters: one :class:`RunResult` per run,
        equal to ``Pipeline(..., measurements=run r).run()`` (see :func:`hybridtrack.engine.batch.run_pipeline_batch`,
        which takes the same ``options`` as the constructor: ``models``, ``estimator``, ``sensors``, ``tau``,
        ``detectors``, ``filter_names``, ``registry``)."""
        from hybridtrack.engine.batch import run_pipeline_batch

        return run_pipeline_batch(measurements, prior, times=times, truth=truth, recorders=recorders, **options)

    def replay(self, result: RunResult, threshold_keys: Mapping[str, set[str]] | None = None) -> None:
        """Load a finished run (e.g. one run of :meth:`run_batch`) of this pipeline's measurements into its storage
        and record it; ``threshold_keys`` (label → names) tells thresholds from statistics in ``results[k]``."""
        if self._count:
            raise RuntimeError("replay: this pipeline has already processed steps")
        k = result.means.shape[0]
        if k != self.steps or result.means.shape[1:] != self._means.shape[1:]:
            raise ValueError(f"result: expected a run of {self.steps} steps of this bank, got means of shape {result.means.shape}")
        self._means[:], self._covs[:], self._nis[:], self._loglik[:], self._nu[:] = (
            result.means,
            result.covs,
            result.nis,
            result.loglik,
            result.innovations,
        )
        self._S[:] = np.nan
        threshold_keys = threshold_keys or {}
        for label, series in result.statistics.items():
            self._series[label] = {key: np.array(values) for key, values in series.items()}
            self._threshold_keys[label] = set(threshold_keys.get(label, ()))
            self._statistic_keys[label] = set(series) - self._threshold_keys[label]
        self.decisions = list(result.decisions)
        self._decision_at = {(d.step, d.detector): d for d in result.decisions}
        self._count = k
        self._result = None
        self.record()

    def result(self) -> RunResult:
        """The steps processed so far as arrays: read-only views of the pipeline's storage (no copy)."""
        if not self._count:
            raise RuntimeError("no step has been processed yet")
        if self._result is None:
            self._result = self._build_result()
        return self._result

    def _build_result(self) -> RunResult:
        k = self._count

        def view(array):
            out = array[:k]
            out.flags.writeable = False
            return out

        return RunResult(
            layout=self.layout,
            filters=self.filter_names,
            times=view(self.times),
            means=view(self._means),
            covs=view(self._covs),
            nis=view(self._nis),
            loglik=view(self._loglik),
            innovations=view(self._nu),
            statistics={label: {key: view(a) for key, a in series.items()} for label, series in self._series.items()},
            decisions=tuple(self.decisions),
        )

    def record(self) -> None:
        """Bring the recording up to date: the steps not yet streamed, then the static path lines, then a flush.

        Logs the truth, measurements, estimates (points and 2σ ellipses), NIS, ℓ,
        ν, clutter associations, detector series and decisions of the new steps;
        calling it again without new steps logs nothing.
        """
        if self._count == 0 or self._static_logged == self._count or isinstance(self.recorder, NullRecorder):
            return
        self._stream(flush=False)
        rec = self.recorder
        k = self._count
        steps, times = np.arange(k), self.times[:k]
        if self.truth is not None:
            rec.log_path("world/truth", steps, self.truth.positions[:k], times, points=False)
        position = [self.layout.index("x"), self.layout.index("y")]
        for j, name in enumerate(self.filter_names):
            rec.log_path(f"world/estimate/{name}", steps, self._means[:k, j][:, position], times, points=False)
        self._static_logged = k
        self._flush_recorder()

    def _flush_recorder(self) -> None:
        flush = getattr(self.recorder, "flush", None)
        if flush is not None:
            flush()
        self._last_flush = time.monotonic()

    def _stream(self, flush: bool = True) -> None:
        """Log steps [logged, processed) to the recorder (per-step rows only; the static path lines come in :meth:`record`)."""
        start, stop = self._logged, self._count
        if stop <= start or isinstance(self.recorder, NullRecorder):
            self._logged = stop
            self._last_flush = time.monotonic()
            return
        rec = self.recorder
        rows = slice(start, stop)
        steps, times = np.arange(start, stop), self.times[rows]
        if self.truth is not None:
            positions = self.truth.positions[rows]
            rec.log_path("world/truth", steps[: len(positions)], positions, times[: len(positions)], line=False)
        if self.record_measurements and self.candidates is not None:
            for seq in self.candidates.values():  # as hybridtrack.recording.clutter.log_scans, for rows start..stop
                if seq.measurement_dim == 2:
                    rec.log_points(f"world/measurements/{seq.sensor}", steps, seq.target_measurements()[rows], times)
                    false = seq.false_measurements()[rows]
                    if false.shape[1]:
                        rec.log_points(f"world/clutter/{seq.sensor}", steps, false, times)
        elif self.record_measurements:
            log_measurements(rec, self.network.sensors, self.network.split(self.z[rows]), steps, times)
        position = [self.layout.index("x"), self.layout.index("y")]
        for j, name in enumerate(self.filter_names):
            log_estimate(rec, name, steps, self._means[rows, j], self._covs[rows, j], position, times, line=False)
            rec.log_scalars(f"estimator/{name}/nis", steps, self._nis[rows, j], times)
            rec.log_scalars(f"estimator/{name}/loglik", steps, self._loglik[rows, j], times)
            rec.log_scalars(f"estimator/{name}/innovation", steps, self._nu[rows, j], times)
        rec.log_scalars(
            "estimator/nis_bounds", steps, nis_bounds(np.isfinite(self.z[rows]).sum(axis=1)), times, names=["χ² 2.5 %", "χ² 97.5 %"]
        )
        if self.candidates is not None:
            from hybridtrack.recording.clutter import log_associations

            log_associations(rec, self.filter_names, steps, [self._innovation_objects.get(i) for i in steps], times)
        for detector in self.detectors:
            hypotheses = tuple(getattr(detector, "hypotheses", None) or self.filter_names)
            for key, values in self._series.get(detector.label, {}).items():
                width = values.shape[1] if values.ndim == 2 else 0
                names = hypotheses if width == len(hypotheses) else hypotheses[1:] if width == len(hypotheses) - 1 else None
                rec.log_scalars(f"detector/{detector.label}/{key}", steps, values[rows], times, names=names)
        for decision in self.decisions:
            if start <= decision.step < stop:
                rec.log_event(decision.step, decision_text(decision), decision.time)
        if self._pending_states:
            self.estimator.record_states(rec, self.filter_names, steps, self._pending_states, self.layout, times)
            self._pending_states.clear()
        self._logged = stop
        if flush:
            self._flush_recorder()
