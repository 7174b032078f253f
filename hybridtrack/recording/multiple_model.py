"""Recording of a :class:`~hybridtrack.algorithms.multiple_model.MultipleModelRun` (``recorder.log_result(run, …)``):
its estimate x̂ = Σ_j μ_j x̂_j coloured by the most probable model, μ_j and argmax_j μ_j (entity paths: docs/recording.md).
"""

from __future__ import annotations

from hybridtrack.algorithms.multiple_model import MultipleModelRun
from hybridtrack.recording.recorder import log_mode, log_run
from hybridtrack.recording.results import log_result


@log_result.register
def log_multiple_model_run(run: MultipleModelRun, recorder, *, name: str, sensors, measurements, truth=None) -> None:
    """``sensors`` the estimator's sensors, ``measurements`` sensor name → (K+1, m), ``truth`` a trajectory or None."""
    steps = log_run(recorder, run, name, sensors=sensors, measurements=measurements, truth=truth)
    for j, mode in enumerate(run.modes):
        recorder.log_scalars(f"estimator/{name}/mode_probability/{mode}", steps, run.mode_probabilities[:, j], run.times)
    log_mode(recorder, name, steps, run)
