"""Recording a pipeline's run: :func:`log_pipeline`, the writer ``recorder.log_result`` finds for a
:class:`~hybridtrack.engine.pipeline.PipelineResult` (entity paths in ``docs/recording.md``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from hybridtrack.engine.pipeline import PipelineResult
from hybridtrack.recording.clutter import log_associations, log_scans
from hybridtrack.recording.recorder import decision_text, log_estimate, log_measurements, measured_components, nis_bounds
from hybridtrack.recording.results import log_result


@log_result.register
def log_pipeline(
    result: PipelineResult,
    recorder,
    *,
    network,
    measurements,
    start: int = 0,
    lines: bool = True,
    candidates: Mapping | None = None,
    truth=None,
    record_measurements: bool = True,
    hypotheses: Mapping[str, Sequence[str]] | None = None,
    innovations: Mapping[int, object] | None = None,
    estimator=None,
    states: Sequence | None = None,
) -> None:
    """Record steps ``start`` … K of a pipeline run whose ``result`` holds steps 0 … K (a run streamed in chunks
    hands each chunk over this way), then, with ``lines``, the static path lines of steps 0 … K.

    Context: ``network`` the sensor network and ``measurements`` its stacked z (K+1, Σm) (or sensor name →
    (K+1, m_i)); ``candidates`` (sensor name → ScanSequence) in clutter; ``truth`` a trajectory;
    ``record_measurements`` False when another run on the recorder logs them; ``hypotheses`` detector label →
    the names of its series' columns (default the filters); ``innovations`` step → the estimator's innovation
    (clutter associations); ``estimator`` and ``states`` (one bank state per step of the chunk) for an estimator
    that records its states.  The entity paths: docs/recording.md.
    """
    z = network.stack(measurements) if isinstance(measurements, Mapping) else np.asarray(measurements)
    K = result.steps
    names = result.modes
    position = [result.layout.index("x"), result.layout.index("y")]
    components = measured_components(network.sensors)  # the innovations' columns
    if start < K:
        rows = slice(start, K)
        steps, times = np.arange(start, K), result.times[rows]
        if truth is not None:
            positions = truth.positions[rows]
            recorder.log_path("world/truth", steps[: len(positions)], positions, times[: len(positions)], line=False)
        if record_measurements and candidates is not None:
            log_scans(recorder, candidates.values(), steps, times)
        elif record_measurements:
            log_measurements(recorder, network.sensors, network.split(z[rows]), steps, times)
        for j, name in enumerate(names):
            log_estimate(recorder, name, steps, result.means[rows, j], result.covs[rows, j], position, times, line=False)
            for key, values in (("nis", result.nis), ("loglik", result.loglik)):
                recorder.log_scalars(f"estimator/{name}/{key}", steps, values[rows, j], times)
            innovation = result.innovations[rows, j]
            labels = components if innovation.ndim == 2 and innovation.shape[1] == len(components) > 1 else None
            recorder.log_scalars(f"estimator/{name}/innovation", steps, innovation, times, names=labels)
        bounds = nis_bounds(np.isfinite(z[rows]).sum(axis=1))
        recorder.log_scalars("estimator/nis_bounds", steps, bounds, times, names=["χ² 2.5 %", "χ² 97.5 %"])
        if candidates is not None:
            log_associations(recorder, names, steps, [(innovations or {}).get(i) for i in steps], times)
        for label, series in result.statistics.items():
            columns = tuple((hypotheses or {}).get(label) or names)
            for key, values in series.items():
                width = values.shape[1] if values.ndim == 2 else 0
                labels = columns if width == len(columns) else columns[1:] if width == len(columns) - 1 else None
                recorder.log_scalars(f"detector/{label}/{key}", steps, values[rows], times, names=labels)
        for decision in result.decisions:
            if start <= decision.step < K:
                recorder.log_event(decision.step, decision_text(decision), decision.time)
        if states:
            estimator.record_states(recorder, names, steps, states, result.layout, times)
    if lines:
        steps, times = np.arange(K), result.times
        if truth is not None:
            recorder.log_path("world/truth", steps, truth.positions[:K], times, points=False)
        for j, name in enumerate(names):
            recorder.log_path(f"world/estimate/{name}", steps, result.means[:, j][:, position], times, points=False)
