"""Multiple hypothesis tracking: the K best global hypotheses, k-best assignments per parent, N-scan pruning.

Reid's MHT (Reid 1979, "An algorithm for tracking multiple targets", IEEE TAC 24(6)) keeps, instead of GNN's one
decision per scan, several *global hypotheses* Θ: each a consistent explanation of every scan so far (which
detections each track took, which were clutter).  Its track-oriented form (Blackman 2004, "Multiple hypothesis
tracking for multiple target tracking", IEEE AES Magazine 19(1)) stores the *track hypotheses* as the
leaves of one tree per track (a *family*): a leaf is one history of detections and misses of its family, with its
own filter; a global hypothesis is a choice of at most one leaf per family such that no detection is used twice.

Scores.  With s_ti = ln(P_D N(z_ti; ẑ_t, S_t)) − ln(λ (1 − P_D P_G)) the log-likelihood ratio of "leaf t took
detection i" against "t missed, i is clutter" (the tracker's score, Bar-Shalom, Willett & Tian 2011, §6.2), Reid's
hypothesis probability (Reid 1979: P_D^{N_DT} (1 − P_D)^{N_TGT − N_DT} β_FT^{N_FT} β_NT^{N_NT} Π N(…) times
the parent's probability) is, in logarithms and relative to "every detection is clutter", the recursion

    L(Θ_k) = L(Θ_{k−1}) + Σ_{(t, i) ∈ a} s_ti + Σ_{families f born at k in Θ_k} L₁(f),

where a is the scan's joint assignment of Θ_k's leaves (each leaf at most one gated detection, each detection at
most one leaf; a miss scores 0) and L₁ = ln(β_NT/λ) (+ the second point's ln(P_D N(z₂; z₁, 2R + (Δt σ_v)² I)/λ) for a
two-point start) the new family's initial track score (Blackman 2004; :mod:`.management`).  Each leaf also carries the
tracker's track score for management (hit ΔL = s_ti + ln(1 − P_D P_G) = ln(P_D N/λ), miss ln(1 − P_D P_G): the
:class:`~.tracker.MultiTargetTracker` bookkeeping) and its :class:`~.management.TrackStatus` row.

One scan k (the leaves are the rows of one :class:`MultipleModelState`, so that every filter step is one call):

1. **Predict** every leaf (one step without measurement) and gate all leaves against the scan's detections at once
   (:func:`~.gating.gate_checked`, joined by the reported velocity where the tracks measure it: :class:`~.tracker.MultiTargetTracker`).
2. **Children** (Cox & Hingorani 1996, "An efficient implementation of Reid's MHT algorithm and its evaluation for
   the purpose of visual tracking", IEEE PAMI 18(2)): for each parent Θ_{k−1} the gate restricted to its leaves,
   and per gated cluster its k best assignments (Murty 1968 by :func:`~.assignment.k_best`); the clusters are
   independent, so the parent's K best children are the K best sums of one ranked option per cluster (found over
   the clusters whose regret s_c,1 − s_c,j is among the K − 1 smallest, by a heap over index vectors).  Of all
   parents' children the K best (by L) are kept.
3. **Leaves**: the distinct (parent leaf, detection or miss) pairs the kept children use, each computed once — the
   hits in one estimator step from the parents' posteriors, the misses the predicted rows.
4. **N-scan pruning** (Blackman 2004): a hypothesis survives only if, for every family it shares with the
   best hypothesis Θ*, its leaf has the same ancestor N scans back as Θ*'s leaf (the decisions older than N scans
   are those of Θ*).  Leaves that no hypothesis uses are dropped.
5. **Management** (:mod:`.management`, M-of-N or the track score) is decided per family on its leaf in the best
   hypothesis that holds it (Θ* for the families it holds); a confirmed family's leaves are all confirmed, a
   deleted family leaves every hypothesis (hypotheses made equal by it are merged, the better one kept).
6. **Initiation**: the tracker's two-point or single-point start (:meth:`~.tracker.MultiTargetTracker._pair_seeds`,
   ``_two_point``, ``_single_point``) on the detections Θ* left unused (seeds: those of the previous scans, also
   unused in the current Θ*).  A new family joins *every* hypothesis in which its detections are all unused
   (``L₁`` added to those), and no other: a hypothesis that gave one of them to a track keeps that explanation.

Output (:class:`~.tracker.MultiTargetResult`, as :meth:`MultiTargetTracker.run`): per scan every confirmed family
in Θ* with its Θ* leaf's estimate; ids are the families' (1, 2, … in the order started); each track's detections
are those of the chosen branch: the ancestry of the family's leaf in the best hypothesis that held it last (the
decisions older than N scans, fixed by the pruning, and the last N of that leaf).  With K = 1 this is GNN.
"""

from __future__ import annotations

import heapq
import itertools
import math

import numpy as np

from hybridtrack.algorithms.multiple_model import MultipleModelEstimator, MultipleModelState
from hybridtrack.algorithms.multitarget.assignment import k_best
from hybridtrack.algorithms.multitarget.gating import Gate, clusters
from hybridtrack.algorithms.multitarget.management import CONFIRMED, TrackStatus
from hybridtrack.algorithms.multitarget.tracker import (
    MultiTargetResult,
    MultiTargetTracker,
    TrackHistory,
    join_rows,
    put_rows,
    take_rows,
)
from hybridtrack.core.validation import check_positive_int
from hybridtrack.engine.detections import Detections


def best_sums(regrets: list[np.ndarray], k: int, *, bound: float = math.inf) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` smallest sums of one entry per list of ``regrets`` (C lists, each starting with 0 and
    non-decreasing), smallest first, those ≤ ``bound`` only (the first, 0, always): (totals (h,), choices (h, C)
    the entry index of each list), h ≤ k.

    The lists that can change are ordered by their second entry; a heap over index vectors j, each with the last
    list p it changed, reaches every vector once: from (j, p) its successors raise j_p by one, set j_{p+1} = 1, or
    (when j_p = 1) move that 1 from p to p + 1 — none is smaller than its predecessor, and every vector has exactly
    one predecessor (the ranked enumeration of sums behind Murty-style k-best methods; Cox & Miller 1995, "On
    finding ranked assignments…", IEEE TAES 31(1)).  The caller passes only the entries that may matter: an entry
    whose own regret is not among the k − 1 smallest of all lists is in none of the k smallest sums (the all-zero
    sum and those k − 1 single changes are smaller)."""
    k = check_positive_int(k, "k", what="the number of sums")
    C = len(regrets)
    movable = [c for c in range(C) if regrets[c].size > 1]
    movable.sort(key=lambda c: float(regrets[c][1]))
    steps = [regrets[c] for c in movable]
    m = len(steps)
    counter = itertools.count()
    heap = [(0.0, next(counter), (0,) * m, -1)]
    totals, chosen = [], []
    while heap and len(totals) < k:
        r, _, index, p = heapq.heappop(heap)
        if totals and r > bound:
            break
        totals.append(r)
        chosen.append(index)
        if p >= 0 and index[p] + 1 < steps[p].size:  # raise j_p
            j = index[p]
            heapq.heappush(heap, (r - steps[p][j] + steps[p][j + 1], next(counter), index[:p] + (j + 1,) + index[p + 1 :], p))
        if p + 1 < m:
            q = p + 1
            heapq.heappush(heap, (r + steps[q][1], next(counter), index[:q] + (1,) + index[q + 1 :], q))  # set j_{p+1} = 1
            if p >= 0 and index[p] == 1:  # move the 1 from p to p + 1
                heapq.heappush(heap, (r - steps[p][1] + steps[q][1], next(counter), index[:p] + (0, 1) + index[q + 1 :], q))
    out = np.zeros((len(chosen), C), dtype=np.intp)
    if m:
        out[:, movable] = np.array(chosen, dtype=np.intp)
    return np.array(totals), out


class MHTTracker(MultiTargetTracker):
    """Reid's multiple hypothesis tracker, track-oriented, with the K best global hypotheses (module docstring).

    ``estimator`` and every keyword of :class:`~.tracker.MultiTargetTracker` (``management``,
    ``detection_probability``, ``clutter_density``, ``birth_density``, ``gate_probability``, ``initiation``,
    ``max_speed``, ``velocity_sigma``, ``seed_window``; ``updates_per_scan`` must be 1: one detection per track per
    scan); ``association`` is ``"mht"``; ``hypotheses`` K, the global hypotheses kept (K = 1: GNN); ``scans`` N, the
    N-scan pruning depth (decisions older than N scans are those of the best hypothesis)."""

    def __init__(self, estimator: MultipleModelEstimator, *, association: str = "mht", hypotheses: int = 10, scans: int = 3, **options):
        if association != "mht":
            raise ValueError(f"association: MHTTracker associates by multiple hypotheses, expected 'mht', got {association!r}")
        updates = options.get("updates_per_scan", 1)
        if updates != 1:
            raise ValueError(f"updates_per_scan: MHT gives each track at most one detection per scan, expected 1, got {updates!r}")
        self.hypotheses = check_positive_int(hypotheses, "hypotheses", what="K, the global hypotheses kept")
        self.scans = check_positive_int(scans, "scans", what="N, the depth of the N-scan pruning")
        super().__init__(estimator, association="gnn", **options)
        self.association = "mht"

    # ------------------------------------------------------------------ pieces
    def _children(self, assign: np.ndarray, score: np.ndarray, pairs: Gate, scores: np.ndarray):
        """Up to K children of every parent hypothesis (rows of ``assign`` (H, F): each family's leaf, −1 absent),
        the K best kept: (parent (C,), score (C,), decision (C, F) the scan detection of each family's new leaf,
        −1 missed, −2 absent), best first.

        The parents' restricted gates are stacked into one problem (a slot per (parent, leaf); parent h's copy of
        detection i is h m + i), so no cluster spans two parents.  A slot alone in its cluster has the options
        "missed" (0) and each of its pairs (s), ranked at once for all such slots; the other clusters are ranked by
        one :func:`~.assignment.k_best` call (Murty).  Per parent, the options of a regret among its K − 1
        smallest are combined by :func:`best_sums`."""
        K = self.hypotheses
        H, F = assign.shape
        m = max(pairs.detections, 1)
        slot_parent, slot_column = np.nonzero(assign >= 0)  # ascending parent, then column
        slot_leaf = assign[slot_parent, slot_column]
        S = slot_leaf.size
        start = np.searchsorted(pairs.track, np.arange(pairs.tracks + 1))
        count = start[slot_leaf + 1] - start[slot_leaf]
        e = np.repeat(start[slot_leaf] - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
        track = np.repeat(np.arange(S), count)
        detection = pairs.detection[e]
        gain = scores[e]
        stacked = Gate(S, H * m, track, slot_parent[track] * m + detection, pairs.d2[e], pairs.log_likelihood[e])
        track_cluster = clusters(stacked)[0]
        lone = np.bincount(track_cluster, minlength=max(S, 1))[track_cluster] == 1
        best = np.full(S, -1, dtype=np.intp)
        base = np.asarray(score, dtype=float).copy()
        # lone slots: "missed" and each pair, best first per slot
        in_lone = lone[track]
        o_slot = np.concatenate([np.flatnonzero(lone), track[in_lone]])
        o_score = np.concatenate([np.zeros(int(lone.sum())), gain[in_lone]])
        o_detection = np.concatenate([np.full(int(lone.sum()), -1, dtype=np.intp), detection[in_lone]])
        order = np.lexsort((-o_score, o_slot))
        o_slot, o_score, o_detection = o_slot[order], o_score[order], o_detection[order]
        head = np.ones(o_slot.size, dtype=bool)
        head[1:] = o_slot[1:] != o_slot[:-1]
        best[o_slot[head]] = o_detection[head]
        np.add.at(base, slot_parent[o_slot[head]], o_score[head])
        top = np.repeat(o_score[head], np.diff(np.append(np.flatnonzero(head), o_slot.size)))
        rest = ~head
        # the options after each cluster's best: parent, cluster (a lone slot s: s; a ranked cluster j: S + j), regret,
        # and what they assign (a lone slot's detection; a ranked cluster's row)
        opt_parent = [slot_parent[o_slot[rest]]]
        opt_cluster = [o_slot[rest]]
        opt_regret = [top[rest] - o_score[rest]]
        opt_what = [o_detection[rest]]
        ranked = []
        crowded = np.flatnonzero(~lone)
        if crowded.size:
            renumber = np.full(S, -1, dtype=np.intp)
            renumber[crowded] = np.arange(crowded.size)
            inside = ~in_lone
            sub = Gate(
                crowded.size, H * m, renumber[track[inside]], stacked.detection[inside], stacked.d2[inside], stacked.log_likelihood[inside]
            )
            for cluster in k_best(sub, gain[inside], K):
                if cluster.tracks.size == 0:
                    continue
                slots = crowded[cluster.tracks]
                h = int(slot_parent[slots[0]])
                chosen = np.where(cluster.assignments >= 0, cluster.assignments - h * m, -1)
                best[slots] = chosen[0]
                base[h] += cluster.scores[0]
                if cluster.scores.size > 1:
                    j = len(ranked)
                    opt_parent.append(np.full(cluster.scores.size - 1, h))
                    opt_cluster.append(np.full(cluster.scores.size - 1, S + j))
                    opt_regret.append(cluster.scores[0] - cluster.scores[1:])
                    opt_what.append(np.arange(1, cluster.scores.size))
                ranked.append((slots, chosen))
        opt_parent, opt_cluster = np.concatenate(opt_parent), np.concatenate(opt_cluster)
        opt_regret, opt_what = np.concatenate(opt_regret), np.concatenate(opt_what)
        # per parent its K − 1 options of the smallest regret (a cluster's kept options are its first ones)
        order = np.lexsort((opt_regret, opt_parent))
        group = np.searchsorted(opt_parent[order], np.arange(H + 1))
        first = np.searchsorted(slot_parent, np.arange(H + 1))
        parents, totals, decisions = [None] * H, [None] * H, [None] * H
        kth = []  # the K best totals so far (a min-heap): a parent's children below the K-th are not needed
        for h in np.argsort(-base, kind="stable").tolist():
            decision = np.full(F, -2, dtype=np.intp)
            decision[slot_column[first[h] : first[h + 1]]] = best[first[h] : first[h + 1]]
            kept = order[group[h] : min(group[h + 1], group[h] + K - 1)]
            involved = list(dict.fromkeys(opt_cluster[kept].tolist()))
            entries = [kept[opt_cluster[kept] == c] for c in involved]
            bound = math.inf if len(kth) < K else base[h] - kth[0]
            sums, choice = best_sums([np.concatenate([[0.0], opt_regret[x]]) for x in entries], K, bound=bound)
            full = np.repeat(decision[None], sums.size, axis=0)
            for i, c in zip(*np.nonzero(choice)):
                option = entries[c][choice[i, c] - 1]
                cluster = int(opt_cluster[option])
                if cluster < S:
                    full[i, slot_column[cluster]] = opt_what[option]
                else:
                    slots, chosen = ranked[cluster - S]
                    full[i, slot_column[slots]] = chosen[opt_what[option]]
            parents[h], totals[h], decisions[h] = np.full(sums.size, h), base[h] - sums, full
            for value in totals[h].tolist():
                if len(kth) < K:
                    heapq.heappush(kth, value)
                elif value > kth[0]:
                    heapq.heapreplace(kth, value)
        parent, total, decision = np.concatenate(parents), np.concatenate(totals), np.concatenate(decisions)
        keep = np.argsort(-total, kind="stable")[:K]
        return parent[keep], total[keep], decision[keep]

    def _pruned(self, assign: np.ndarray, lineage: np.ndarray) -> np.ndarray:
        """(H,) whether each hypothesis agrees with the best (row 0) on the ancestor N scans back of every family both hold."""
        root = np.where(assign >= 0, lineage[np.maximum(assign, 0), 0], -1)
        agree = (root == root[0]) | (assign < 0) | (assign[0] < 0)[None]
        return agree.all(axis=1)

    # ------------------------------------------------------------------ the run
    def run(self, detections: Detections) -> MultiTargetResult:
        """All scans of ``detections``, in order (module docstring)."""
        return self.run_hypotheses(detections)[0]

    def run_hypotheses(self, detections: Detections) -> tuple[MultiTargetResult, np.ndarray]:
        """:meth:`run`'s result and the scores L(Θ) of the global hypotheses kept at the end, best first."""
        if not isinstance(detections, Detections):
            raise TypeError(f"detections: expected a Detections (scans of unlabelled detections), got {type(detections).__name__}")
        if detections.measurement_dim != 2:
            raise ValueError(f"detections: expected (x, y) positions, got {detections.measurement_dim} components")
        est, N = self.estimator, self.scans
        # leaves (track hypotheses): rows of one state, with per-leaf arrays
        leaves: MultipleModelState | None = None
        status = TrackStatus.born(0, 0.0, 0.0)
        lineage = np.zeros((0, N + 1), dtype=np.intp)  # node ids of the leaf and its ancestors 1 … N scans back
        leaf_detection = np.zeros(0, dtype=np.intp)  # this scan's detection of each leaf (−1 none)
        # families (columns) and global hypotheses (rows)
        family_ids = np.zeros(0, dtype=np.intp)
        family_confirmed = np.zeros(0, dtype=bool)
        family_terminal = np.zeros(0, dtype=np.intp)  # the node of each family's deciding leaf
        assign = np.zeros((1, 0), dtype=np.intp)
        score = np.zeros(1)
        used = np.zeros((1, 0), dtype=bool)  # per hypothesis: detections used, from detection index used_base on
        used_base = 0
        # the tree: every node's parent node and detection (−1: a birth / a miss)
        node_parent: list[np.ndarray] = []
        node_detection: list[np.ndarray] = []
        nodes = 0
        terminal: dict[int, int] = {}
        origin: dict[int, list[int]] = {}
        born_at: dict[int, float] = {}
        confirmed_at: dict[int, float] = {}
        deleted_at: dict[int, float | None] = {}
        seeds = np.zeros(0, dtype=np.intp)
        next_id = 1
        rows_out: dict[str, list] = {k: [] for k in ("time", "scan", "id", "mean", "pcov", "mode", "hit")}
        bounds = detections.bounds()
        previous = None
        pos = self._position
        reported = self._reported_velocity(detections)
        for k, now in enumerate(detections.scan_times.tolist()):
            here = np.arange(bounds[k].start, bounds[k].stop)
            z, t = detections.z[here], detections.times[here]
            v = None if reported is None else reported[here]
            m = here.size
            used = np.concatenate([used, np.zeros((used.shape[0], m), dtype=bool)], axis=1)
            now_col = bounds[k].start - used_base
            M = 0 if leaves is None else leaves.mean.shape[0]
            if M:
                dt = now - previous
                predicted = est.step(leaves, np.full((M, self._measured), np.nan), dt)
                pairs, measured = self._gate(predicted, z, t, v, now)
                scores = self._scores(pairs.log_likelihood)
                parent, score, decision = self._children(assign, score, pairs, scores)
                # the distinct (parent leaf, detection or miss) of the kept children: the new leaves
                parent_leaf = assign[parent]
                present = parent_leaf >= 0
                key, inverse = np.unique(parent_leaf[present] * (m + 1) + decision[present] + 1, return_inverse=True)
                source, detection = key // (m + 1), key % (m + 1) - 1
                assign = np.full(parent_leaf.shape, -1, dtype=np.intp)
                assign[present] = inverse
                hit = detection >= 0
                rows = np.flatnonzero(hit)
                new = take_rows(predicted, source)
                gain = np.zeros(key.size)
                if rows.size:
                    width = max(m, 1)
                    e = np.searchsorted(pairs.track * width + pairs.detection, source[rows] * width + detection[rows])
                    new = put_rows(new, rows, self._updated(leaves, predicted, source[rows], measured[e], dt))
                    gain[rows] = scores[e]  # ΔL = ln(1 − P_D P_G) + s = ln(P_D N / λ)
                leaves = new
                status = status.take(source)
                status.record(hit, self._log_miss + gain, now)
                ids = nodes + np.arange(key.size)
                node_parent.append(lineage[source, -1])
                leaf_detection = np.where(hit, bounds[k].start + np.maximum(detection, 0), -1)
                node_detection.append(leaf_detection)
                nodes += key.size
                lineage = np.column_stack([lineage[source, 1:], ids])
                used = used[parent]
                h, f = np.nonzero(decision >= 0)
                used[h, now_col + decision[h, f]] = True
                # N-scan pruning
                keep = self._pruned(assign, lineage)
                assign, score, used = assign[keep], score[keep], used[keep]
                # management on each family's leaf in the best hypothesis holding it
                have = assign >= 0
                held = have.any(axis=0)
                decider = assign[np.argmax(have, axis=0), np.arange(assign.shape[1])]
                confirm, delete = self.management.decide(status, now)
                confirm = held & confirm[decider]
                delete = held & delete[decider]
                family_confirmed = family_confirmed | confirm
                column = self._columns(assign, key.size)
                confirmed_leaf = (column >= 0) & family_confirmed[np.maximum(column, 0)]
                status.status = np.where(confirmed_leaf, CONFIRMED, status.status).astype(np.int8)
                family_terminal = np.where(held, lineage[decider, -1], family_terminal)
                for track in family_ids[confirm].tolist():
                    confirmed_at[track] = now
                gone = delete | ~held
                for track, node in zip(family_ids[gone & family_confirmed].tolist(), family_terminal[gone & family_confirmed].tolist()):
                    deleted_at[track] = now
                    terminal[track] = node
                shown = ~gone & family_confirmed & (assign[0] >= 0)
                if shown.any():
                    best = assign[0, shown]
                    rows_out["time"].append(np.full(best.size, now))
                    rows_out["scan"].append(np.full(best.size, k))
                    rows_out["id"].append(family_ids[shown])
                    rows_out["mean"].append(leaves.mean[best])
                    rows_out["pcov"].append(leaves.cov[best][:, pos[:, None], pos[None, :]])
                    rows_out["mode"].append(np.argmax(leaves.log_mode_probabilities[best], axis=1))
                    rows_out["hit"].append(leaf_detection[best] >= 0)
                best_used = used[0, now_col : now_col + m].copy()  # before the deletions: the tracker's "used"
                # drop the deleted / vanished families, merge equal hypotheses, drop unused leaves
                assign = assign[:, ~gone]
                family_ids, family_confirmed, family_terminal = family_ids[~gone], family_confirmed[~gone], family_terminal[~gone]
                _, first = np.unique(assign, axis=0, return_index=True)
                first = np.sort(first)
                assign, score, used = assign[first], score[first], used[first]
                alive = np.unique(assign[assign >= 0])
                remap = np.full(key.size, -1, dtype=np.intp)
                remap[alive] = np.arange(alive.size)
                assign = np.where(assign >= 0, remap[np.maximum(assign, 0)], -1)
                leaves, status = take_rows(leaves, alive), status.take(alive)
                lineage, leaf_detection = lineage[alive], leaf_detection[alive]
            else:
                best_used = used[0, now_col : now_col + m].copy()
            # initiation from the detections the best hypothesis left unused
            candidates = seeds[~used[0, seeds - used_base]] if seeds.size else seeds  # also unused in the current Θ*
            birth, free, paired = self._births(detections, candidates, here, np.flatnonzero(~best_used), now)
            seeds = seeds[~np.isin(seeds, paired)]
            if birth is not None:
                fresh, fresh_status, picked = birth
                B, hits = picked.shape
                new_ids = np.arange(next_id, next_id + B)
                next_id += B
                for track, chosen in zip(new_ids.tolist(), picked.tolist()):
                    born_at[track] = now
                    origin[track] = [int(i) for i in chosen]
                # a new family joins every hypothesis in which its detections are all unused
                joined = ~used[:, picked - used_base].any(axis=2)  # (H, B)
                for j in range(hits):
                    used[:, picked[:, j] - used_base] |= joined
                M = 0 if leaves is None else leaves.mean.shape[0]
                assign = np.concatenate([assign, np.where(joined, M + np.arange(B), -1)], axis=1)
                score = score + joined @ fresh_status.score
                order = np.argsort(-score, kind="stable")
                assign, score, used = assign[order], score[order], used[order]
                leaves = fresh if leaves is None or M == 0 else join_rows([leaves, fresh])
                status = TrackStatus.concatenate([status, fresh_status])
                ids = nodes + np.arange(B)
                node_parent.append(np.full(B, -1, dtype=np.intp))
                node_detection.append(np.full(B, -1, dtype=np.intp))
                nodes += B
                lineage = np.vstack([lineage, np.repeat(ids[:, None], N + 1, axis=1)])
                leaf_detection = np.concatenate([leaf_detection, np.full(B, -1, dtype=np.intp)])
                family_ids = np.concatenate([family_ids, new_ids])
                family_confirmed = np.concatenate([family_confirmed, np.zeros(B, dtype=bool)])
                family_terminal = np.concatenate([family_terminal, ids])
            if self.initiation == "two_point":
                if self.seed_window is None or previous is None:
                    seeds = here[free]
                else:  # the older seeds within the window wait on, but those a track of the best hypothesis explains
                    seeds = seeds[detections.times[seeds] >= now - self.seed_window]
                    best = assign[0][assign[0] >= 0]
                    if seeds.size and best.size:
                        seeds = seeds[~self._explained(take_rows(leaves, best), now, *self._seed_points(detections, seeds))]
                    seeds = np.concatenate([seeds, here[free]])
            # the detections a later scan may ask about: the seeds' and on
            base = int(seeds.min()) if seeds.size else bounds[k].stop
            used, used_base = used[:, base - used_base :], base
            previous = now
        for track, node, confirmed in zip(family_ids.tolist(), family_terminal.tolist(), family_confirmed.tolist()):
            if confirmed:
                deleted_at.setdefault(track, None)
                terminal[track] = node
        histories = self._histories(detections, terminal, origin, born_at, confirmed_at, deleted_at, node_parent, node_detection)

        result = self._result(detections, rows_out, histories, next_id - 1)
        return result, score.copy()

    @staticmethod
    def _columns(assign: np.ndarray, leaves: int) -> np.ndarray:
        """(leaves,) the family (column of ``assign``) of every leaf, −1 for a leaf that no hypothesis holds."""
        out = np.full(leaves, -1, dtype=np.intp)
        h, f = np.nonzero(assign >= 0)
        out[assign[h, f]] = f
        return out

    @staticmethod
    def _histories(detections, terminal, origin, born_at, confirmed_at, deleted_at, node_parent, node_detection):
        """The confirmed families' :class:`TrackHistory`: their start detections and those on the path from the
        terminal node back to the birth node (all families traced at once, one parent step per scan)."""
        tracks = sorted(confirmed_at)
        parent = np.concatenate(node_parent) if node_parent else np.zeros(0, dtype=np.intp)
        taken = np.concatenate(node_detection) if node_detection else np.zeros(0, dtype=np.intp)
        current = np.array([terminal[track] for track in tracks], dtype=np.intp)
        found = []
        while current.size and (current >= 0).any():
            alive = current >= 0
            found.append(np.where(alive, taken[np.maximum(current, 0)], -1))
            current = np.where(alive, parent[np.maximum(current, 0)], -1)
        path = np.array(found, dtype=np.intp).T if found else np.zeros((len(tracks), 0), dtype=np.intp)
        out = []
        for row, track in enumerate(tracks):
            picked = origin[track] + [int(i) for i in path[row][path[row] >= 0].tolist()]
            out.append(
                TrackHistory(
                    id=track,
                    born=born_at[track],
                    confirmed=confirmed_at[track],
                    deleted=deleted_at.get(track),
                    detections=np.array(sorted(picked, key=lambda i: detections.times[i]), dtype=np.intp),
                )
            )
        return tuple(out)
