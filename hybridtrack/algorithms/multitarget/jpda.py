"""Exact joint probabilistic data association over the clusters of a gate, by an efficient hypothesis net.

A joint event θ gives each track at most one gated detection and each detection at most one track (Fortmann,
Bar-Shalom & Scheffe 1983, "Sonar tracking of multiple targets using joint probabilistic data association",
IEEE J. Oceanic Eng. 8(3); Bar-Shalom & Li 1995, "Multitarget-Multisensor Tracking", ch. 9).  With s_e the log-likelihood ratio of the gated pair
e = (t, i) and miss_t the score of track t missing, its weight is

    w(θ) = exp(Σ_{e ∈ θ} s_e + Σ_{t missed in θ} miss_t) ∝ exp(Σ_{e ∈ θ} g_e),    g_e = s_e − miss_{t(e)},

and the association probabilities are its marginals

    β_e = Σ_{θ ∋ e} w(θ) / Σ_θ w(θ),    β_t0 = P(t missed) = 1 − Σ_{e of t} β_e.

The clusters of the gating graph are independent, so every sum factorises over them.  A cluster with one track
t gives β_e = e^{s_e} / (e^{miss_t} + Σ_{e' of t} e^{s_e'}); one with one detection and several tracks gives
β_e = e^{g_e} / (1 + Σ_{e'} e^{g_e'}); both are vectorized over all such clusters.

A larger cluster is summed exactly on the net of Efficient Hypothesis Management (Maskell, Briers & Wright,
"Fast mutual exclusion", SPIE 5428, 2004; Horridge & Maskell, "Real-time tracking of hundreds of targets with
efficient exact JPDAF implementation", FUSION 2006).  Its "items" are taken in an order
x_1 … x_n, each choosing "none" (gain 0) or one of its "partners" not yet used (gain g_e); items are the
cluster's tracks (partners its detections) or its detections (partners its tracks), whichever net is
smaller.  The node of layer j is the set of used partners that items x_j … x_n can still take
(key_j = used ∩ A_j, A_j = ∪_{l ≥ j} partners(x_l)), so events agreeing on it share their future.  The forward
sums α(node) = Σ_{paths to node} exp(Σ g) and backward sums β(node) (from the node to the single end node) give
every option's marginal Σ_{edges of the option} α(parent) e^{g} β(child) / Z, Z = α(end), all in the log
domain (scores may be ± hundreds).  An item order keeping the layers' frontiers F_j = (∪_{l<j} partners(x_l))
∩ A_j small (keys are subsets of F_j) is chosen greedily, or for a large net by reverse Cuthill–McKee
(a small-bandwidth order), whichever bounds the net smaller.  β_t0 is the marginal of "none" (tracks as items)
or the probability that the track is still free after its last detection (detections as items); no
difference 1 − Σ β is taken, so small probabilities keep their relative precision.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import reverse_cuthill_mckee

from hybridtrack.algorithms.multitarget import gating
from hybridtrack.algorithms.multitarget.gating import Gate, check_scores, cluster_layout
from hybridtrack.core.validation import check_positive_int


def _group_logsumexp(values: np.ndarray, groups: np.ndarray, n: int) -> np.ndarray:
    """ln Σ_{k: groups_k = g} exp(values_k) for g = 0 … n−1 (−inf for an empty group)."""
    top = np.full(n, -np.inf)
    np.maximum.at(top, groups, values)
    shift = np.where(np.isfinite(top), top, 0.0)
    total = np.bincount(groups, weights=np.exp(values - shift[groups]), minlength=n)
    with np.errstate(divide="ignore"):
        return shift + np.log(total)


def _logsumexp(values: np.ndarray) -> float:
    if values.size == 0:
        return -math.inf
    top = float(values.max())
    return top + math.log(float(np.exp(values - top).sum()))


def _greedy_order(partner_sets: list[int], n_partners: int) -> list[int]:
    """An item order keeping the frontiers small: each step places the item leaving the smallest frontier
    (ties: the fewest new partners).  ``partner_sets`` are bit masks of each item's partners."""
    n = len(partner_sets)
    count = [0] * n_partners
    for bits in partner_sets:
        for p in range(n_partners):
            if bits >> p & 1:
                count[p] += 1
    ones = sum(1 << p for p in range(n_partners) if count[p] == 1)
    remaining = list(range(n))
    frontier = 0
    order: list[int] = []
    while remaining:
        best, best_key = -1, None
        for x in remaining:
            bits = partner_sets[x]
            key = (((frontier | bits) & ~(bits & ones)).bit_count(), (bits & ~frontier).bit_count(), x)
            if best_key is None or key < best_key:
                best, best_key = x, key
        bits = partner_sets[best]
        remaining.remove(best)
        order.append(best)
        for p in range(n_partners):
            if bits >> p & 1:
                count[p] -= 1
                if count[p] == 1:
                    ones |= 1 << p
                elif count[p] == 0:
                    ones &= ~(1 << p)
        frontier = (frontier | bits) & _union(partner_sets, remaining)
    return order


def _bandwidth_order(item: np.ndarray, partner: np.ndarray, n_items: int, n_partners: int) -> list[int]:
    """The reverse Cuthill–McKee order of the items (items adjacent when they share a partner), a small-bandwidth
    order: the frontier stays about one "width" of the cluster."""
    incidence = scipy.sparse.csr_matrix((np.ones(item.size), (item, partner)), shape=(n_items, n_partners))
    return reverse_cuthill_mckee((incidence @ incidence.T).tocsr(), symmetric_mode=True).tolist()


def _net_bound(partner_sets: list[int], order: list[int]) -> int:
    """A bound on the node count of the net in ``order``: Σ_j Σ_{k ≤ min(c_j, |F_j|)} C(|F_j|, k), with F_j the
    frontier after j items and c_j the placed items touching it (a key is a subset of F_j, one partner per item)."""
    suffix = [0] * (len(order) + 1)
    for j in range(len(order) - 1, -1, -1):
        suffix[j] = suffix[j + 1] | partner_sets[order[j]]
    bound, placed = 1, 0
    for j, x in enumerate(order):
        placed |= partner_sets[x]
        frontier = placed & suffix[j + 1]
        size = frontier.bit_count()
        touching = sum(1 for y in order[: j + 1] if partner_sets[y] & frontier)
        bound += sum(math.comb(size, k) for k in range(min(touching, size) + 1))
    return bound


def _union(partner_sets: list[int], items: list[int]) -> int:
    out = 0
    for x in items:
        out |= partner_sets[x]
    return out


def _too_large(size_text: str, limit: int, j: int, n_items: int) -> ValueError:
    return ValueError(
        f"max_hypotheses: the hypothesis net of a cluster of {size_text} exceeds {limit} nodes (at item {j + 1} of "
        f"{n_items}); exact JPDA refused: raise max_hypotheses or split the cluster (a smaller gate probability)"
    )


class _Net:
    """The hypothesis net of one cluster's items (module docstring) and its marginals."""

    def __init__(self, item: np.ndarray, partner: np.ndarray, gain: np.ndarray, n_items: int, n_partners: int, order: list[int]):
        self.item, self.partner, self.gain = item, partner, gain
        self.n_items, self.n_partners, self.order = n_items, n_partners, order
        position = np.empty(n_items, dtype=np.intp)
        position[order] = np.arange(n_items)
        layer_of = position[item]
        by_layer = np.argsort(layer_of, kind="stable")
        start = np.searchsorted(layer_of[by_layer], np.arange(n_items + 1))
        self.layer_edges = [by_layer[start[j] : start[j + 1]] for j in range(n_items)]
        # A_j (partners of items j…n−1), U_j (of items 0…j−1), F_j = U_j ∩ A_j; local bit indices within F_j
        later = np.zeros((n_items + 1, n_partners), dtype=bool)
        for j in range(n_items - 1, -1, -1):
            later[j] = later[j + 1]
            later[j, partner[self.layer_edges[j]]] = True
        earlier = np.zeros((n_items + 1, n_partners), dtype=bool)
        for j in range(n_items):
            earlier[j + 1] = earlier[j]
            earlier[j + 1, partner[self.layer_edges[j]]] = True
        frontier = earlier & later
        self.local = np.where(frontier, np.cumsum(frontier, axis=1) - 1, -1)
        self.words = max(1, -(-int(frontier.sum(axis=1).max()) // 64))
        self.last = np.full(n_partners, -1, dtype=np.intp)
        for j in range(n_items):
            self.last[partner[self.layer_edges[j]]] = j

    def _bits(self, local: np.ndarray) -> np.ndarray:
        """(k, W) words holding one bit per entry of ``local`` (−1: no bit)."""
        out = np.zeros((local.size, self.words), dtype=np.uint64)
        have = local >= 0
        rows = np.flatnonzero(have)
        out[rows, local[have] // 64] = np.left_shift(np.uint64(1), (local[have] % 64).astype(np.uint64))
        return out

    def forward(self, limit: int, size_text: str) -> None:
        W = self.words
        keys = np.zeros((1, W), dtype=np.uint64)
        log_alpha = np.zeros(1)
        self.layers = []
        nodes = 1
        for j in range(self.n_items):
            edges = self.layer_edges[j]
            partners = self.partner[edges]
            option_gain = np.concatenate([[0.0], self.gain[edges]])
            here, there = self.local[j], self.local[j + 1]
            # option o ≥ 1 is allowed unless its partner is in the key (a partner outside F_j is unused)
            option_bits = self._bits(np.concatenate([[-1], here[partners]]))
            valid = ~((keys[:, None, :] & option_bits[None, :, :]) != 0).any(axis=2)
            # the keys re-indexed on F_{j+1}
            moved = np.zeros_like(keys)
            for p in np.flatnonzero((here >= 0) & (there >= 0)).tolist():
                a, b = int(here[p]), int(there[p])
                bit = (keys[:, a // 64] >> np.uint64(a % 64)) & np.uint64(1)
                moved[:, b // 64] |= bit << np.uint64(b % 64)
            next_bits = self._bits(np.concatenate([[-1], there[partners]]))
            parent, option = np.nonzero(valid)
            child = moved[parent] | next_bits[option]
            if W == 1:
                unique, inverse = np.unique(child[:, 0], return_inverse=True)
                unique = unique[:, None]
            else:
                unique, inverse = np.unique(child, axis=0, return_inverse=True)
            inverse = inverse.reshape(-1)
            nodes += unique.shape[0]
            if nodes > limit:
                raise _too_large(size_text, limit, j, self.n_items)
            self.layers.append((keys, log_alpha, parent, option, inverse, option_gain, partners))
            log_alpha = _group_logsumexp(log_alpha[parent] + option_gain[option], inverse, unique.shape[0])
            keys = unique
        if keys.shape[0] != 1 or keys.any():
            raise RuntimeError("jpda: the hypothesis net does not end in one empty node")
        self.log_z = float(log_alpha[0])
        self.nodes = nodes

    def marginals(self, partner_free: bool):
        """(β of each edge, P(item chose none) (n_items,), P(partner unused) (n_partners,) or None)."""
        log_edge = np.full(self.item.size, -np.inf)
        log_none = np.full(self.n_items, -np.inf)
        log_free = np.full(self.n_partners, -np.inf) if partner_free else None
        log_beta = np.zeros(1)
        for j in range(self.n_items - 1, -1, -1):
            keys, log_alpha, parent, option, inverse, option_gain, partners = self.layers[j]
            toward = option_gain[option] + log_beta[inverse]
            log_marginal = log_alpha[parent] + toward - self.log_z
            per_option = _group_logsumexp(log_marginal, option, option_gain.size)
            log_none[self.order[j]] = per_option[0]
            log_edge[self.layer_edges[j]] = per_option[1:]
            if partner_free:
                option_partner = np.concatenate([[-1], partners])[option]
                for p in np.flatnonzero(self.last == j).tolist():
                    a = int(self.local[j, p])
                    free = option_partner != p
                    if a >= 0:
                        free &= ((keys[parent, a // 64] >> np.uint64(a % 64)) & np.uint64(1)) == 0
                    log_free[p] = _logsumexp(log_marginal[free])
            log_beta = _group_logsumexp(toward, parent, keys.shape[0])
        if partner_free:
            log_free[self.last < 0] = 0.0  # a partner no item can take stays free
        return np.exp(log_edge), np.exp(log_none), None if log_free is None else np.exp(log_free)


def _logaddexp(a: float, b: float) -> float:
    return max(a, b) + math.log1p(math.exp(-abs(a - b)))


def _small_net(item, partner, gain, n_items: int, n_partners: int, order: list[int], partner_free: bool, limit: int, size_text: str):
    """The same net and marginals as :class:`_Net`, in plain Python over dicts keyed by bit masks (Python ints):
    faster for the many small clusters, where numpy's per-call cost dominates."""
    position = [0] * n_items
    for j, x in enumerate(order):
        position[x] = j
    options: list[list[tuple[int, float, int, int]]] = [[(0, 0.0, -1, -1)] for _ in range(n_items)]
    for e, (x, p, g) in enumerate(zip(item.tolist(), partner.tolist(), gain.tolist())):
        options[position[x]].append((1 << p, g, e, p))
    available = [0] * (n_items + 1)
    for j in range(n_items - 1, -1, -1):
        available[j] = available[j + 1]
        for bit, _, _, _ in options[j]:
            available[j] |= bit
    ending: list[list[int]] = [[] for _ in range(n_items)]
    if partner_free:
        last = [-1] * n_partners
        for j in range(n_items):
            for _, _, _, p in options[j][1:]:
                last[p] = j
        for p, j in enumerate(last):
            ending[j].append(p)
    layers = [{0: 0.0}]
    nodes = 1
    for j in range(n_items):
        ahead, following = available[j + 1], {}
        for key, log_alpha in layers[-1].items():
            for bit, g, _, _ in options[j]:
                if key & bit:
                    continue
                child = (key | bit) & ahead
                value = log_alpha + g
                old = following.get(child)
                following[child] = value if old is None else _logaddexp(old, value)
        nodes += len(following)
        if nodes > limit:
            raise _too_large(size_text, limit, j, n_items)
        layers.append(following)
    log_z = layers[-1][0]
    edge = np.zeros(item.size)
    none = np.zeros(n_items)
    free = np.zeros(n_partners) if partner_free else None
    log_beta = {0: 0.0}
    for j in range(n_items - 1, -1, -1):
        ahead, here, sums = available[j + 1], {}, [0.0] * len(options[j])
        for key, log_alpha in layers[j].items():
            towards = []
            for o, (bit, g, _, _) in enumerate(options[j]):
                if key & bit:
                    continue
                full = key | bit
                toward = g + log_beta[full & ahead]
                towards.append(toward)
                probability = math.exp(log_alpha + toward - log_z)
                sums[o] += probability
                for p in ending[j]:
                    if not full >> p & 1:
                        free[p] += probability
            top = max(towards)
            here[key] = top + math.log(math.fsum(math.exp(t - top) for t in towards))
        log_beta = here
        none[order[j]] = sums[0]
        for o, (_, _, e, _) in enumerate(options[j][1:], start=1):
            edge[e] = sums[o]
    return edge, none, free


def _partner_masks(item: np.ndarray, partner: np.ndarray, n_items: int) -> list[int]:
    masks = [0] * n_items
    for x, p in zip(item.tolist(), partner.tolist()):
        masks[x] |= 1 << p
    return masks


#: nets of at most this many nodes (by the bound of :func:`_greedy_order`) are summed in plain Python
SMALL_NET = 300


def _cluster_marginals(row: np.ndarray, col: np.ndarray, gain: np.ndarray, Tc: int, Nc: int, limit: int, size_text: str):
    """β (per edge) and β_t0 (per local track) of one cluster with local track ``row`` and detection ``col`` of
    each edge, on the smallest net (by :func:`_net_bound`) of the two orientations, each in the greedy order
    and, for a large net, in the reverse Cuthill–McKee order."""
    candidates = []
    for tracks_first, (item, partner, n_items, n_partners) in ((True, (row, col, Tc, Nc)), (False, (col, row, Nc, Tc))):
        masks = _partner_masks(item, partner, n_items)
        order = _greedy_order(masks, n_partners)
        candidates.append((_net_bound(masks, order), tracks_first, order))
    if min(candidates)[0] > SMALL_NET:
        for tracks_first, (item, partner, n_items, n_partners) in ((True, (row, col, Tc, Nc)), (False, (col, row, Nc, Tc))):
            order = _bandwidth_order(item, partner, n_items, n_partners)
            candidates.append((_net_bound(_partner_masks(item, partner, n_items), order), tracks_first, order))
    bound, tracks_first, order = min(candidates, key=lambda candidate: candidate[0])
    item, partner, n_items, n_partners = (row, col, Tc, Nc) if tracks_first else (col, row, Nc, Tc)
    if bound <= SMALL_NET:
        edge, none, free = _small_net(item, partner, gain, n_items, n_partners, order, not tracks_first, limit, size_text)
    else:
        net = _Net(item, partner, gain, n_items, n_partners, order)
        net.forward(limit, size_text)
        edge, none, free = net.marginals(partner_free=not tracks_first)
    return edge, none if tracks_first else free


def jpda(gate: Gate, scores, *, miss_scores=None, max_hypotheses: int = 1_000_000) -> tuple[np.ndarray, np.ndarray]:
    """The exact JPDA association probabilities (module docstring): ``beta`` (E,) P(track t took detection i | Z)
    of each gated pair and ``beta_miss`` (T,) P(track t missed); per track β_t0 + Σ_{e of t} β_e = 1.

    ``scores`` (E,) the log-likelihood ratio s_e of each pair, ``miss_scores`` (T,) (default 0).  A cluster whose
    hypothesis net would exceed ``max_hypotheses`` nodes raises a ValueError naming its size.
    """
    scores, miss = check_scores(gate, scores, miss_scores)
    limit = check_positive_int(max_hypotheses, "max_hypotheses", what="the most nodes of one cluster's hypothesis net")
    beta = np.zeros(gate.pairs)
    beta_miss = np.ones(gate.tracks)
    if gate.pairs == 0:
        return beta, beta_miss
    gain = scores - miss[gate.track]
    layout = cluster_layout(gate)
    Tc, Nc = layout.cluster_tracks, layout.cluster_detections
    edge_cluster = layout.edge_cluster
    if gating.NUMBA_AVAILABLE:  # the one-track and one-detection clusters, compiled
        gating.association_kernels().simple_marginals(gain, gate.track, edge_cluster, Tc, Nc, beta, beta_miss)
    else:
        _simple_marginals(gate, gain, layout, beta, beta_miss)
    for cluster in np.flatnonzero((Tc >= 2) & (Nc >= 2)).tolist():
        tracks, detections, edges = layout.members(cluster)
        row = np.searchsorted(tracks, gate.track[edges])
        col = np.searchsorted(detections, gate.detection[edges])
        size_text = f"{tracks.size} tracks × {detections.size} detections ({edges.size} gated pairs)"
        beta[edges], beta_miss[tracks] = _cluster_marginals(row, col, gain[edges], tracks.size, detections.size, limit, size_text)
    return beta, beta_miss


def _simple_marginals(gate: Gate, gain: np.ndarray, layout, beta: np.ndarray, beta_miss: np.ndarray) -> None:
    """β and β_t0 of the clusters with one track or one detection (module docstring), written into ``beta`` and
    ``beta_miss``, in numpy (:func:`._association_kernels.simple_marginals` compiled)."""
    Tc, Nc, edge_cluster = layout.cluster_tracks, layout.cluster_detections, layout.edge_cluster
    # one track: ln Z_t = ln(1 + Σ_e e^{g_e}) relative to "missed"
    e = np.flatnonzero(Tc[edge_cluster] == 1)
    if e.size:
        t = gate.track[e]
        top = np.zeros(gate.tracks)
        np.maximum.at(top, t, gain[e])
        weight = np.exp(gain[e] - top[t])
        total = np.exp(-top) + np.bincount(t, weights=weight, minlength=gate.tracks)
        beta[e] = weight / total[t]
        owners = np.unique(t)
        beta_miss[owners] = np.exp(-top[owners]) / total[owners]

    # one detection, several tracks: the detection is clutter (gain 0) or one track's
    e = np.flatnonzero((Nc[edge_cluster] == 1) & (Tc[edge_cluster] >= 2))
    if e.size:
        c = edge_cluster[e]
        top = np.zeros(layout.count)
        np.maximum.at(top, c, gain[e])
        weight = np.exp(gain[e] - top[c])
        total = np.exp(-top) + np.bincount(c, weights=weight, minlength=layout.count)
        beta[e] = weight / total[c]
        # β_t0 = (Z − e^{g_e}) / Z, the difference taken only where it does not cancel (at most one dominant pair)
        dominant = weight > 0.5 * total[c]
        rest = np.exp(-top) + np.bincount(c[~dominant], weights=weight[~dominant], minlength=layout.count)
        others = np.where(dominant, rest[c], total[c] - weight)
        beta_miss[gate.track[e]] = others / total[c]
