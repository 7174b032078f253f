"""Recording of clutter scans and of the clutter filters' associations (paths in ``docs/recording.md``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack.core.protocols import ClutterInnovation
from hybridtrack.engine.clutter import ScanSequence


def log_scans(recorder, sequences: Sequence[ScanSequence], steps: np.ndarray, times: np.ndarray | None = None) -> None:
    """False candidates under ``world/clutter/<sensor>`` and target-originated ones under
    ``world/measurements/<sensor>`` at ``steps`` (2-D sensors only: the split uses the simulator's labels)."""
    steps = np.asarray(steps)
    for seq in sequences:
        if seq.measurement_dim != 2:
            continue
        recorder.log_points(f"world/measurements/{seq.sensor}", steps, seq.target_measurements()[steps], times)
        false = seq.false_measurements()[steps]
        if false.shape[1]:
            recorder.log_points(f"world/clutter/{seq.sensor}", steps, false, times)


def log_associations(
    recorder, filter_names: Sequence[str], steps: np.ndarray, innovations: Sequence, times: np.ndarray | None = None
) -> None:
    """Per filter and sensor, the gate {z : (z − ẑ)ᵀS⁻¹(z − ẑ) ≤ γ} (2-D sensors, finite γ), β_0 and the largest β_i,
    the candidates in the gate and ln Λ of each scan of clutter-aware updates (entity paths: docs/recording.md).

    ``innovations`` holds one :class:`~hybridtrack.core.protocols.ClutterInnovation` (or plain Innovation, skipped) per step.
    """
    steps = np.asarray(steps)
    by_sensor: dict[str, list] = {}
    for k, innovation in zip(steps, innovations):
        for a in innovation.associations if isinstance(innovation, ClutterInnovation) else ():
            by_sensor.setdefault(a.sensor, []).append((k, a))
    times_of = {int(k): t for k, t in zip(steps, times)} if times is not None else None
    several = len(by_sensor) > 1
    for sensor, rows in by_sensor.items():
        ks = np.array([k for k, _ in rows])
        ts = None if times_of is None else np.array([times_of[int(k)] for k in ks])
        suffix = f"/{sensor}" if several else ""
        for j, name in enumerate(filter_names):
            beta0 = np.array([a.missed[j] for _, a in rows])
            largest = np.array([a.weights[j].max(initial=0.0) for _, a in rows])
            recorder.log_scalars(
                f"estimator/{name}/beta{suffix}", ks, np.stack([beta0, largest], axis=-1), ts, names=["beta_0", "beta_max"]
            )
            recorder.log_scalars(f"estimator/{name}/gated{suffix}", ks, np.array([float(a.gated[j].sum()) for _, a in rows]), ts)
            recorder.log_scalars(f"estimator/{name}/association_loglik{suffix}", ks, np.array([a.loglik[j] for _, a in rows]), ts)
            gamma = rows[0][1].gate
            if rows[0][1].predicted.shape[-1] == 2 and np.isfinite(gamma):
                centers = np.stack([a.predicted[j] for _, a in rows])
                covs = np.stack([a.S[j] for _, a in rows])
                recorder.log_ellipses(f"world/estimate/{name}/gate{suffix}", ks, centers, covs, ts, sigmas=float(np.sqrt(gamma)))
