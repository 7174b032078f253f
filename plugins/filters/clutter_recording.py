"""Recording the inside of the nonlinear and clutter filters through the recorder seam (docs/recording.md; issue 17 item 6).

Per filter ``<name>`` of a bank, from the states of a run (one state per step), the entities listed in
docs/recording.md: a ``particle`` filter's cloud (the ``max_points`` heaviest, radius ∝ √w) and N_eff = 1/Σ w²
(:class:`~hybridtrack_plugins.filters.particle.ParticleState`); a ``gaussian_sum`` filter's component means,
weights w_c and 2σ position ellipses per slot (:class:`~hybridtrack_plugins.filters.gaussian_sum.MixtureState`;
slots heaviest first); an ``mht`` filter's hypothesis probabilities p_h, live count and 2σ ellipses per slot
(:class:`~hybridtrack_plugins.filters.mht.MHTState`).

Weighted points go through the recorder's optional ``log_weighted_points``
(:class:`~hybridtrack.recording.RerunRecorder`); a recorder without it gets
plain ``log_points``.  Other states are skipped.  Slots beyond the widest state
of the run are padded (a bank's width changes as mixtures are reduced).

No hook: a helper of the filter family, not a plugin.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack_plugins.filters._association import pad_axis


def _weighted_points(recorder, entity, steps, points, weights, times, max_radius):
    log = getattr(recorder, "log_weighted_points", None)
    if log is not None:
        log(entity, steps, points, weights, times, max_radius=max_radius)
    else:
        recorder.log_points(entity, steps, np.where((weights > 0)[..., None], points, np.nan), times)


def _pad(arrays: list[np.ndarray], fill: float) -> np.ndarray:
    """Stack per-step arrays whose axis 0 (slots) differ in length, padding with ``fill``."""
    width = max(a.shape[0] for a in arrays)
    return np.stack([pad_axis(np.asarray(a, dtype=np.float64), 0, width, fill) for a in arrays])


def log_filter_states(
    recorder,
    filter_names: Sequence[str],
    steps,
    states: Sequence,
    layout: Sequence[str],
    times=None,
    *,
    max_points: int = 500,
    max_radius: float = 0.05,
) -> None:
    """Log particle clouds, mixture components or MHT hypotheses of ``states`` (one bank state per step; module docstring).

    ``filter_names`` names the M filters of the bank; ``steps`` (K,) and ``times`` (K,) or None as everywhere.
    """
    from hybridtrack_plugins.filters.gaussian_sum import MixtureState  # these modules' estimators use RecordsFilterStates
    from hybridtrack_plugins.filters.mht import MHTState
    from hybridtrack_plugins.filters.particle import ParticleState

    steps = np.asarray(steps)
    if len(states) != steps.shape[0]:
        raise ValueError(f"states: expected one state per step ({steps.shape[0]}), got {len(states)}")
    if not states:
        return
    first = states[0]
    if any(type(s) is not type(first) for s in states):
        raise ValueError("states: expected states of one estimator")
    layout = tuple(layout)
    if "x" not in layout or "y" not in layout:
        raise ValueError(f"layout: recording positions needs 'x' and 'y' in the state layout, got {layout}")
    names = list(filter_names)
    log = {ParticleState: _log_particles, MixtureState: _log_mixtures, MHTState: _log_hypotheses}.get(type(first))
    if log is None:
        return
    if first.mean.shape[0] != len(names):
        raise ValueError(f"filter_names: expected {first.mean.shape[0]} names (the bank size), got {len(names)}")
    log(recorder, names, steps, states, [layout.index("x"), layout.index("y")], times, max_points, max_radius)


class RecordsFilterStates:
    """Mixin for the estimators whose states :func:`log_filter_states` records (``particle``, ``gaussian_sum``,
    ``mht``): ``Estimator.record_states`` through it, so a recording ``Pipeline`` logs their insides."""

    records_states = True
    record_states = staticmethod(log_filter_states)


def _log_particles(recorder, names, steps, states, position, times, max_points, max_radius):
    keep = min(states[0].particles.shape[1], max_points)
    for j, name in enumerate(names):
        lw = np.stack([s.log_weights[j] for s in states])  # (K, N)
        order = np.argsort(-lw, axis=1, kind="stable")[:, :keep]  # the heaviest (all when N ≤ max_points)
        pts = np.stack([s.particles[j][:, position] for s in states])  # (K, N, 2)
        pts = np.take_along_axis(pts, order[..., None], axis=1)
        w = np.exp(np.take_along_axis(lw, order, axis=1))
        _weighted_points(recorder, f"world/estimate/{name}/particles", steps, pts, w, times, max_radius)
        ess = np.exp(-np.log(np.sum(np.exp(2.0 * lw), axis=1)))
        recorder.log_scalars(f"estimator/{name}/effective_sample_size", steps, ess, times)


def _log_mixtures(recorder, names, steps, states, position, times, max_points, max_radius):
    index = np.ix_(position, position)
    for j, name in enumerate(names):
        w = _pad([np.exp(s.log_weights[j]) for s in states], 0.0)  # (K, C)
        centers = _pad([s.x[j][:, position] for s in states], np.nan)  # (K, C, 2)
        covs = _pad([s.P[j][:, index[0], index[1]] for s in states], np.nan)  # (K, C, 2, 2)
        centers = np.where((w > 0)[..., None], centers, np.nan)
        _weighted_points(recorder, f"world/estimate/{name}/components", steps, centers, w, times, max_radius)
        recorder.log_scalars(f"estimator/{name}/component_weight", steps, w, times, names=[f"w{c}" for c in range(w.shape[1])])
        for c in range(w.shape[1]):
            recorder.log_ellipses(f"world/estimate/{name}/component/{c}", steps, centers[:, c], covs[:, c], times)


def _log_hypotheses(recorder, names, steps, states, position, times, max_points, max_radius):
    index = np.ix_(position, position)
    for j, name in enumerate(names):
        p = np.stack([s.probabilities[j] for s in states])  # (K, H)
        live = np.stack([np.isfinite(s.scores[j]) for s in states])
        recorder.log_scalars(f"estimator/{name}/hypothesis_probability", steps, p, times, names=[f"h{h}" for h in range(p.shape[1])])
        recorder.log_scalars(f"estimator/{name}/hypotheses", steps, live.sum(axis=1).astype(float), times)
        centers = np.where(live[..., None], np.stack([s.x[j][:, position] for s in states]), np.nan)  # (K, H, 2)
        covs = np.stack([s.P[j][:, index[0], index[1]] for s in states])  # (K, H, 2, 2)
        for h in range(p.shape[1]):
            recorder.log_ellipses(f"world/estimate/{name}/hypothesis/{h}", steps, centers[:, h], covs[:, h], times)
