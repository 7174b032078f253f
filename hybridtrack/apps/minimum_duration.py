"""The shortest segment a person should believe, from the mode sojourn prior of a multiple-model tracker.

A multiple-model estimator with mean sojourn times T_j (``[estimator] sojourn``) holds that mode j lasts an
exponential time of mean T_j: Π(Δt) = expm(Λ Δt), Λ_jj = −1/T_j (Bar-Shalom, Li & Kirubarajan 2001, §11.6,
the sojourn time of a Markov chain), P(sojourn < d) = 1 − e^{−d/T_j}.  Of its true segments of mode j the prior
puts the fraction q below the q-quantile

    d_j = −T_j ln(1 − q),

so a segment shorter than d_j is one the tracker's own prior calls rarer than q: with ``[segments]
sojourn_quantile = q``, d_j is each mode's minimum duration (q = 0.1, T_j = 120 s: 12.6 s).  It is the prior of
the estimator that made the segments, not a duration chosen apart from it.

* **Causal** (:func:`held_modes`; a causal run, ``--lag``): a switch of the steps' modes to j is taken only once j
  has lasted d_j (its steps from the switch on, over the times of the reports); until then, and for a shorter
  spell, the current mode goes on.  A taken segment starts at its first step (the change time is back-dated, as
  a CUSUM dates its change); it was decided d_j later, at the step returned with it.
* **Fixed interval** (:func:`merged_modes`; ``--smooth``, the whole record known): while some segment is shorter
  than its mode's d_j, the one shortest relative to its d_j is merged into its longer neighbour and equal
  neighbours are joined — the rule of the course labels (:mod:`hybridtrack.apps.mode_labels`) with d_j for
  their one ``min_duration``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np


def minimum_durations(sojourns: Mapping[str, float], quantile: float) -> dict[str, float]:
    """d_j = −T_j ln(1 − q) (seconds) for each mode name → mean sojourn T_j (seconds) of ``sojourns``."""
    q = float(quantile)
    if not 0.0 <= q < 1.0:
        raise ValueError(f"quantile: expected the sojourn quantile q in [0, 1), got {quantile!r}")
    return {mode: -float(T) * math.log1p(-q) for mode, T in sojourns.items()}


def held_modes(times: np.ndarray, modes: Sequence, minimum: Mapping) -> tuple[list, list[tuple[int, int]]]:
    """The causal modes of the steps (module docstring) and, per taken switch, (its first step, the step at which it
    was decided).  ``times`` (K,) seconds, ascending; ``modes`` (K,) labels (any hashable: a name, a (name, radius)
    pair); ``minimum`` label → d_j (absent: 0)."""
    times = np.asarray(times, dtype=float)
    out = list(modes[:1])
    decided: list[tuple[int, int]] = []
    current, candidate = (modes[0] if len(modes) else None), None
    for k in range(1, len(modes)):
        mode = modes[k]
        if mode == current:
            candidate = None
        else:
            if candidate is None or modes[candidate] != mode:
                candidate = k
            if times[k] - times[candidate] >= minimum.get(mode, 0.0):
                out[candidate:k] = [mode] * (k - candidate)
                decided.append((candidate, k))
                current, candidate = mode, None
        out.append(current)
    return out, decided


def merged_modes(times: np.ndarray, modes: Sequence, minimum: Mapping) -> list:
    """The modes of the steps with every segment shorter than its d_j merged away (:func:`merged_runs`)."""
    runs = merged_runs(joined_runs([[mode, k, k] for k, mode in enumerate(modes)]), times, minimum)
    return [mode for mode, first, last in runs for _ in range(first, last + 1)]


def merged_runs(runs: list[list], times: np.ndarray, minimum: Mapping) -> list[list]:
    """[mode, first step, last step] runs (equal neighbours joined) with every run shorter than its mode's minimum
    (``minimum`` mode → seconds, absent: 0) merged away: the shortest relative to its minimum first, into its longer
    neighbour, equal neighbours joined again (module docstring; with one minimum for every mode the rule of the
    course labels).  A run spans from its first step to the next run's first step (the last: to its last step)."""
    times = np.asarray(times, dtype=float)
    while len(runs) > 1:
        ends = [run[1] for run in runs[1:]] + [runs[-1][2]]
        lengths = [times[end] - times[first] for (_, first, _), end in zip(runs, ends)]
        shortness = [
            length / minimum.get(mode, 0.0) if length < minimum.get(mode, 0.0) else math.inf for (mode, _, _), length in zip(runs, lengths)
        ]
        i = int(np.argmin(shortness))
        if shortness[i] == math.inf:
            break
        left = lengths[i - 1] if i > 0 else -1.0
        right = lengths[i + 1] if i + 1 < len(runs) else -1.0
        j = i - 1 if left >= right else i + 1
        runs[j] = [runs[j][0], min(runs[j][1], runs[i][1]), max(runs[j][2], runs[i][2])]
        del runs[i]
        runs = joined_runs(runs)
    return runs


def joined_runs(runs: list[list]) -> list[list]:
    """[mode, first step, last step] runs with equal neighbours joined."""
    out: list[list] = []
    for mode, first, last in runs:
        if out and out[-1][0] == mode:
            out[-1] = [mode, out[-1][1], last]
        else:
            out.append([mode, first, last])
    return out
