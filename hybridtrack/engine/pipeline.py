"""Compose and run: measurements → estimator bank → detectors, over one run or R runs as one bank.

A :class:`Pipeline` runs one bank of M filters, filter j using motion model j,
on the stacked measurements of a sensor network:

* step 0: each filter starts from the prior and is updated with z_0 (when row 0
  has data);
* step k ≥ 1: predict with the model's transition, then update with z_k.

A linear model's transition is fixed from the prior mean, the state at the
switching moment (SPEC §1: a turn's ω and centre are fixed at the switch); a
nonlinear model is relinearized at each filter's own estimate every step
(EKF).  Each step's transition is built for its own Δt (``times`` or ``tau``).

**R runs, one loop.**  A run is a batch of one: :meth:`Pipeline.batch` runs R
measurement sequences as one :class:`~hybridtrack.engine.bank.FilterBank` of
R × M filters (row r·M + j is filter j of run r), each run with its own copy of
every detector (``detector.batch(R)``) and, for a sampling estimator, of the
estimator; the results equal R single runs to 1e-12 (tests/engine/test_batch.py).

The per-step results live in arrays preallocated for the K steps:
:meth:`Pipeline.result` returns read-only views of them, ``pipeline.results[k]``
rebuilds step k's :class:`StepResult`.  Recording is not done here: the
recorders get the finished steps, ``recorder.log_result(result, start=…, …)``
(:func:`hybridtrack.recording.pipeline.log_pipeline`), every ``record_every``
steps or ``record_seconds`` seconds, each chunk flushed.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.core.interfaces import Detector, DetectorStep, Estimator, Innovation, MotionModel, Sensor
from hybridtrack.core.plugins import resolve
from hybridtrack.core.registry import Registry
from hybridtrack.core.types import Decision, Gaussian
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.batch import batch_times, per_run, prior_arrays, stacked_measurements
from hybridtrack.engine.clutter import ScanSequence
from hybridtrack.engine.results import RunResult
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_intervals

#: the most steps whose bank states a recording pipeline keeps before it hands them over
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
    :class:`~hybridtrack.core.protocols.ClutterInnovation` holding the associations.
    """

    step: int
    time: float
    mean: np.ndarray  # (M, n)
    cov: np.ndarray  # (M, n, n)
    innovation: Innovation
    detectors: dict[str, DetectorStep]


@attrs.frozen(eq=False, kw_only=True)
class PipelineResult(RunResult):
    """A fixed bank's run: :class:`~hybridtrack.engine.results.RunResult` with ``modes`` the filter names, means
    (K+1, M, n), covs (K+1, M, n, n) for every filter and ``mode`` None; plus ``nis`` and ``loglik`` (K+1, M)
    (NaN where nothing was measured), ``innovations`` ν (K+1, M, Σm) (NaN where a step lacked some measurement)
    and the detectors' ``statistics``, label → series → array over steps (NaN where a detector did not report)."""

    nis: np.ndarray
    loglik: np.ndarray
    innovations: np.ndarray
    statistics: dict[str, dict[str, np.ndarray]]

    @property
    def filters(self) -> tuple[str, ...]:
        """The filter names (``modes``)."""
        return self.modes


class StepResults(Sequence):
    """The steps processed so far, ``pipeline.results``: ``len``, ``results[k]`` (negative k and slices too), iteration.

    Each :class:`StepResult` (of run 0) is a copy rebuilt from the stored arrays: an :class:`Innovation` of the
    stored ν, S, ℓ and NIS (a single run's steps with missing components or clutter associations keep the
    estimator's own object), the detectors' series (NaN where a detector did not report one).
    """

    def __init__(self, pipeline: Pipeline):
        self.pipeline = pipeline

    def __len__(self) -> int:
        return self.pipeline.processed

    def __getitem__(self, k: int | slice) -> StepResult | list[StepResult]:
        if isinstance(k, slice):
            return [self.pipeline.step_result(i) for i in range(*k.indices(len(self)))]
        if not isinstance(k, (int, np.integer)) or isinstance(k, bool):
            raise TypeError(f"results[{k!r}]: expected an integer step or a slice")
        n = len(self)
        if not -n <= k < n:
            raise IndexError(f"results[{k}]: step out of range, {n} steps processed")
        return self.pipeline.step_result(int(k) % n)


class Pipeline:
    """A bank of filters (one per motion model) on a network's measurements, with detectors and a recorder.

    Parameters: ``models`` (motion models, names or (name, parameters)); ``estimator``; ``sensors`` (a
    :class:`SensorNetwork` or a list); ``measurements`` (sensor name → (steps, m_i)); ``prior`` (a
    :class:`Gaussian` or (mean, cov), in the models' layout); ``times`` (seconds, one per step) or ``tau``;
    ``detectors`` (unique labels); ``recorder`` (None: nothing recorded); ``truth`` (a trajectory recorded beside
    the estimates); ``filter_names``; ``record_measurements`` (False when another pipeline on the recorder logs
    them); ``candidates`` (sensor name → :class:`~hybridtrack.engine.clutter.ScanSequence`) in place of
    ``measurements`` in clutter, for an estimator with ``accepts_scans``; ``record_every`` (steps, default 10,000)
    and ``record_seconds`` (wall-clock seconds, default 2.0; None: by steps only, the same chunks every run)
    bound how much work a killed recorded run loses.  R runs at once: :meth:`batch`, :meth:`run_batch`.
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
        self.compose(models, estimator, sensors, detectors, filter_names, registry)
        self.candidates = self.check_candidates(candidates, measurements)
        if self.candidates is not None:
            measurements = {name: seq.target_measurements() for name, seq in self.candidates.items()}
        elif measurements is None:
            raise ValueError("measurements: required (sensor name → (steps, m_i)) unless candidates are given")
        z = self.network.stack(measurements)
        if z.shape[0] == 0:
            shapes = ", ".join(f"{name!r} {np.shape(value)}" for name, value in measurements.items())
            raise ValueError(f"measurements: expected at least one step (a row per step) for the sensors, got 0 steps ({shapes})")
        t, dt = step_intervals(times, tau, z.shape[0])
        self.start(
            z[None], t[None], dt[None], prior_arrays(prior, 1), [recorder], [truth], record_measurements, record_every, record_seconds
        )

    @classmethod
    def batch(cls, measurements: Mapping[str, np.ndarray], prior, *, times=None, truth=None, recorders=None, **options) -> Pipeline:
        """R runs as one pipeline over a bank of R × M filters (module docstring), ready to :meth:`run`.

        ``measurements``: sensor name → (R, K+1, m_i) (NaN: not measured); ``prior``: one Gaussian (or (mean,
        cov)), or per-run means (R, n) and covariances (R, n, n); ``times``: (K+1,) shared or (R, K+1), or
        ``tau``; ``truth``: per-run trajectories (sequence of R or mapping run → trajectory); ``recorders``: run
        index → recorder.  ``options`` as for the constructor; clutter candidates are not batched.
        """
        if "candidates" in options:
            raise ValueError("candidates: clutter candidates are not batched; run those one by one")
        tau = options.pop("tau", None)
        streaming = {key: options.pop(key) for key in ("record_measurements", "record_every", "record_seconds") if key in options}
        pipeline = cls.__new__(cls)
        pipeline.compose(**options)
        pipeline.candidates = None
        z = stacked_measurements(pipeline.network, measurements)
        R, steps = z.shape[:2]
        t, dt = batch_times(times, tau, R, steps)
        priors, truths, recorders = prior_arrays(prior, R), per_run(truth, R, "truth"), per_run(recorders, R, "recorders")
        pipeline.start(z, t, dt, priors, recorders, truths, **streaming)
        return pipeline

    @classmethod
    def run_batch(cls, measurements: Mapping[str, np.ndarray], prior, **options) -> list[PipelineResult]:
        """Run R measurement sequences as one stacked bank (:meth:`batch`, same arguments): one
        :class:`PipelineResult` per run, equal to ``Pipeline(..., measurements=run r).run()``."""
        pipeline = cls.batch(measurements, prior, **options)
        pipeline.run()
        return [pipeline.result(r) for r in range(pipeline.runs)]

    # -- composition
    def compose(self, models, estimator, sensors, detectors=(), filter_names=None, registry=None) -> None:
        """Resolve and check the components: the models (one layout), the estimator, the network, the detectors
        (unique labels) and the filter names."""
        self.models: list[MotionModel] = [resolve("motion_model", m, registry) for m in models]
        if not self.models:
            raise ValueError("models: a bank needs at least one motion model")
        layouts = {m.layout for m in self.models}
        if len(layouts) != 1:
            raise ValueError(f"models: every filter of a bank must share one state layout, got {sorted(layouts)}")
        self.layout = self.models[0].layout
        self.estimator: Estimator = resolve("estimator", estimator, registry)
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.detectors: list[Detector] = [resolve("detector", d, registry) for d in detectors]
        for detector in self.detectors:
            algorithm = getattr(detector, "requires_bank_management", None)
            if algorithm is not None:
                raise ValueError(
                    f"detectors: {detector.name!r} (label {detector.label!r}) needs the bank management of the algorithm"
                    f" {algorithm!r} (its hypotheses are filters the algorithm starts and prunes as it tests); a Pipeline's"
                    f" bank is fixed, so the test cannot do what it is for. Run the algorithm instead:"
                    f" resolve('algorithm', ({algorithm!r}, {{'detector': <this detector>, ...}})) (hybridtrack plugins lists the algorithms)"
                )
        self.labels = labels = [d.label for d in self.detectors]
        if len(set(labels)) != len(labels):
            raise ValueError(
                f"detectors: labels must be unique, got {labels}; give each instance a label, e.g. ('glr', {{...}}, 'glr_fast')"
            )
        self.filter_names = tuple(filter_names) if filter_names is not None else mode_labels(self.models)
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

    def check_candidates(self, candidates, measurements):
        """Validate ``candidates`` (one ScanSequence per network sensor) against the estimator."""
        if candidates is None:
            return None
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

    def start(self, z, t, dt, priors, recorders, truths, record_measurements=True, record_every=10_000, record_seconds=2.0) -> None:
        """Initialize the bank of R runs: measurements z (R, K, Σm), times t (R, K), Δt (R, K−1), the priors
        (means (R, n), covs (R, n, n)), one recorder and truth per run; preallocate the per-step arrays."""
        (x0, P0), M = priors, len(self.models)
        R = x0.shape[0]
        if x0.shape[1] != len(self.layout):
            raise ValueError(f"prior: expected a state of the layout {self.layout}, got dimension {x0.shape[1]}")
        if isinstance(record_every, bool) or not isinstance(record_every, (int, np.integer)) or record_every < 1:
            raise ValueError(f"record_every: expected a whole number of steps ≥ 1, got {record_every!r}")
        if record_seconds is not None and not (isinstance(record_seconds, (int, float)) and record_seconds > 0):
            raise ValueError(f"record_seconds: expected a positive number of seconds or None, got {record_seconds!r}")
        self.runs = R
        self.Z, self.T, self.DT = z, t, dt
        self.recorders, self.truths = list(recorders), list(truths)
        self.record_measurements = record_measurements
        self.record_every, self.record_seconds = int(record_every), record_seconds
        est = self.estimator
        self.bank = FilterBank(est, self.layout, self.network.sensors)
        means, run = np.repeat(x0, M, 0), np.repeat(np.arange(R), M)
        if est.sampling and R > 1:  # each run initialized as its own pipeline would be: a fresh copy of the estimator
            fresh = copy.deepcopy(est)
            state = est.concatenate([copy.deepcopy(fresh).initialize(np.tile(x, (M, 1)), np.tile(P, (M, 1, 1))) for x, P in zip(x0, P0)])
            self.bank.set(state, self.models * R, means, run)
        else:  # a linear model's transition fixed at its run's prior mean, the switch state
            self.bank.start(means, np.repeat(P0, M, 0), self.models * R, means, run)
        self.batches = [d.batch(R) for d in self.detectors] if R > 1 else None
        K, n, m = z.shape[1], len(self.layout), z.shape[2]
        self.processed = 0
        self.means, self.covs = np.empty((R, K, M, n)), np.empty((R, K, M, n, n))
        self.nis, self.loglik = np.empty((R, K, M)), np.empty((R, K, M))
        self.nu = np.empty((R, K, M, m))  # NaN rows where a step lacked some measurement
        self.S = np.empty((K, M, m, m))  # run 0's, for results[k]
        self.innovation_objects: dict[int, Innovation] = {}  # a single run's steps whose innovation is not a complete plain one
        self.series: list[dict[str, dict[str, np.ndarray]]] = [{} for _ in range(R)]  # label → series → (K, ...)
        self.statistic_keys: dict[str, set[str]] = {}
        self.threshold_keys: dict[str, set[str]] = {}
        self.run_decisions: list[list[Decision]] = [[] for _ in range(R)]
        self.decision_at: dict[tuple[int, str], Decision] = {}  # run 0's
        self.results = StepResults(self)
        self.logged = 0  # steps already handed to the recorders
        self.lines_logged = 0  # number of steps the static path lines were logged for
        recorded = [r for r, rec in enumerate(self.recorders) if rec is not None]
        self.recording = bool(recorded)
        #: per recorded run, the states of the steps not yet handed over (Estimator.records_states)
        self._pending_states = {r: [] for r in recorded} if recorded and getattr(est, "records_states", False) else None
        self.last_flush = time.monotonic()

    @property
    def steps(self) -> int:
        """Number of steps in the measurements (0..steps−1)."""
        return self.Z.shape[1]

    @property
    def done(self) -> bool:
        return self.processed >= self.steps

    @property
    def state(self) -> Any:
        """The bank's estimator state after the last step (every run's filters, run by run)."""
        return self.bank.state

    # -- the loop
    def step(self) -> StepResult:
        """Process the next step of every run, store it, hand the recorders their steps when due, and return the
        step's result (run 0's)."""
        k = self.processed
        if k >= self.steps:
            raise StopIteration(f"all {self.steps} steps processed")
        R, M = self.runs, len(self.models)
        est = self.estimator
        z = self.Z[:, k] if self.candidates is None else [seq.scan(k) for seq in self.candidates.values()]
        updates = self.bank.step(self.DT[:, k - 1] if k else None, z).updates
        state = self.bank.state
        if self._pending_states is not None:
            for r, pending in self._pending_states.items():
                pending.append(state if R == 1 else est.take(state, np.arange(r * M, (r + 1) * M)))
        mean, cov = self.bank.means, self.bank.raw_covs
        self.means[:, k] = mean.reshape(R, M, -1)
        self.covs[:, k] = cov.reshape(R, M, *self.covs.shape[-2:])
        for runs, innovation in updates:
            self.store_scores(k, runs, innovation)
            if R == 1:  # a single run steps the detectors it was given
                outputs = {d.label: d.step(k, innovation) for d in self.detectors}
                self.store_detectors(k, 0, outputs)
                continue
            columns = [b.step(k, runs, innovation) for b in self.batches]
            for position, r in enumerate(runs):
                self.store_detectors(k, int(r), {label: column[position] for label, column in zip(self.labels, columns)})
        self.processed = k + 1
        due = self.processed - self.logged
        if self.recording and (
            due >= self.record_every
            or (self._pending_states is not None and due >= STATE_CHUNK)
            or (self.record_seconds is not None and time.monotonic() - self.last_flush >= self.record_seconds)
        ):
            self.hand_over(lines=False)
        if R == 1:
            return StepResult(k, float(self.T[0, k]), mean, cov, updates[0][1], outputs)
        return self.step_result(k)

    def store_scores(self, k: int, runs: np.ndarray, innovation: Innovation) -> None:
        """Write step k's ℓ, NIS and ν of the runs ``runs`` (NaN: nothing measured / a component missing)."""
        G, (M, m) = runs.size, self.nu.shape[2:]
        rows = slice(None) if G == self.runs else runs  # every run: a plain slice is the faster write
        dim = innovation.measurement_dim
        self.nis[rows, k] = np.asarray(innovation.nis).reshape(G, M) if dim > 0 else np.nan
        self.loglik[rows, k] = np.asarray(innovation.loglik).reshape(G, M) if dim > 0 else np.nan
        complete = dim == m and np.shape(innovation.nu) == (G * M, m) and np.shape(innovation.S) == (G * M, m, m)
        self.nu[rows, k] = np.asarray(innovation.nu).reshape(G, M, m) if complete else np.nan
        if runs[0] == 0:
            self.S[k] = np.asarray(innovation.S)[:M] if complete else np.nan
            if self.runs == 1 and (not complete or type(innovation) is not Innovation):
                self.innovation_objects[k] = innovation

    def store_detectors(self, k: int, r: int, outputs: Mapping[str, DetectorStep]) -> None:
        """Write run r's detector outputs of step k into its series (label → name → (K, …), NaN where a detector
        did not report that name) and its decisions (timed with the run's step time)."""
        table_of = self.series[r]
        for label, output in outputs.items():
            table = table_of.setdefault(label, {})
            self.statistic_keys.setdefault(label, set()).update(output.statistics)
            self.threshold_keys.setdefault(label, set()).update(output.thresholds)
            for key, value in {**output.statistics, **output.thresholds}.items():
                value = np.asarray(value, dtype=float)
                if key not in table:
                    table[key] = np.full((self.steps, *value.shape), np.nan)
                elif table[key].shape[1:] != value.shape:
                    raise ValueError(
                        f"detector {label!r}: series {key!r} changed shape at step {k}: "
                        f"got {value.shape}, expected {table[key].shape[1:]} as at its earlier steps"
                    )
                table[key][k] = value
            if output.decision is not None:
                decision = attrs.evolve(output.decision, time=float(self.T[r, k]))
                self.run_decisions[r].append(decision)
                if r == 0:
                    self.decision_at[(k, label)] = decision

    def step_result(self, k: int) -> StepResult:
        """The :class:`StepResult` of processed step k (run 0), rebuilt from the stored arrays."""
        innovation = self.innovation_objects.get(k)
        if innovation is None:
            innovation = Innovation(self.nu[0, k].copy(), self.S[k].copy(), self.loglik[0, k].copy(), self.nis[0, k].copy())
        outputs = {}
        for detector in self.detectors:
            label = detector.label
            series = self.series[0].get(label, {})
            value = {key: (float(a[k]) if a.ndim == 1 else a[k].copy()) for key, a in series.items()}
            thresholds = self.threshold_keys.get(label, set())
            statistics = self.statistic_keys.get(label, set())
            outputs[label] = DetectorStep(
                statistics={key: v for key, v in value.items() if key in statistics},
                thresholds={key: v for key, v in value.items() if key in thresholds},
                decision=self.decision_at.get((k, label)),
            )
        return StepResult(k, float(self.T[0, k]), self.means[0, k].copy(), self.covs[0, k].copy(), innovation, outputs)

    def run(self) -> PipelineResult:
        """Process the remaining steps, record the run(s) and return run 0's result.

        If a step raises, what was processed before is still recorded.  While it
        runs, the recorders get their steps in chunks (``record_every``/``record_seconds``).
        """
        try:
            while not self.done:
                self.step()
        finally:
            self.record()
        return self.result()

    def result(self, run: int = 0) -> PipelineResult:
        """Run ``run``'s steps processed so far as arrays: read-only views of the pipeline's storage (no copy)."""
        if not self.processed:
            raise RuntimeError("no step has been processed yet")
        k = self.processed

        def view(array):
            out = array[:k]
            out.flags.writeable = False
            return out

        return PipelineResult(
            layout=self.layout,
            modes=self.filter_names,
            times=view(self.T[run]),
            means=view(self.means[run]),
            covs=view(self.covs[run]),
            decisions=tuple(self.run_decisions[run]),
            nis=view(self.nis[run]),
            loglik=view(self.loglik[run]),
            innovations=view(self.nu[run]),
            statistics={label: {key: view(a) for key, a in series.items()} for label, series in self.series[run].items()},
        )

    # -- recording: the recorders get finished steps, the writer is hybridtrack.recording.pipeline
    def record(self) -> None:
        """Bring the recordings up to date: the steps not yet handed over, the static path lines, a flush.

        Calling it again without new steps logs nothing.
        """
        if self.processed and self.lines_logged != self.processed and self.recording:
            self.hand_over(lines=True)

    def hand_over(self, lines: bool) -> None:
        """Give each recorder its run's steps [logged, processed) (``recorder.log_result``; with ``lines`` the static
        path lines of steps 0 … processed − 1 too) and flush it."""
        for r, recorder in enumerate(self.recorders):
            if recorder is None:
                continue
            states = None if self._pending_states is None else self._pending_states[r]
            recorder.log_result(
                self.result(r),
                start=self.logged,
                lines=lines,
                network=self.network,
                measurements=self.Z[r],
                candidates=self.candidates,
                truth=self.truths[r],
                record_measurements=self.record_measurements,
                hypotheses={d.label: tuple(getattr(d, "hypotheses", None) or self.filter_names) for d in self.detectors},
                innovations=self.innovation_objects,
                estimator=self.estimator,
                states=states,
            )
            if states:
                states.clear()
            flush = getattr(recorder, "flush", None)
            if flush is not None:
                flush()
        self.logged = self.processed
        if lines:
            self.lines_logged = self.processed
        self.last_flush = time.monotonic()
