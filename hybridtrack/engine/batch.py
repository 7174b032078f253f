"""Monte Carlo runs at bank speed: R measurement sequences through one stacked bank of R × M filters.

:func:`run_pipeline_batch` (also ``Pipeline.run_batch``) runs what R separate
:class:`~hybridtrack.engine.pipeline.Pipeline` s would run, run r on its own
measurements, times and prior, as one bank of the estimator: row r·M + j of
the bank is filter j (motion model j) of run r.  Each step is one ``predict``
and one ``update`` of the whole bank, so the interpreter's per-step cost is
paid once for all runs:

* **transitions**: a linear model's transition is fixed at run r's prior mean
  and rebuilt for run r's Δt_k (SPEC §1, as the pipeline); runs sharing (Δt,
  prior mean) share one block, and the stacked bank object is reused while
  nothing changes, so the estimator's per-bank caches hit.  A nonlinear model
  is relinearized at each filter's own mean (EKF), row by row;
* **measurements**: z_k of run r feeds the rows of run r ((R·M, Σm), one row
  per filter, :mod:`hybridtrack.sdk.measurements`).  A bank's NaN pattern must be
  one for all its filters, so when runs miss different components at step k
  the runs are grouped by pattern: each group is cut out with the
  estimator's ``take``, updated, and the groups joined back with
  ``concatenate`` and ``take`` (the bank keeps its own form, e.g. square-root
  factors);
* **detectors**: each run has its own copy of every detector (a deep copy of
  the one given, as a fresh per-run pipeline would have); a step of all runs
  is one call of the class's ``observe_runs`` (score detectors: ℓ and NIS
  (R, M)) or ``step_runs`` (others: each run's slice of the step's innovation,
  :func:`innovation_rows`) — loops over the copies by default, vectorized over
  the runs where the class overrides them (``Detector`` contract);
* **sampling estimators** (particle filters): each run's bank is initialized
  by its own copy of the estimator, so run r draws what a per-run pipeline
  with that estimator draws; later steps draw from streams carried in each
  filter's state (``Estimator`` contract), independent of the other rows.

Results equal the per-run pipeline to rounding (1e-12, tests/kernel/test_batch.py).
Recordings are made after the batch for the runs given in ``recorders`` (run
index → recorder) through :meth:`Pipeline.replay`.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.core.interfaces import Association, DetectorStep, Innovation, ScoreDetector, TransitionBank
from hybridtrack.core.plugins import resolve
from hybridtrack.core.types import Gaussian
from hybridtrack.core.validation import as_float_array
from hybridtrack.engine.pipeline import Pipeline, RunResult, store_detector_outputs
from hybridtrack.sdk.timestamps import step_intervals

#: Association fields stacked over the filters of the bank (the others describe the scan)
ASSOCIATION_ROWS = ("predicted", "S", "distances", "gated", "weights", "missed", "selected", "loglik")


def innovation_rows(innovation: Innovation, rows: np.ndarray, bank_size: int) -> Innovation:
    """The innovation of the filters ``rows`` of a bank of ``bank_size`` filters (same class, sliced).

    Every array field whose first axis has ``bank_size`` entries is indexed by
    ``rows`` (ν, S, ℓ, NIS and the extras of subclasses, e.g. a particle
    filter's effective sample sizes); the per-filter fields of each
    :class:`~hybridtrack.core.interfaces.Association` likewise; other fields are kept.
    """
    changes = {}
    for field in attrs.fields(type(innovation)):
        value = getattr(innovation, field.name)
        if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == bank_size:
            changes[field.name] = value[rows]
        elif isinstance(value, tuple) and value and all(isinstance(a, Association) for a in value):
            changes[field.name] = tuple(
                attrs.evolve(a, **{name: np.asarray(getattr(a, name))[rows] for name in ASSOCIATION_ROWS}) for a in value
            )
    return attrs.evolve(innovation, **changes)


def batch_measurements(measurements: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], int, int]:
    if not isinstance(measurements, Mapping) or not measurements:
        raise ValueError("measurements: expected a mapping sensor name → array (runs, K+1, m)")
    arrays = {
        name: as_float_array(value, f"measurements[{name!r}]", (None, None, None), allow_nan=True) for name, value in measurements.items()
    }
    shapes = {a.shape[:2] for a in arrays.values()}
    if len(shapes) != 1:
        raise ValueError(f"measurements: every sensor needs the same (runs, K+1), got {sorted(shapes)}")
    runs, steps = shapes.pop()
    if runs < 1 or steps < 1:
        raise ValueError(f"measurements: expected at least one run and one step, got (runs, K+1) = ({runs}, {steps})")
    return arrays, runs, steps


def batch_times(times, tau, runs: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Times (R, K+1) and Δt (R, K): ``times`` shared (K+1,) or per run (R, K+1), else ``tau``."""
    if times is None or np.ndim(times) == 1:
        t, dt = step_intervals(times, tau, steps)
        return np.broadcast_to(t, (runs, steps)), np.broadcast_to(dt, (runs, steps - 1))
    t = np.asarray(times, dtype=float)
    if t.shape != (runs, steps):
        raise ValueError(f"times: expected (K+1,) = ({steps},) shared or (runs, K+1) = ({runs}, {steps}) per run, got {t.shape}")
    pairs = [step_intervals(t[r], None, steps) for r in range(runs)]
    out_t, out_dt = np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])
    out_t.setflags(write=False)
    return out_t, out_dt


def batch_priors(prior, runs: int) -> list[Gaussian]:
    """One Gaussian per run from a shared prior (Gaussian or (mean (n,), cov (n, n))) or per-run (mean (R, n), cov (R, n, n))."""
    if isinstance(prior, Gaussian):
        return [prior] * runs
    if not isinstance(prior, (tuple, list)) or len(prior) != 2:
        raise ValueError("prior: expected a Gaussian, (mean (n,), cov (n, n)) or per-run (mean (runs, n), cov (runs, n, n))")
    mean = np.asarray(prior[0], dtype=float)
    if mean.ndim == 1:
        return [Gaussian(*prior)] * runs
    mean = as_float_array(mean, "prior mean", (runs, None))
    cov = as_float_array(prior[1], "prior cov", (runs, mean.shape[1], mean.shape[1]))
    return [Gaussian(mean[r], cov[r]) for r in range(runs)]


def per_run(value, runs: int, name: str) -> list:
    """``value`` given per run (a sequence of R, or a mapping run → value) as a list of R (None where absent)."""
    if value is None:
        return [None] * runs
    if isinstance(value, Mapping):
        bad = [r for r in value if not isinstance(r, (int, np.integer)) or not 0 <= r < runs]
        if bad:
            raise ValueError(f"{name}: run indices must be in 0 … {runs - 1}, got {bad}")
        return [value.get(r) for r in range(runs)]
    if isinstance(value, Sequence) and not isinstance(value, str) and len(value) == runs:
        return list(value)
    raise ValueError(f"{name}: expected a mapping run index → value or a sequence of {runs} (one per run)")


class _Transitions:
    """The stacked bank of transitions of R runs × M linear models, cached per (Δt, prior mean) block."""

    def __init__(self, models, priors: list[Gaussian]):
        self.models = models
        self.means = [p.mean for p in priors]
        shared = all(m is self.means[0] or np.array_equal(m, self.means[0]) for m in self.means)
        self.prior_keys = np.zeros(len(priors), dtype=np.int64) if shared else np.arange(len(priors))
        self.blocks: dict[tuple[float, int], TransitionBank] = {}
        self.last: tuple[bytes, TransitionBank] | None = None

    def block(self, dt: float, run: int) -> TransitionBank:
        key = (dt, int(self.prior_keys[run]))
        if key not in self.blocks:
            self.blocks[key] = TransitionBank.stack([m.transition(dt, self.means[run]) for m in self.models])
        return self.blocks[key]

    def bank(self, dt: np.ndarray) -> TransitionBank:
        key = np.stack([dt, self.prior_keys.astype(float)]).tobytes()
        if self.last is not None and self.last[0] == key:
            return self.last[1]
        blocks = [self.block(float(d), r) for r, d in enumerate(dt)]
        roots = [b.noise_root for b in blocks]
        same_roots = all(r is not None for r in roots) and len({r.shape for r in roots}) == 1
        bank = TransitionBank(
            np.concatenate([b.F for b in blocks]),
            np.concatenate([b.B for b in blocks]),
            np.concatenate([b.Q for b in blocks]),
            np.concatenate(roots) if same_roots else None,
        )
        self.last = (key, bank)
        return bank


def run_pipeline_batch(
    measurements: Mapping[str, np.ndarray],
    prior,
    *,
    times=None,
    truth=None,
    recorders: Mapping[int, Any] | None = None,
    models: Sequence[Any],
    estimator: Any,
    sensors,
    tau: float | None = None,
    detectors: Sequence[Any] = (),
    filter_names: Sequence[str] | None = None,
    registry=None,
) -> list[RunResult]:
    """R pipeline runs as one bank of R × M filters (module docstring); returns R :class:`RunResult` s.

    ``measurements``: sensor name → (R, K+1, m_i) (NaN: not measured); ``prior``:
    one Gaussian (or (mean, cov)) for all runs, or per-run means (R, n) and
    covariances (R, n, n); ``times``: (K+1,) shared or (R, K+1) per run, or
    ``tau``; ``truth``: per-run trajectories (sequence of R or mapping run →
    trajectory), recorded beside the estimates; ``recorders``: run index →
    recorder for the runs to record.  ``models``, ``estimator``, ``sensors``,
    ``detectors``, ``filter_names``, ``registry`` as for :class:`Pipeline`.
    Clutter candidates are not batched (run those per run).
    """
    arrays, R, steps = batch_measurements(measurements)
    T, DT = batch_times(times, tau, R, steps)
    priors = batch_priors(prior, R)
    truths = per_run(truth, R, "truth")
    recorders = dict(recorders or {})
    per_run(recorders, R, "recorders")
    estimator = resolve("estimator", estimator, registry)
    fresh = copy.deepcopy(estimator) if estimator.sampling else None  # before the template's initialize draws
    # run 0 through the pipeline's own checks: models, estimator, network, detectors, names, prior
    template = Pipeline(
        models=models,
        estimator=estimator,
        sensors=sensors,
        measurements={name: a[0] for name, a in arrays.items()},
        prior=priors[0],
        times=T[0],
        detectors=detectors,
        filter_names=filter_names,
        registry=registry,
    )
    for r in range(1, R):
        if priors[r].dim != len(template.layout):
            raise ValueError(f"prior: run {r} has dimension {priors[r].dim}, expected the layout {template.layout}")
    est, network, layout = template.estimator, template.network, template.layout
    M, n, m = len(template.models), len(layout), network.measurement_dim
    Z = network.stack({name: a.reshape(R * steps, a.shape[-1]) for name, a in arrays.items()}).reshape(R, steps, m)
    pristine = [copy.deepcopy(d) for d in template.detectors]
    run_detectors = [[copy.deepcopy(d) for d in pristine] for _ in range(R)]

    if est.sampling:  # each run initialized as its own pipeline would be: a fresh copy of the estimator per run
        state = est.concatenate([copy.deepcopy(fresh).initialize(np.tile(p.mean, (M, 1)), np.tile(p.cov, (M, 1, 1))) for p in priors])
    else:
        state = est.initialize(
            np.repeat(np.stack([p.mean for p in priors]), M, axis=0), np.repeat(np.stack([p.cov for p in priors]), M, axis=0)
        )
    transitions = _Transitions(template.models, priors)
    means = np.empty((R, steps, M, n))
    covs = np.empty((R, steps, M, n, n))
    nis = np.empty((R, steps, M))
    loglik = np.empty((R, steps, M))
    nu = np.empty((R, steps, M, m))
    series = [{} for _ in range(R)]
    statistic_keys = [{} for _ in range(R)]
    threshold_keys = [{} for _ in range(R)]
    decisions: list[list] = [[] for _ in range(R)]
    filters = np.arange(M)
    sensors_list = network.sensors

    for k in range(steps):
        if k > 0:
            if template.linear:
                bank = transitions.bank(DT[:, k - 1])
            else:
                x = est.mean(state)
                bank = TransitionBank.stack(
                    [template.models[j].transition(float(DT[i // M, k - 1]), x[i]) for i, j in enumerate(np.tile(filters, R))]
                )
            state = est.predict(state, bank)
        z = Z[:, k]
        missing = np.isnan(z)
        if (missing == missing[0]).all():
            groups = [np.arange(R)]
            state, innovation = est.update(state, z[0] if R == 1 else np.repeat(z, M, axis=0), sensors_list, layout)
            updates = [innovation]
        else:
            patterns, which = np.unique(missing, axis=0, return_inverse=True)
            groups = [np.flatnonzero(which.reshape(-1) == g) for g in range(len(patterns))]
            parts, updates = [], []
            for runs in groups:
                rows = (runs[:, None] * M + filters).reshape(-1)
                part, innovation = est.update(est.take(state, rows), np.repeat(z[runs], M, axis=0), sensors_list, layout)
                parts.append(part)
                updates.append(innovation)
            order = np.concatenate([(runs[:, None] * M + filters).reshape(-1) for runs in groups])
            state = est.take(est.concatenate(parts), np.argsort(order))
        means[:, k] = np.asarray(est.mean(state)).reshape(R, M, n)
        covs[:, k] = np.asarray(est.covariance(state)).reshape(R, M, n, n)
        for runs, innovation in zip(groups, updates):
            G = runs.size
            dim = innovation.measurement_dim
            nis[runs, k] = np.asarray(innovation.nis).reshape(G, M) if dim > 0 else np.nan
            loglik[runs, k] = np.asarray(innovation.loglik).reshape(G, M) if dim > 0 else np.nan
            complete = dim == m and np.shape(innovation.nu) == (G * M, m) and np.shape(innovation.S) == (G * M, m, m)
            nu[runs, k] = np.asarray(innovation.nu).reshape(G, M, m) if complete else np.nan
            if not pristine:
                continue
            columns = []  # per detector: its output for each run of the group
            for d, template_detector in enumerate(pristine):
                kind = type(template_detector)
                copies = [run_detectors[r][d] for r in runs]
                if isinstance(template_detector, ScoreDetector) and kind.step is ScoreDetector.step:
                    scores = np.asarray(innovation.loglik, dtype=float), np.asarray(innovation.nis, dtype=float)
                    columns.append(kind.observe_runs(copies, k, scores[0].reshape(G, M), scores[1].reshape(G, M), dim))
                else:
                    own = [innovation if G == 1 else innovation_rows(innovation, p * M + filters, G * M) for p in range(G)]
                    columns.append(kind.step_runs(copies, k, own))
            for position, r in enumerate(runs):
                outputs: dict[str, DetectorStep] = {}
                for detector, column in zip(run_detectors[r], columns):
                    output = column[position]
                    outputs[detector.label] = output
                    if output.decision is not None:
                        decisions[r].append(attrs.evolve(output.decision, time=float(T[r, k])))
                store_detector_outputs(series[r], statistic_keys[r], threshold_keys[r], k, steps, outputs)

    def frozen(array):
        array.flags.writeable = False
        return array

    for array in (means, covs, nis, loglik, nu):
        frozen(array)
    results = [
        RunResult(
            layout=layout,
            filters=template.filter_names,
            times=frozen(np.array(T[r])),
            means=means[r],
            covs=covs[r],
            nis=nis[r],
            loglik=loglik[r],
            innovations=nu[r],
            statistics={label: {key: frozen(a) for key, a in table.items()} for label, table in series[r].items()},
            decisions=tuple(decisions[r]),
        )
        for r in range(R)
    ]
    for r, recorder in recorders.items():
        pipeline = Pipeline(
            models=template.models,
            estimator=copy.deepcopy(fresh) if fresh is not None else est,
            sensors=network,
            measurements={name: a[r] for name, a in arrays.items()},
            prior=priors[r],
            times=T[r],
            detectors=[copy.deepcopy(d) for d in pristine],
            recorder=recorder,
            truth=truths[r],
            filter_names=template.filter_names,
            record_seconds=None,
        )
        pipeline.replay(results[r], threshold_keys[r])
    return results
