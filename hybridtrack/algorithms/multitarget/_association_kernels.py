"""The compiled kernels of the association (numba, ``cache=True``), loaded by :func:`.gating.association_kernels` on
first use only, so that importing the trackers does not import numba.  The formulas and the order of every
floating-point operation are those of the numpy code they stand for — :func:`.gating.gate_checked` (m = 2, every
pair computed), :func:`.gating.cluster_layout` and the one-track and one-detection clusters of :func:`.jpda.jpda` —
so the results equal theirs, bit for bit (the exponentials of the last to rounding; tests/algorithms/test_gating.py,
tests/algorithms/test_jpda.py)."""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

_jit = functools.partial(numba.njit, cache=True, error_model="numpy", nogil=True)


@_jit()
def dense_gate_2d(
    predicted, a, b, c, det, log_det, detections, velocities, offsets, gamma, track, detection, d2, loglik
):  # pragma: no cover - compiled
    """Every (track, detection) pair with d² = (c ν₁² − 2b ν₁ν₂ + a ν₂²)/det S ≤ γ, ν = z_i − ẑ_t (− v̂_t δ_i when
    ``velocities`` has T rows), in the order track then detection, written to the outputs (T·N long); returns E."""
    T, N = predicted.shape[0], detections.shape[0]
    shifted = velocities.shape[0] == T
    constant = 2.0 * math.log(2.0 * math.pi)
    e = 0
    for t in range(T):
        for i in range(N):
            n1 = detections[i, 0] - predicted[t, 0]
            n2 = detections[i, 1] - predicted[t, 1]
            if shifted:
                n1 -= velocities[t, 0] * offsets[i]
                n2 -= velocities[t, 1] * offsets[i]
            value = (c[t] * n1 * n1 - 2.0 * b[t] * n1 * n2 + a[t] * n2 * n2) / det[t]
            if value <= gamma:
                track[e], detection[e], d2[e] = t, i, value
                loglik[e] = -0.5 * (value + log_det[t] + constant)
                e += 1
    return e


@_jit()
def _root(parent, u):  # pragma: no cover - compiled
    while parent[u] != u:
        parent[u] = parent[parent[u]]
        u = parent[u]
    return u


@_jit()
def _group(labels, count, order, start):  # pragma: no cover - compiled
    """A stable counting sort of ``labels`` into ``order``; ``start`` (count + 1) the offsets of each label."""
    start[:] = 0
    for k in range(labels.shape[0]):
        start[labels[k] + 1] += 1
    for g in range(count):
        start[g + 1] += start[g]
    fill = start[:count].copy()
    for k in range(labels.shape[0]):
        order[fill[labels[k]]] = k
        fill[labels[k]] += 1


@_jit()
def cluster_layout(T, N, track, detection):  # pragma: no cover - compiled
    """(labels (T + N,), count, edge_cluster (E,), edge_order, edge_start, track_order, track_start, detection_order,
    detection_start): union–find with the smallest node as each root (tracks 0…T−1, detections T…T+N−1), the
    components numbered in ascending order of their roots (first appearance, tracks before detections) and the
    pairs, tracks and detections grouped by a stable counting sort."""
    n = T + N
    parent = np.arange(n)
    for k in range(track.shape[0]):
        ru, rv = _root(parent, track[k]), _root(parent, T + detection[k])
        if ru < rv:
            parent[rv] = ru
        elif rv < ru:
            parent[ru] = rv
    labels = np.empty(n, dtype=np.intp)
    count = 0
    for u in range(n):  # a root precedes every other node of its component
        r = _root(parent, u)
        if r == u:
            labels[u] = count
            count += 1
        else:
            labels[u] = labels[r]
    E = track.shape[0]
    edge_cluster = np.empty(E, dtype=np.intp)
    for k in range(E):
        edge_cluster[k] = labels[track[k]]
    edge_order, edge_start = np.empty(E, dtype=np.intp), np.empty(count + 1, dtype=np.intp)
    track_order, track_start = np.empty(T, dtype=np.intp), np.empty(count + 1, dtype=np.intp)
    detection_order, detection_start = np.empty(N, dtype=np.intp), np.empty(count + 1, dtype=np.intp)
    _group(edge_cluster, count, edge_order, edge_start)
    _group(labels[:T], count, track_order, track_start)
    _group(labels[T:], count, detection_order, detection_start)
    return labels, count, edge_cluster, edge_order, edge_start, track_order, track_start, detection_order, detection_start


@_jit()
def simple_marginals(gain, track, edge_cluster, cluster_tracks, cluster_detections, beta, beta_miss):  # pragma: no cover - compiled
    """β (E,) and β_t0 (T,) of the clusters with one track or one detection, written in place (the other clusters'
    entries untouched): :func:`.jpda.jpda`'s formulas, its sums taken in the same order (edges ascending)."""
    E, T, C = gain.shape[0], beta_miss.shape[0], cluster_tracks.shape[0]
    top_t, total_t, owned = np.zeros(T), np.zeros(T), np.zeros(T, dtype=np.bool_)
    top_c, total_c, rest_c = np.zeros(C), np.zeros(C), np.zeros(C)
    for e in range(E):  # the largest gain of each (with 0 for "missed" / "clutter")
        c = edge_cluster[e]
        if cluster_tracks[c] == 1:
            top_t[track[e]] = max(top_t[track[e]], gain[e])
        elif cluster_detections[c] == 1:
            top_c[c] = max(top_c[c], gain[e])
    for e in range(E):
        c = edge_cluster[e]
        if cluster_tracks[c] == 1:
            beta[e] = math.exp(gain[e] - top_t[track[e]])
            total_t[track[e]] += beta[e]
            owned[track[e]] = True
        elif cluster_detections[c] == 1:
            beta[e] = math.exp(gain[e] - top_c[c])
            total_c[c] += beta[e]
    for t in range(T):
        if owned[t]:
            total_t[t] += math.exp(-top_t[t])
    for c in range(C):
        if cluster_tracks[c] >= 2 and cluster_detections[c] == 1:
            total_c[c] += math.exp(-top_c[c])
    for e in range(E):  # β_t0 = (Z − e^{g_e}) / Z, the difference taken only where it does not cancel
        c = edge_cluster[e]
        if cluster_tracks[c] >= 2 and cluster_detections[c] == 1 and not beta[e] > 0.5 * total_c[c]:
            rest_c[c] += beta[e]
    for c in range(C):
        if cluster_tracks[c] >= 2 and cluster_detections[c] == 1:
            rest_c[c] += math.exp(-top_c[c])
    for e in range(E):
        c = edge_cluster[e]
        if cluster_tracks[c] == 1:
            beta[e] = beta[e] / total_t[track[e]]
        elif cluster_detections[c] == 1:
            weight = beta[e]
            others = rest_c[c] if weight > 0.5 * total_c[c] else total_c[c] - weight
            beta[e] = weight / total_c[c]
            beta_miss[track[e]] = others / total_c[c]
    for t in range(T):
        if owned[t]:
            beta_miss[t] = math.exp(-top_t[t]) / total_t[t]
