"""χ² gating of many tracks against many detections, with a k-d tree, and the clusters of the gating graph.

A detection z_i falls in the gate of track t (predicted measurement ẑ_t, innovation covariance S_t) when its
normalised innovation squared is at most the gate value γ (Blackman & Popoli 1999, "Design and Analysis of
Modern Tracking Systems", ch. 6; Bar-Shalom & Li 1995, "Multitarget-Multisensor Tracking", ch. 9):

    ν = z_i − ẑ_t,    d² = νᵀ S_t⁻¹ ν ≤ γ,    γ = χ²_m quantile of the gate probability P_G,

and the pair's log-likelihood is ln N(z_i; ẑ_t, S_t) = −½ (d² + ln det S_t + m ln 2π).

Thousands of tracks: since d² ≥ ‖ν‖² / λ_max(S_t), every gated detection lies in the ball of radius
r_t = √(γ λ_max(S_t)) around ẑ_t, so k-d trees (``scipy.spatial.cKDTree``, one on the detections, one per band
of similar radii on the predicted points, met by a dual-tree search) return the candidates of every track at
once, and the exact d² is computed on those only, through the Cholesky factor S_t = L_t L_tᵀ (w = L_t⁻¹ ν by
forward substitution, d² = ‖w‖², ln det S_t = 2 Σ ln L_jj).

Detections of slightly different times (a time-windowed scan): with ``velocities`` v̂_t and ``offsets``
δ_i = t_i − t_k the detection is moved to the scan time along the track, z_ti = z_i − v̂_t δ_i (so
ν = z_i − v̂_t δ_i − ẑ_t); the ball radius grows by ‖v̂_t‖ max|δ| so that no gated pair is missed.

The gated pairs form a bipartite graph between tracks and detections; its connected components (clusters) are
the independent sub-problems of every association method (Bar-Shalom & Li 1995, ch. 9).
"""

from __future__ import annotations

import functools
import importlib.util
import math

import attrs
import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from hybridtrack.core.validation import as_float_array, check_positive, check_positive_int
from hybridtrack.sdk.distributions import chi2_quantile

#: the ball radius is widened by this relative amount so that pairs on the gate's boundary survive rounding
_RADIUS_SLACK = 1e-9


#: up to this many track–detection pairs, :func:`_candidates` computes every distance (no k-d tree)
_DENSE_PAIRS = 4096
#: up to this many gated pairs, :func:`clusters` propagates labels in numpy (no sparse graph)
_SMALL_GRAPH = 2000
#: numba is installed: the m = 2 gate of up to :data:`_DENSE_PAIRS` pairs, :func:`cluster_layout` and JPDA's one-track
#: and one-detection clusters run compiled (:mod:`._association_kernels`, the same arithmetic), else in numpy
NUMBA_AVAILABLE = importlib.util.find_spec("numba") is not None


@functools.cache
def association_kernels():
    """The compiled kernels of :mod:`._association_kernels`, imported (and numba with it) on first use."""
    from hybridtrack.algorithms.multitarget import _association_kernels

    return _association_kernels


def _index_array(value, name: str) -> np.ndarray:
    array = np.array(value, copy=True)
    if array.ndim != 1 or (array.size and not np.issubdtype(array.dtype, np.integer)):
        raise ValueError(f"{name}: expected a 1-D integer array, got shape {array.shape} of {array.dtype}")
    array = array.astype(np.intp)
    array.setflags(write=False)
    return array


def _float_array(value, name: str) -> np.ndarray:
    return as_float_array(value, name, (None,), readonly=True)


@attrs.frozen(eq=False)
class Gate:
    """The gated (track, detection) pairs of one scan, sparse: E pairs sorted by track, then detection.

    ``d2`` is νᵀ S_t⁻¹ ν with ν = z_i − ẑ_t and ``log_likelihood`` is ln N(z_i; ẑ_t, S_t) for each pair.
    The arrays are read-only copies.
    """

    tracks: int = attrs.field(converter=lambda v: check_positive_int(v, "tracks", minimum=0))
    detections: int = attrs.field(converter=lambda v: check_positive_int(v, "detections", minimum=0))
    track: np.ndarray = attrs.field(converter=lambda v: _index_array(v, "track"))
    detection: np.ndarray = attrs.field(converter=lambda v: _index_array(v, "detection"))
    d2: np.ndarray = attrs.field(converter=lambda v: _float_array(v, "d2"))
    log_likelihood: np.ndarray = attrs.field(converter=lambda v: _float_array(v, "log_likelihood"))

    def __attrs_post_init__(self):
        E = self.track.size
        for name in ("detection", "d2", "log_likelihood"):
            if getattr(self, name).size != E:
                raise ValueError(f"{name}: expected {E} entries (one per gated pair, as track), got {getattr(self, name).size}")
        if E:
            if self.track.min() < 0 or self.track.max() >= self.tracks:
                raise ValueError(f"track: expected indices in [0, {self.tracks}), got {self.track.min()}…{self.track.max()}")
            if self.detection.min() < 0 or self.detection.max() >= self.detections:
                raise ValueError(
                    f"detection: expected indices in [0, {self.detections}), got {self.detection.min()}…{self.detection.max()}"
                )
            key = self.track * max(self.detections, 1) + self.detection
            if (np.diff(key) <= 0).any():
                raise ValueError("track, detection: expected distinct pairs sorted by track, then detection")
            if (self.d2 < 0).any():
                raise ValueError("d2: expected squared distances ≥ 0")

    @property
    def pairs(self) -> int:
        """E, the number of gated pairs."""
        return int(self.track.size)

    @classmethod
    def empty(cls, tracks: int, detections: int) -> Gate:
        """No gated pair between ``tracks`` tracks and ``detections`` detections."""
        none = np.zeros(0, dtype=np.intp)
        return cls(tracks, detections, none, none, np.zeros(0), np.zeros(0))


def gate_threshold(probability: float, m: int) -> float:
    """γ = χ²_m quantile of the gate probability P_G (``scipy.stats.chi2.ppf``): a true detection of an
    m-dimensional Gaussian innovation falls in the gate d² ≤ γ with probability P_G."""
    p = float(probability)
    if not 0.0 < p < 1.0:
        raise ValueError(f"probability: expected the gate probability P_G in (0, 1), got {probability!r}")
    m = check_positive_int(m, "m", what="the measurement dimension")
    return float(chi2_quantile(p, m))


def _cholesky(S: np.ndarray) -> np.ndarray:
    """Batched Cholesky factors of the (T, m, m) stack ``S``; a ValueError names the first non-SPD one."""
    scale = np.maximum(np.abs(S).max(axis=(1, 2)), np.finfo(float).tiny)
    asymmetric = np.abs(S - np.swapaxes(S, 1, 2)).max(axis=(1, 2)) > 1e-9 * scale
    if asymmetric.any():
        t = int(np.flatnonzero(asymmetric)[0])
        raise ValueError(f"S: expected symmetric positive definite innovation covariances, S[{t}] is not symmetric")
    try:
        return np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        bad = np.linalg.eigvalsh(S)[:, 0] <= 0
        t = int(np.flatnonzero(bad)[0]) if bad.any() else -1
        where = f"S[{t}]" if t >= 0 else "one of them"
        raise ValueError(f"S: expected symmetric positive definite innovation covariances, {where} is not positive definite") from None


def _largest_eigenvalue(S: np.ndarray) -> np.ndarray:
    """λ_max of each symmetric S_t: (a + c)/2 + √(((a − c)/2)² + b²) for 2 × 2, else ``np.linalg.eigvalsh``."""
    if S.shape[1] == 2:
        a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
        return 0.5 * (a + c) + np.hypot(0.5 * (a - c), b)
    return np.linalg.eigvalsh(S)[:, -1]


def _whiten(L: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """w = L⁻¹ ν for stacks L (E, m, m) lower triangular and ν (E, m): forward substitution, vectorized over E."""
    m = nu.shape[1]
    w = np.empty_like(nu)
    for j in range(m):
        w[:, j] = (nu[:, j] - np.einsum("ek,ek->e", L[:, j, :j], w[:, :j])) / L[:, j, j]
    return w


def _candidates(predicted: np.ndarray, detections: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (track, detection) pairs with ‖z_i − ẑ_t‖ ≤ r_t, sorted by track then detection.

    Up to :data:`_DENSE_PAIRS` track–detection pairs, every distance is computed (one array operation).  Beyond,
    the tracks are grouped in bands of radius within a factor 2 (⌊log₂ r⌋); each band's tree of predicted
    points meets the tree of the detections once (``cKDTree.sparse_distance_matrix`` at the band's largest
    radius, a dual-tree search), then each pair is checked against its own track's radius.
    """
    T, N = predicted.shape[0], detections.shape[0]
    if T * N <= _DENSE_PAIRS:
        distance2 = np.sum((detections[None, :, :] - predicted[:, None, :]) ** 2, axis=-1)
        track, detection = np.nonzero(distance2 <= (radius**2)[:, None])  # row-major: sorted by track, then detection
        return track.astype(np.intp), detection.astype(np.intp)
    detection_tree = cKDTree(detections, balanced_tree=False, compact_nodes=False)  # quicker to build, as quick to search
    band = np.floor(np.log2(radius)).astype(np.int64)
    tracks, found = [], []
    for b in np.unique(band).tolist():
        rows = np.flatnonzero(band == b)
        near = cKDTree(predicted[rows], balanced_tree=False, compact_nodes=False).sparse_distance_matrix(
            detection_tree, float(radius[rows].max()), output_type="ndarray"
        )
        ok = near["v"] <= radius[rows][near["i"]]
        tracks.append(rows[near["i"][ok]])
        found.append(near["j"][ok].astype(np.intp))
    key = np.concatenate(tracks).astype(np.int64) * N + np.concatenate(found)
    key.sort()
    return (key // N).astype(np.intp), (key % N).astype(np.intp)


def gate(predicted, S, detections, *, threshold, velocities=None, offsets=None) -> Gate:
    """The (track, detection) pairs with d² = νᵀ S_t⁻¹ ν ≤ γ (module docstring), found with a k-d tree.

    ``predicted`` (T, m) the predicted measurements ẑ_t, ``S`` (T, m, m) their innovation covariances (SPD),
    ``detections`` (N, m), ``threshold`` the gate value γ (:func:`gate_threshold`).  Optional ``velocities``
    (T, m) and ``offsets`` (N,) move each detection to the scan time along the track: ν = z_i − v̂_t δ_i − ẑ_t.
    T = 0 or N = 0 gives an empty gate.
    """
    gamma = check_positive(threshold, "threshold", what="the χ² gate value γ")
    predicted = as_float_array(predicted, "predicted")
    detections = as_float_array(detections, "detections")
    if predicted.ndim == 1 and predicted.size == 0 and detections.ndim == 2:  # no track: shape (0,) accepted
        predicted = predicted.reshape(0, detections.shape[1])
    if detections.ndim == 1 and detections.size == 0 and predicted.ndim == 2:  # no detection: shape (0,) accepted
        detections = detections.reshape(0, predicted.shape[1])
    if predicted.ndim != 2:
        raise ValueError(f"predicted: expected shape (T, m), got {predicted.shape}")
    if detections.ndim != 2:
        raise ValueError(f"detections: expected shape (N, m), got {detections.shape}")
    T, m = predicted.shape
    N = detections.shape[0]
    if detections.shape[1] != m:
        raise ValueError(f"detections: expected shape ({N}, {m}) (the measurement dimension of predicted), got {detections.shape}")
    if m == 0:
        raise ValueError("predicted: expected a measurement dimension m ≥ 1, got 0")
    S = as_float_array(S, "S", (T, m, m))
    shifted = (velocities is not None) or (offsets is not None)
    if shifted:
        if velocities is None or offsets is None:
            raise ValueError("velocities, offsets: expected both (moving detections along the tracks) or neither")
        velocities = as_float_array(velocities, "velocities", (T, m))
        offsets = as_float_array(offsets, "offsets", (N,))
    return gate_checked(predicted, S, detections, gamma, velocities, offsets)


def gate_checked(predicted: np.ndarray, S: np.ndarray, detections: np.ndarray, gamma: float, velocities=None, offsets=None) -> Gate:
    """:func:`gate` on inputs already checked (float arrays of matching shapes, γ > 0, velocities and offsets
    both or neither): the per-scan call of a tracker, without :func:`gate`'s input checks.  For m = 2 the
    innovation covariance S = [[a, b], [b, c]] is inverted in closed form, d² = (c ν₁² − 2b ν₁ν₂ + a ν₂²)/det S,
    det S = ac − b²; otherwise through its Cholesky factor (module docstring)."""
    T, m = predicted.shape
    N = detections.shape[0]
    if T == 0 or N == 0:
        return Gate.empty(T, N)
    shifted = velocities is not None
    if m == 2:
        a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
        det = a * c - b * b
        bad = (np.abs(b - S[:, 1, 0]) > 1e-9 * np.maximum(np.abs(S).max(axis=(1, 2)), np.finfo(float).tiny)) | ~(a > 0) | ~(det > 0)
        if bad.any():
            _cholesky(S)  # raises the ValueError naming the first bad S_t
            raise ValueError(f"S: expected symmetric positive definite innovation covariances, S[{int(np.flatnonzero(bad)[0])}] is not")
        log_det = np.log(det)
        if NUMBA_AVAILABLE and T * N <= _DENSE_PAIRS:  # every pair, compiled: the same d² and log-likelihoods
            track, detection = np.empty(T * N, dtype=np.intp), np.empty(T * N, dtype=np.intp)
            d2, log_likelihood = np.empty(T * N), np.empty(T * N)
            moved = (velocities, offsets) if shifted else _NOT_SHIFTED
            E = association_kernels().dense_gate_2d(
                predicted, a, b, c, det, log_det, detections, *moved, gamma, track, detection, d2, log_likelihood
            )
            return _built_gate(T, N, track[:E], detection[:E], d2[:E], log_likelihood[:E])
    else:
        L = _cholesky(S)
        log_det = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
    radius = np.sqrt(gamma * _largest_eigenvalue(S))  # the ball holding every gated detection (module docstring)
    if shifted:
        radius = radius + np.sqrt(np.einsum("ti,ti->t", velocities, velocities)) * float(np.abs(offsets).max())
    radius = radius * (1.0 + _RADIUS_SLACK) + np.finfo(float).tiny
    track, detection = _candidates(predicted, detections, radius)
    nu = detections[detection] - predicted[track]
    if shifted:
        nu -= velocities[track] * offsets[detection][:, None]
    if m == 2:
        n1, n2 = nu[:, 0], nu[:, 1]
        d2 = (c[track] * n1 * n1 - 2.0 * b[track] * n1 * n2 + a[track] * n2 * n2) / det[track]
    else:
        w = _whiten(L[track], nu)
        d2 = np.einsum("ej,ej->e", w, w)
    keep = d2 <= gamma
    track, detection, d2 = track[keep], detection[keep], d2[keep]
    log_likelihood = -0.5 * (d2 + log_det[track] + m * math.log(2.0 * math.pi))
    return _built_gate(T, N, track, detection, d2, log_likelihood)


_NOT_SHIFTED = (np.zeros((0, 2)), np.zeros(0))  # the kernel's velocities and offsets of an unshifted gate


def _built_gate(T: int, N: int, *arrays: np.ndarray) -> Gate:
    """A :class:`Gate` of arrays this module computed (sorted, in range, d² ≥ 0 by construction): read-only,
    without the constructor's checks of arbitrary input."""
    out = object.__new__(Gate)
    for name, value in zip(("tracks", "detections"), (T, N)):
        object.__setattr__(out, name, int(value))
    for name, array in zip(("track", "detection", "d2", "log_likelihood"), arrays):
        array = np.ascontiguousarray(array, dtype=np.intp if name in ("track", "detection") else np.float64)
        array.setflags(write=False)
        object.__setattr__(out, name, array)
    return out


def clusters(gate: Gate) -> tuple[np.ndarray, np.ndarray, int]:
    """The connected components of the bipartite gating graph (tracks and detections as nodes, gated pairs as
    edges): (track_cluster (T,), detection_cluster (N,), count).  A track or detection gated with nothing is a
    cluster of its own.  Labels are numbered in order of first appearance, tracks before detections.

    Up to :data:`_SMALL_GRAPH` pairs by min-label propagation with pointer jumping (Shiloach & Vishkin 1982, "An
    O(log n) parallel connectivity algorithm", J. Algorithms 3(1)): every node starts as its own label, each edge
    lowers both ends' labels to the smaller one, and l ← l[l] until fixed; at the fixed point every node carries the
    smallest node index of its component.  Larger graphs: ``scipy.sparse.csgraph.connected_components``."""
    if not isinstance(gate, Gate):
        raise TypeError(f"gate: expected a Gate, got {type(gate).__name__}")
    T, N = gate.tracks, gate.detections
    n = T + N
    if n == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), 0
    u, v = gate.track, T + gate.detection
    if gate.pairs <= _SMALL_GRAPH:
        labels = np.arange(n, dtype=np.intp)
        while True:
            lu, lv = labels[u], labels[v]
            if np.array_equal(lu, lv):
                break
            low = np.minimum(lu, lv)
            np.minimum.at(labels, lu, low)
            np.minimum.at(labels, lv, low)
            while True:
                jumped = labels[labels]
                if np.array_equal(jumped, labels):
                    break
                labels = jumped
        # every label is its component's smallest node, a root (labels[r] = r): numbered in ascending order, the
        # order of first appearance
        rank = np.cumsum(labels == np.arange(n)) - 1
        labels = rank[labels]
        count = int(rank[-1]) + 1
    else:
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(u, minlength=n), out=indptr[1:])  # the pairs are sorted by track: CSR rows as they are
        graph = scipy.sparse.csr_matrix((np.ones(gate.pairs, dtype=np.int8), v, indptr), shape=(n, n))
        count, labels = connected_components(graph, directed=False)
    labels = labels.astype(np.intp)
    return labels[:T], labels[T:], int(count)


@attrs.frozen(eq=False)
class ClusterLayout:
    """The gated pairs and tracks grouped by cluster (the common first step of the association methods).

    ``edge_order`` lists the pair indices cluster by cluster (by track, then detection inside one), the pairs of
    cluster c being ``edge_order[edge_start[c]:edge_start[c + 1]]``; likewise ``track_order`` / ``track_start``
    and ``detection_order`` / ``detection_start``.
    """

    track_cluster: np.ndarray
    detection_cluster: np.ndarray
    count: int
    edge_cluster: np.ndarray
    edge_order: np.ndarray
    edge_start: np.ndarray
    track_order: np.ndarray
    track_start: np.ndarray
    detection_order: np.ndarray
    detection_start: np.ndarray

    @property
    def cluster_tracks(self) -> np.ndarray:
        """T_c of every cluster."""
        return np.diff(self.track_start)

    @property
    def cluster_detections(self) -> np.ndarray:
        """N_c of every cluster."""
        return np.diff(self.detection_start)

    def members(self, c: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(tracks, detections, pairs) of cluster ``c``, each ascending."""
        return (
            self.track_order[self.track_start[c] : self.track_start[c + 1]],
            self.detection_order[self.detection_start[c] : self.detection_start[c + 1]],
            self.edge_order[self.edge_start[c] : self.edge_start[c + 1]],
        )


def cluster_layout(gate: Gate) -> ClusterLayout:
    """:func:`clusters` of ``gate`` with its pairs, tracks and detections grouped by cluster (compiled with numba:
    union–find and counting sorts, the same labels and orders)."""
    if NUMBA_AVAILABLE:
        T = gate.tracks
        labels, count, *grouped = association_kernels().cluster_layout(T, gate.detections, gate.track, gate.detection)
        return ClusterLayout(labels[:T], labels[T:], int(count), *grouped)
    track_cluster, detection_cluster, count = clusters(gate)

    def group(labels):
        order = np.argsort(labels, kind="stable").astype(np.intp)
        start = np.zeros(count + 1, dtype=np.intp)
        np.cumsum(np.bincount(labels, minlength=count), out=start[1:])
        return order, start

    edge_cluster = track_cluster[gate.track]
    edge_order, edge_start = group(edge_cluster)
    track_order, track_start = group(track_cluster)
    detection_order, detection_start = group(detection_cluster)
    return ClusterLayout(
        track_cluster,
        detection_cluster,
        count,
        edge_cluster,
        edge_order,
        edge_start,
        track_order,
        track_start,
        detection_order,
        detection_start,
    )


def check_scores(gate: Gate, scores, miss_scores) -> tuple[np.ndarray, np.ndarray]:
    """``scores`` (E,) and ``miss_scores`` (T,) (default zeros) as finite float arrays, checked against ``gate``."""
    if not isinstance(gate, Gate):
        raise TypeError(f"gate: expected a Gate, got {type(gate).__name__}")
    scores = as_float_array(scores, "scores", (gate.pairs,))
    if miss_scores is None:
        miss = np.zeros(gate.tracks)
    else:
        miss = as_float_array(miss_scores, "miss_scores", (gate.tracks,))
    return scores, miss
