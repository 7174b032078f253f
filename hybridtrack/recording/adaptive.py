"""The recording of the adaptive algorithms' results (``recorder.log_result(run, …)``; the entity paths of
:class:`~hybridtrack.algorithms.known_switch.KnownSwitchRun`, :class:`~hybridtrack.algorithms.unknown_change.UnknownChangeRun`
and :class:`~hybridtrack.algorithms.known_modes.ScheduleRun` (its estimate and NIS): docs/recording.md).

Context keywords: ``measurements`` (sensor name → (K+1, m)), ``sensors``,
``truth`` (a Trajectory or None), ``name`` (the estimator's entity name),
``detector`` (the test's label), ``signal`` (the signal function's label or None).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack.algorithms.known_modes import ScheduleRun
from hybridtrack.algorithms.known_switch import KnownSwitchRun
from hybridtrack.algorithms.unknown_change import UnknownChangeRun
from hybridtrack.recording.recorder import decision_text, log_mode, log_run
from hybridtrack.recording.results import log_result
from hybridtrack.recording.style import log_ratio_name


def _log_ratios(recorder, entity: str, steps, values: np.ndarray, names: Sequence[str], times, against: np.ndarray | None = None) -> None:
    """ln λ of each hypothesis j (column j of ``values``) as ``<entity>/<name_j>``, NaN where not finite: a hypothesis
    not in play leaves a gap (rerun breaks a line at NaN, so no line joins two periods in play); a column never
    finite is not logged.  Each series is named by its hypothesis pair (:func:`log_ratio_name`): against the best of
    the others (``against`` None: Algorithm 1's pairwise SPRT, L_j − max_{i≠j} L_i), or against the mode
    ``against[k]`` (indices into ``names``) of each step, one series per mode it was compared with (Algorithm 3:
    ln λ_p of a change to p against the mode followed before the step)."""
    for j, name in enumerate(names):
        finite = np.isfinite(values[:, j])
        if not finite.any():
            continue
        if against is None:
            recorder.log_scalars(f"{entity}/{name}", steps, np.where(finite, values[:, j], np.nan), times, names=[log_ratio_name(name)])
            continue
        rivals = np.unique(against[finite])
        columns = np.full((len(steps), rivals.size), np.nan)
        for i, rival in enumerate(rivals):
            rows = finite & (against == rival)
            columns[rows, i] = values[rows, j]
        labels = [log_ratio_name(name, names[r] if 0 <= r < len(names) else "no mode") for r in rivals]
        recorder.log_scalars(f"{entity}/{name}", steps, columns[:, 0] if rivals.size == 1 else columns, times, names=labels)


def _log_run(run, recorder, *, measurements, sensors, truth, name: str, detector: str, against: np.ndarray | None = None) -> np.ndarray:
    """What every adaptive run records (module docstring; ``against`` as :func:`_log_ratios`); returns the steps."""
    steps = log_run(recorder, run, name, sensors=sensors, measurements=measurements, truth=truth)
    times = run.times
    if run.hypothesis_positions is not None:  # the bank's hypotheses fanning out of each switch, each in its colour
        for j, hypothesis in enumerate(run.modes):
            path = run.hypothesis_positions[:, j]
            if np.isfinite(path).any():
                recorder.log_path(f"world/estimate/{name}/hypotheses/{hypothesis}", steps, path, times)
    base = f"detector/{detector}"
    _log_ratios(recorder, f"{base}/log_ratio", steps, run.log_ratios, run.modes, times, against)
    recorder.log_scalars(f"{base}/upper", steps, np.full(steps.size, run.upper), times)
    recorder.log_scalars(f"{base}/lower", steps, np.full(steps.size, run.lower), times)
    for d in run.decisions:
        recorder.log_event(d.step, decision_text(d), d.time)
    return steps


@log_result.register
def log_known_switch_run(run: KnownSwitchRun, recorder, *, name: str = "known_switch", truth=None, **context) -> None:
    """Algorithm 1's run (module docstring) with the hypothesis followed and the filters running per step."""
    steps = _log_run(run, recorder, name=name, truth=truth, **context)
    log_mode(recorder, name, steps, run, "followed")
    # filters running per step: the hypotheses still in play, one after the decision
    bank_size = np.maximum(1, np.isfinite(run.log_ratios).sum(axis=1))
    recorder.log_scalars(f"estimator/{name}/bank_size", steps, bank_size.astype(float), run.times)


@log_result.register
def log_unknown_change_run(run: UnknownChangeRun, recorder, *, name: str = "unknown_change", truth=None, signal=None, **context) -> None:
    """Algorithm 3's run (module docstring) with the signal function, the bank size and the mode per step."""
    mode = np.asarray(run.mode, dtype=np.int64)
    before = np.concatenate([mode[:1], mode[:-1]])  # step k's ln λ_p weighs a change to p against the mode of step k − 1
    steps = _log_run(run, recorder, name=name, truth=truth, against=before, **context)
    times = run.times
    if signal is not None:
        for key, values in (("signal", run.signal), ("lower", run.signal_bounds[:, 0]), ("upper", run.signal_bounds[:, 1])):
            recorder.log_scalars(f"detector/{signal}/{key}", steps, values, times)
    recorder.log_scalars(f"estimator/{name}/bank_size", steps, run.bank_sizes.astype(float), times)
    log_mode(recorder, name, steps, run)


@log_result.register
def log_schedule_run(run: ScheduleRun, recorder, *, name: str = "known_modes", **context) -> None:
    """The told filter's estimate ``world/estimate/<name>`` (2σ ellipses) and its NIS ``estimator/<name>/nis``."""
    steps = log_run(recorder, run, name)
    recorder.log_scalars(f"estimator/{name}/nis", steps, run.nis, run.times)
