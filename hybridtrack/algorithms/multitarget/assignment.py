"""Global nearest neighbour (the best joint assignment) and the k best joint assignments of gated clusters.

A joint assignment gives each track at most one gated detection and each detection at most one track.  With
s_e the log-likelihood ratio of the gated pair e = (t, i) against "t missed, i is clutter" (for instance
s = ln(P_D N(ν; 0, S) / (λ (1 − P_D P_G))); Blackman & Popoli 1999, "Design and Analysis of Modern Tracking
Systems", ch. 6) and miss_t the score of track t missing, its score is

    Σ_{assigned e} s_e + Σ_{missed t} miss_t  =  Σ_t miss_t + Σ_{assigned e} g_e,    g_e = s_e − miss_{t(e)}.

GNN is the assignment of the largest score (Blackman & Popoli 1999, ch. 6).  A small scan (T (N + T) ≤
:data:`DENSE_CELLS`) is one rectangular assignment problem on the matrix described next, for all its tracks at once;
a larger one is solved per cluster of the gating graph (:func:`~.gating.clusters`).  A cluster with one track takes its best pair if g > 0; a cluster with one
detection gives it to the track of the largest g if g > 0 (both vectorized over all such clusters).  A larger
cluster is the rectangular assignment problem on the T_c × (N_c + T_c) matrix holding g_e in the gated cells,
0 in each track's own "missed" column and a large negative finite value in the forbidden cells, solved by
``scipy.optimize.linear_sum_assignment`` (maximising; Crouse 2016, "On implementing 2D rectangular assignment
algorithms", IEEE TAES 52(4)); the matrix's dedicated missed columns make
the joint assignments and the matrix's column assignments one-to-one.

The k best assignments per cluster (track-oriented MHT) are Murty's (1968, "An algorithm for ranking all the
assignments in order of increasing cost", Operations Research 16(3)) partition of the solution space:
after the best assignment a_1 … a_q of the free rows r_1 … r_q of a sub-problem, its j-th child forces
(r_l, a_l) for l < j and forbids (r_j, a_j); each child is solved again by the assignment solver, and a heap
keeps the best unexplored sub-problem (Cox & Miller 1995, "On finding ranked assignments with application to multitarget tracking and motion
correspondence", IEEE TAES 31(1)).
"""

from __future__ import annotations

import heapq
import itertools

import attrs
import numpy as np
from scipy.optimize import linear_sum_assignment

from hybridtrack.algorithms.multitarget.gating import ClusterLayout, Gate, check_scores, cluster_layout
from hybridtrack.core.validation import check_positive_int

#: up to this many cells T (N + T), :func:`gnn` solves one assignment matrix for the whole scan (its optimum is
#: every cluster's: the clusters share no track and no detection) instead of one per cluster
DENSE_CELLS = 4096


def _readonly(value, dtype, ndim: int, name: str) -> np.ndarray:
    array = np.array(value, dtype=dtype, copy=True)
    if array.ndim != ndim:
        raise ValueError(f"{name}: expected a {ndim}-D array, got shape {array.shape}")
    array.setflags(write=False)
    return array


@attrs.frozen(eq=False)
class Hypotheses:
    """The best joint assignments of one cluster, best first.

    ``tracks`` (T_c,) the cluster's track indices; ``assignments`` (h, T_c) the detection of each track in each
    hypothesis (−1 = missed), h ≤ k; ``scores`` (h,) the total score Σ s + Σ miss of each, non-increasing.
    """

    tracks: np.ndarray = attrs.field(converter=lambda v: _readonly(v, np.intp, 1, "tracks"))
    assignments: np.ndarray = attrs.field(converter=lambda v: _readonly(v, np.intp, 2, "assignments"))
    scores: np.ndarray = attrs.field(converter=lambda v: _readonly(v, np.float64, 1, "scores"))

    def __attrs_post_init__(self):
        h = self.scores.size
        if self.assignments.shape != (h, self.tracks.size):
            raise ValueError(f"assignments: expected shape ({h}, {self.tracks.size}) (hypotheses, tracks), got {self.assignments.shape}")


def _best_of_simple_clusters(gate: Gate, gain: np.ndarray, layout: ClusterLayout, simple: np.ndarray) -> np.ndarray:
    """The best pair (largest g) of each cluster flagged ``simple`` (one track or one detection), when g > 0."""
    e = np.flatnonzero(simple[layout.edge_cluster])
    if e.size == 0:
        return e
    e = e[np.lexsort((-gain[e], layout.edge_cluster[e]))]
    cluster = layout.edge_cluster[e]
    first = np.ones(e.size, dtype=bool)
    first[1:] = cluster[1:] != cluster[:-1]
    best = e[first]
    return best[gain[best] > 0]


class _Matrices:
    """The T_c × (N_c + T_c) gain matrices of the chosen clusters, built at once in one flat buffer: g_e in the
    gated cells, 0 in each track's own missed column, −F_c in the forbidden cells.  F_c = 1 + 2 T_c max|g| is so
    large that no optimum uses a forbidden cell while a feasible assignment exists: any feasible total is
    ≥ −T_c max|g|, any total with a forbidden cell ≤ −F_c + (T_c − 1) max|g|."""

    def __init__(self, gate: Gate, gain: np.ndarray, layout: ClusterLayout, chosen: np.ndarray):
        self.rows = layout.cluster_tracks[chosen]
        self.cols = layout.cluster_detections[chosen] + self.rows
        size = self.rows * self.cols
        self.offset = np.zeros(chosen.size + 1, dtype=np.intp)
        np.cumsum(size, out=self.offset[1:])
        index = np.full(layout.count, -1, dtype=np.intp)
        index[chosen] = np.arange(chosen.size)
        # rank of each track / detection within its cluster
        track_rank = np.empty(gate.tracks, dtype=np.intp)
        track_rank[layout.track_order] = np.arange(gate.tracks) - layout.track_start[layout.track_cluster[layout.track_order]]
        detection_rank = np.empty(gate.detections, dtype=np.intp)
        detection_rank[layout.detection_order] = (
            np.arange(gate.detections) - layout.detection_start[layout.detection_cluster[layout.detection_order]]
        )
        edges = np.flatnonzero(index[layout.edge_cluster] >= 0)
        k = index[layout.edge_cluster[edges]]
        largest = np.zeros(chosen.size)
        np.maximum.at(largest, k, np.abs(gain[edges]))
        self.forbidden = -(1.0 + 2.0 * self.rows * largest)
        self.buffer = np.repeat(self.forbidden, size)
        Nc = layout.cluster_detections[chosen]
        self.buffer[self.offset[k] + track_rank[gate.track[edges]] * self.cols[k] + detection_rank[gate.detection[edges]]] = gain[edges]
        tracks_in = np.flatnonzero(index[layout.track_cluster] >= 0)
        k = index[layout.track_cluster[tracks_in]]
        r = track_rank[tracks_in]
        self.buffer[self.offset[k] + r * self.cols[k] + Nc[k] + r] = 0.0

    def matrix(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(G, A): the gains and the allowed cells of the k-th chosen cluster."""
        G = self.buffer[self.offset[k] : self.offset[k + 1]].reshape(self.rows[k], self.cols[k])
        return G, G > self.forbidden[k]


def _solve(cost: np.ndarray, forced: np.ndarray, forbidden: float):
    """The best column of every row of ``cost`` (gains, ``forbidden`` in the forbidden cells) with the rows
    ``forced`` ≥ 0 fixed to their columns: (columns (T_c,), total gain) or None when infeasible (by the choice
    of ``forbidden``, an optimum through a forbidden cell means no feasible assignment exists)."""
    free = forced < 0
    columns = forced.copy()
    if free.any():
        free_rows = np.flatnonzero(free)
        keep = np.ones(cost.shape[1], dtype=bool)
        keep[forced[~free]] = False
        free_cols = np.flatnonzero(keep)
        sub = cost[free_rows[:, None], free_cols]
        r, c = linear_sum_assignment(sub, maximize=True)
        if (sub[r, c] <= forbidden).any():
            return None
        columns[free_rows[r]] = free_cols[c]
    return columns, float(cost[np.arange(cost.shape[0]), columns].sum())


def _detections_of(columns: np.ndarray, detections: np.ndarray) -> np.ndarray:
    """Matrix columns to detection indices (−1 for the missed columns)."""
    Nc = detections.size
    return np.where(columns < Nc, detections[np.minimum(columns, max(Nc - 1, 0))], -1).astype(np.intp)


def gnn(gate: Gate, scores, *, miss_scores=None) -> np.ndarray:
    """The joint assignment maximising Σ_assigned s_e + Σ_unassigned miss_t (module docstring).

    ``scores`` (E,) the log-likelihood ratio of each gated pair, ``miss_scores`` (T,) (default 0).  Returns
    ``assigned`` (T,) intp: the detection of each track, −1 for none.
    """
    scores, miss = check_scores(gate, scores, miss_scores)
    assigned = np.full(gate.tracks, -1, dtype=np.intp)
    if gate.pairs == 0:
        return assigned
    gain = scores - miss[gate.track]
    T, N = gate.tracks, gate.detections
    if T * (N + T) <= DENSE_CELLS:  # one matrix for every cluster at once: quicker than splitting a small scan
        forbidden = -(1.0 + 2.0 * T * float(np.abs(gain).max()))
        matrix = np.full((T, N + T), forbidden)
        matrix[gate.track, gate.detection] = gain
        matrix[np.arange(T), N + np.arange(T)] = 0.0
        rows, columns = linear_sum_assignment(matrix, maximize=True)
        took = (columns < N) & (matrix[rows, columns] > 0.0)  # a pair of gain 0 is no better than the miss
        assigned[rows[took]] = columns[took]
        return assigned
    layout = cluster_layout(gate)
    Tc, Nc = layout.cluster_tracks, layout.cluster_detections
    best = _best_of_simple_clusters(gate, gain, layout, (Tc == 1) | (Nc == 1))
    assigned[gate.track[best]] = gate.detection[best]
    big = np.flatnonzero((Tc >= 2) & (Nc >= 2))
    if big.size == 0:
        return assigned
    matrices = _Matrices(gate, gain, layout, big)
    buffer, offset, rows, cols = matrices.buffer, matrices.offset.tolist(), matrices.rows.tolist(), matrices.cols.tolist()
    chosen = np.empty(int(matrices.rows.sum()), dtype=np.intp)
    at = 0
    for k in range(big.size):
        _, c = linear_sum_assignment(buffer[offset[k] : offset[k + 1]].reshape(rows[k], cols[k]), maximize=True)
        chosen[at : at + rows[k]] = c
        at += rows[k]
    # the tracks of the big clusters in cluster order, each cluster's by rank: the rows of the matrices in turn
    in_big = np.zeros(layout.count, dtype=bool)
    in_big[big] = True
    tracks = layout.track_order[in_big[layout.track_cluster[layout.track_order]]]
    cluster = layout.track_cluster[tracks]
    k = np.repeat(np.arange(big.size), matrices.rows)
    first_row = np.zeros(big.size, dtype=np.intp)
    np.cumsum(matrices.rows[:-1], out=first_row[1:])
    rank = np.arange(tracks.size) - np.repeat(first_row, matrices.rows)
    value = buffer[matrices.offset[k] + rank * matrices.cols[k] + chosen]
    Nc_of = Nc[cluster]
    took = (chosen < Nc_of) & (value > matrices.forbidden[k])  # a forbidden cell is never optimal; dropped all the same
    assigned[tracks[took]] = layout.detection_order[layout.detection_start[cluster[took]] + chosen[took]]
    return assigned


def _murty(cost: np.ndarray, k: int, forbidden: float) -> list[tuple[float, np.ndarray]]:
    """The k best (total gain, columns) of the assignment problem ``cost`` (gains, ``forbidden`` in the forbidden
    cells), best first (Murty 1968): each popped sub-problem (forced rows, its own cost) is split into children
    forcing the solution's first free rows and forbidding the next one's cell."""
    Tc = cost.shape[0]
    first = _solve(cost, np.full(Tc, -1, dtype=np.intp), forbidden)
    counter = itertools.count()
    heap = [(-first[1], next(counter), first[0], np.full(Tc, -1, dtype=np.intp), cost)]
    out = []
    while heap and len(out) < k:
        negative, _, columns, forced, node_cost = heapq.heappop(heap)
        out.append((-negative, columns))
        if len(out) == k:
            break
        child_forced = forced.copy()
        for row in np.flatnonzero(forced < 0).tolist():
            child_cost = node_cost.copy()
            child_cost[row, columns[row]] = forbidden
            solved = _solve(child_cost, child_forced, forbidden)
            if solved is not None:
                heapq.heappush(heap, (-solved[1], next(counter), solved[0], child_forced.copy(), child_cost))
            child_forced[row] = columns[row]
    return out


def k_best(gate: Gate, scores, k: int, *, miss_scores=None) -> list[Hypotheses]:
    """Per cluster of :func:`~.gating.clusters` (in its order), the k best joint assignments (Murty 1968, with
    ``scipy.optimize.linear_sum_assignment`` as the inner solver), for track-oriented MHT.

    A cluster without tracks (a lone detection) has the one empty hypothesis of score 0; a lone track the one
    hypothesis "missed" of score miss_t.  A cluster of one track or one detection has the hypotheses "none" and
    one per gated pair, ranked together for all such clusters at once.  Fewer than k hypotheses are returned
    when fewer exist.
    """
    scores, miss = check_scores(gate, scores, miss_scores)
    k = check_positive_int(k, "k", what="the number of hypotheses per cluster")
    gain = scores - miss[gate.track]
    layout = cluster_layout(gate)
    Tc, Nc, count = layout.cluster_tracks, layout.cluster_detections, layout.count
    base = np.bincount(layout.track_cluster, weights=miss, minlength=count)
    out: list[Hypotheses | None] = [None] * count
    # one track or one detection: rank "none" (gain 0) and the pairs of every such cluster together
    simple = np.flatnonzero((Tc >= 1) & ((Tc == 1) | (Nc == 1)))
    is_simple = np.zeros(count, dtype=bool)
    is_simple[simple] = True
    pairs = np.flatnonzero(is_simple[layout.edge_cluster])
    option_cluster = np.concatenate([simple, layout.edge_cluster[pairs]])
    option_gain = np.concatenate([np.zeros(simple.size), gain[pairs]])
    option_pair = np.concatenate([np.full(simple.size, -1, dtype=np.intp), pairs])
    order = np.lexsort((-option_gain, option_cluster))
    option_cluster, option_gain, option_pair = option_cluster[order], option_gain[order], option_pair[order]
    start = np.searchsorted(option_cluster, simple)
    stop = np.minimum(np.append(start[1:], option_cluster.size), start + k)
    for c, a, b in zip(simple.tolist(), start.tolist(), stop.tolist()):
        tracks = layout.track_order[layout.track_start[c] : layout.track_start[c + 1]]
        chosen = option_pair[a:b]
        assignments = np.full((b - a, tracks.size), -1, dtype=np.intp)
        taken = np.flatnonzero(chosen >= 0)
        assignments[taken, np.searchsorted(tracks, gate.track[chosen[taken]])] = gate.detection[chosen[taken]]
        out[c] = Hypotheses(tracks, assignments, base[c] + option_gain[a:b])
    for c in np.flatnonzero(Tc == 0).tolist():
        out[c] = Hypotheses(np.zeros(0, dtype=np.intp), np.zeros((1, 0), dtype=np.intp), np.array([0.0]))
    big = np.flatnonzero((Tc >= 2) & (Nc >= 2))
    matrices = _Matrices(gate, gain, layout, big)
    for index, c in enumerate(big.tolist()):
        tracks, detections, _ = layout.members(c)
        cost, _ = matrices.matrix(index)
        ranked = _murty(cost, k, float(matrices.forbidden[index]))
        assignments = np.array([_detections_of(columns, detections) for _, columns in ranked], dtype=np.intp)
        out[c] = Hypotheses(tracks, assignments, base[c] + np.array([total for total, _ in ranked]))
    return out
