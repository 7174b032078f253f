"""GNN and the k best joint assignments (hybridtrack.algorithms.multitarget.assignment) against brute-force
enumeration of every joint assignment."""

import numpy as np
import pytest

from hybridtrack.algorithms.multitarget.assignment import Hypotheses, gnn, k_best
from hybridtrack.algorithms.multitarget.gating import Gate, clusters, gate, gate_threshold


def joint_assignments(g: Gate, tracks):
    """Every joint assignment of ``tracks`` (each ≤ 1 gated detection, each detection ≤ 1 track): a list of
    tuples of the chosen pair index per track (−1 = missed)."""
    options = [[-1, *np.flatnonzero(g.track == t).tolist()] for t in tracks]
    out = []

    def extend(k, used, chosen):
        if k == len(tracks):
            out.append(tuple(chosen))
            return
        for e in options[k]:
            if e >= 0 and g.detection[e] in used:
                continue
            extend(k + 1, used | ({int(g.detection[e])} if e >= 0 else set()), chosen + [e])

    extend(0, frozenset(), [])
    return out


def total(chosen, tracks, scores, miss):
    return sum(scores[e] if e >= 0 else miss[t] for t, e in zip(tracks, chosen))


def detections_of(g, chosen):
    return tuple(int(g.detection[e]) if e >= 0 else -1 for e in chosen)


def random_scene(seed, T=None, N=None, spread=10.0):
    rng = np.random.default_rng(seed)
    T = int(rng.integers(2, 7)) if T is None else T
    N = int(rng.integers(2, 8)) if N is None else N
    predicted = rng.uniform(0, spread, (T, 2))
    detections = rng.uniform(0, spread, (N, 2))
    A = rng.normal(size=(T, 2, 2))
    S = 3.0 * (A @ A.transpose(0, 2, 1) + 0.5 * np.eye(2))
    g = gate(predicted, S, detections, threshold=gate_threshold(0.99, 2))
    scores = rng.normal(0.0, 3.0, g.pairs)
    miss = rng.normal(0.0, 1.0, T)
    return g, scores, miss


@pytest.mark.parametrize("dense_cells", [0, 4096])  # per cluster, and one matrix for the whole scan
@pytest.mark.parametrize("seed", range(25))
def test_gnn_equals_brute_force(monkeypatch, seed, dense_cells):
    import hybridtrack.algorithms.multitarget.assignment as assignment

    monkeypatch.setattr(assignment, "DENSE_CELLS", dense_cells)
    g, scores, miss = random_scene(seed)
    tracks = list(range(g.tracks))
    events = joint_assignments(g, tracks)
    values = np.array([total(ev, tracks, scores, miss) for ev in events])
    assigned = gnn(g, scores, miss_scores=miss)
    chosen = [int(np.flatnonzero((g.track == t) & (g.detection == d))[0]) if d >= 0 else -1 for t, d in enumerate(assigned)]
    assert total(chosen, tracks, scores, miss) == pytest.approx(values.max(), abs=1e-9)
    best = np.argsort(-values)
    if len(values) == 1 or values[best[0]] - values[best[1]] > 1e-9:
        assert tuple(assigned.tolist()) == detections_of(g, events[best[0]])
    used = assigned[assigned >= 0]
    assert used.size == np.unique(used).size


def test_gnn_default_miss_score_is_zero():
    g, scores, _ = random_scene(3)
    np.testing.assert_array_equal(gnn(g, scores), gnn(g, scores, miss_scores=np.zeros(g.tracks)))


def test_gnn_on_many_trivial_and_a_few_big_clusters():
    """Groups far apart: lone tracks with one or two detections, lone detections, lone tracks, and a few
    crowded groups; the total equals the sum of each cluster's brute-force best."""
    rng = np.random.default_rng(11)
    predicted, detections, S = [], [], []
    for k in range(400):
        centre = np.array([1000.0 * (k % 20), 1000.0 * (k // 20)])
        kind = k % 10
        if kind < 6:  # a track with 1 or 2 detections, or none
            predicted.append(centre)
            detections.extend(centre + rng.normal(0, 1, (kind % 3, 2)))
        elif kind == 6:  # two tracks sharing one detection
            predicted.extend([centre, centre + [1.5, 0]])
            detections.append(centre + [0.7, 0.1])
        elif kind == 7:  # a detection alone
            detections.append(centre)
        elif k % 40 in (8, 9):  # a crowded group
            predicted.extend(centre + rng.normal(0, 1.5, (4, 2)))
            detections.extend(centre + rng.normal(0, 1.5, (5, 2)))
        else:
            predicted.append(centre)
    predicted, detections = np.array(predicted), np.array(detections)
    S = np.tile(4.0 * np.eye(2), (len(predicted), 1, 1))
    g = gate(predicted, S, detections, threshold=gate_threshold(0.999, 2))
    scores = g.log_likelihood + 4.0 + rng.normal(0, 1, g.pairs)
    miss = rng.normal(0, 0.5, g.tracks)
    assigned = gnn(g, scores, miss_scores=miss)
    track_cluster, _, count = clusters(g)
    sizes = np.bincount(track_cluster, minlength=count)
    assert (sizes == 1).sum() > 200 and (sizes >= 4).sum() >= 10
    expected = 0.0
    for c in range(count):
        tracks = np.flatnonzero(track_cluster == c).tolist()
        if tracks:
            expected += max(total(ev, tracks, scores, miss) for ev in joint_assignments(g, tracks))
    chosen = [int(np.flatnonzero((g.track == t) & (g.detection == d))[0]) if d >= 0 else -1 for t, d in enumerate(assigned)]
    assert total(chosen, range(g.tracks), scores, miss) == pytest.approx(expected, abs=1e-8)
    used = assigned[assigned >= 0]
    assert used.size == np.unique(used).size


@pytest.mark.parametrize("seed", range(12))
def test_k_best_equals_brute_force(seed):
    g, scores, miss = random_scene(seed, spread=8.0)
    track_cluster, _, count = clusters(g)
    truth = []
    for c in range(count):
        tracks = np.flatnonzero(track_cluster == c)
        events = joint_assignments(g, tracks.tolist())
        feasible = {detections_of(g, ev): total(ev, tracks, scores, miss) for ev in events}
        truth.append((tracks, feasible, sorted(feasible.values(), reverse=True)))
    for k in range(1, 11):
        per_cluster = k_best(g, scores, k, miss_scores=miss)
        assert len(per_cluster) == count
        for hypotheses, (tracks, feasible, values) in zip(per_cluster, truth):
            np.testing.assert_array_equal(hypotheses.tracks, tracks)
            h = min(k, len(values))
            np.testing.assert_allclose(hypotheses.scores, values[:h], atol=1e-9)
            assert hypotheses.assignments.shape == (h, tracks.size)
            # each hypothesis is a distinct valid joint assignment whose score is the one reported
            rows = [tuple(row) for row in hypotheses.assignments.tolist()]
            assert len(set(rows)) == len(rows)
            for row, value in zip(rows, hypotheses.scores):
                assert feasible[row] == pytest.approx(value, abs=1e-9)


def test_k_best_of_lone_tracks_and_detections():
    g = Gate(3, 3, [0, 0], [0, 1], [0.0, 0.0], [0.0, 0.0])
    out = k_best(g, [2.0, -1.0], 5, miss_scores=[0.5, -0.25, 0.0])
    assert len(out) == 4  # {t0, d0, d1}, {t1}, {t2}, {d2}
    np.testing.assert_array_equal(out[0].assignments, [[0], [-1], [1]])
    np.testing.assert_allclose(out[0].scores, [2.0, 0.5, -1.0])
    np.testing.assert_array_equal(out[1].assignments, [[-1]])
    np.testing.assert_allclose(out[1].scores, [-0.25])
    assert out[3].tracks.size == 0 and out[3].assignments.shape == (1, 0) and out[3].scores.tolist() == [0.0]


def test_k_best_of_a_big_cluster_first_is_gnn():
    g, scores, miss = random_scene(5, T=6, N=7, spread=5.0)
    first = k_best(g, scores, 1, miss_scores=miss)
    assigned = gnn(g, scores, miss_scores=miss)
    for hypotheses in first:
        tracks = hypotheses.tracks
        chosen = [int(np.flatnonzero((g.track == t) & (g.detection == d))[0]) if d >= 0 else -1 for t, d in zip(tracks, assigned[tracks])]
        assert total(chosen, tracks, scores, miss) == pytest.approx(hypotheses.scores[0], abs=1e-9)


def test_bad_inputs_are_named():
    g, scores, miss = random_scene(1)
    with pytest.raises(ValueError, match="scores"):
        gnn(g, scores[:-1])
    with pytest.raises(ValueError, match="scores"):
        gnn(g, np.full(g.pairs, np.nan))
    with pytest.raises(ValueError, match="miss_scores"):
        gnn(g, scores, miss_scores=np.zeros(g.tracks + 1))
    with pytest.raises(TypeError, match="gate"):
        gnn("gate", scores)
    with pytest.raises(ValueError, match="k"):
        k_best(g, scores, 0)
    with pytest.raises(ValueError, match="assignments"):
        Hypotheses([0, 1], [[0]], [1.0])


def test_empty_gate():
    g = Gate.empty(3, 0)
    np.testing.assert_array_equal(gnn(g, []), [-1, -1, -1])
    out = k_best(g, [], 3, miss_scores=[1.0, 2.0, 3.0])
    assert [h.scores.tolist() for h in out] == [[1.0], [2.0], [3.0]]
