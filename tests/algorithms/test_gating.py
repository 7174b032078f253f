"""χ² gating with a k-d tree (hybridtrack.algorithms.multitarget.gating) against the dense all-pairs computation,
and the clusters of the gating graph against a hand example."""

import numpy as np
import pytest
from scipy.stats import chi2, multivariate_normal

from hybridtrack.algorithms.multitarget.gating import Gate, cluster_layout, clusters, gate, gate_threshold


def random_covariances(rng, T, m, elongation=1.0):
    """SPD (T, m, m): random rotations of diagonal spreads up to ``elongation``² in ratio."""
    Q, _ = np.linalg.qr(rng.normal(size=(T, m, m)))
    spread = rng.uniform(1.0, elongation, (T, m)) ** 2 * rng.uniform(0.5, 2.0, (T, 1))
    return np.einsum("tij,tj,tkj->tik", Q, spread, Q)


def dense(predicted, S, detections, gamma, velocities=None, offsets=None):
    """All T × N pairs (dense solves, no Cholesky): (track, detection, d2, log-likelihood) of those with d2 ≤ γ, by
    track then detection; ln N = −½ (d2 + ln det S + m ln 2π) with ``slogdet``."""
    z = detections[None, :, :] if velocities is None else detections[None] - velocities[:, None, :] * offsets[None, :, None]
    nu = z - predicted[:, None, :]  # (T, N, m)
    d2 = np.einsum("tnj,tnj->tn", nu, np.linalg.solve(S[:, None], nu[..., None])[..., 0])
    t, i = np.nonzero(d2 <= gamma)
    log_det = np.linalg.slogdet(S)[1]
    ll = -0.5 * (d2[t, i] + log_det[t] + predicted.shape[1] * np.log(2 * np.pi))
    return t, i, d2[t, i], ll


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [1, 2, 3])
def test_gate_equals_all_pairs(seed, m):
    rng = np.random.default_rng(seed)
    T, N = int(rng.integers(1, 25)), int(rng.integers(1, 40))
    predicted = rng.uniform(-10, 10, (T, m))
    detections = rng.uniform(-10, 10, (N, m))
    S = random_covariances(rng, T, m, elongation=30.0 if seed % 2 else 1.5)  # elongated gates: the ball is loose
    gamma = gate_threshold(0.99, m)
    got = gate(predicted, S, detections, threshold=gamma)
    t, i, d2, ll = dense(predicted, S, detections, gamma)
    assert got.tracks == T and got.detections == N
    np.testing.assert_array_equal(got.track, t)
    np.testing.assert_array_equal(got.detection, i)
    np.testing.assert_allclose(got.d2, d2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.log_likelihood, ll, rtol=1e-9, atol=1e-9)
    assert got.track.dtype == np.intp and not got.track.flags.writeable
    for e in range(0, got.pairs, max(1, got.pairs // 5)):  # a few against scipy's density
        t_, i_ = got.track[e], got.detection[e]
        assert got.log_likelihood[e] == pytest.approx(multivariate_normal(predicted[t_], S[t_]).logpdf(detections[i_]), rel=1e-9)


def test_very_elongated_gate_keeps_every_pair_inside():
    """A thin ellipse along a diagonal: the pairs deep inside it are found and those beside it are not."""
    S = np.array([[[1e4 + 1e-2, 1e4 - 1e-2], [1e4 - 1e-2, 1e4 + 1e-2]]]) / 2  # variance 1e4 along (1, 1), 1e-2 across
    along = np.array([[50.0, 50.0], [-80.0, -80.0], [0.0, 0.5], [30.0, 29.0]])
    got = gate(np.zeros((1, 2)), S, along, threshold=gate_threshold(0.99, 2))
    t, i, d2, ll = dense(np.zeros((1, 2)), S, along, gate_threshold(0.99, 2))
    np.testing.assert_array_equal(got.detection, i)
    np.testing.assert_array_equal(got.detection, [0, 1])
    np.testing.assert_allclose(got.d2, d2, rtol=1e-9)


def test_time_offsets_move_detections_along_the_tracks():
    rng = np.random.default_rng(7)
    T, N = 15, 30
    predicted = rng.uniform(-50, 50, (T, 2))
    velocities = rng.normal(0, 5, (T, 2))
    offsets = -rng.uniform(0, 4, N)
    detections = rng.uniform(-50, 50, (N, 2))
    detections[:T] = predicted + velocities * offsets[:T, None]  # these sit on their track once moved
    S = random_covariances(rng, T, 2, elongation=3.0)
    gamma = gate_threshold(0.95, 2)
    got = gate(predicted, S, detections, threshold=gamma, velocities=velocities, offsets=offsets)
    t, i, d2, ll = dense(predicted, S, detections, gamma, velocities, offsets)
    np.testing.assert_array_equal(got.track, t)
    np.testing.assert_array_equal(got.detection, i)
    np.testing.assert_allclose(got.d2, d2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.log_likelihood, ll, rtol=1e-9)
    assert {(k, k) for k in range(T)} <= set(zip(got.track.tolist(), got.detection.tolist()))
    with pytest.raises(ValueError, match="velocities, offsets"):
        gate(predicted, S, detections, threshold=gamma, velocities=velocities)


@pytest.mark.parametrize("T, N", [(0, 5), (4, 0), (0, 0)])
def test_empty_inputs_give_an_empty_gate(T, N):
    rng = np.random.default_rng(0)
    got = gate(rng.normal(size=(T, 2)), np.tile(np.eye(2), (T, 1, 1)), rng.normal(size=(N, 2)), threshold=9.0)
    assert (got.tracks, got.detections, got.pairs) == (T, N, 0)
    assert got.track.shape == got.detection.shape == got.d2.shape == got.log_likelihood.shape == (0,)
    track_cluster, detection_cluster, count = clusters(got)
    assert count == T + N and track_cluster.shape == (T,) and detection_cluster.shape == (N,)


def test_far_away_detections_give_no_pair():
    got = gate(np.zeros((3, 2)), np.tile(np.eye(2), (3, 1, 1)), np.full((4, 2), 100.0), threshold=gate_threshold(0.999, 2))
    assert got.pairs == 0 and got.tracks == 3 and got.detections == 4


def test_gate_threshold_is_the_chi2_quantile():
    assert gate_threshold(0.99, 2) == pytest.approx(chi2.ppf(0.99, 2), rel=1e-15)
    assert gate_threshold(0.9, 3) == pytest.approx(6.251388631170325, rel=1e-12)
    for bad in (0.0, 1.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="probability"):
            gate_threshold(bad, 2)
    with pytest.raises(ValueError, match="m"):
        gate_threshold(0.9, 0)


def test_bad_inputs_are_named():
    z = np.zeros((2, 2))
    S = np.tile(np.eye(2), (2, 1, 1))
    with pytest.raises(ValueError, match="predicted"):
        gate(np.array([[0.0, np.nan], [0, 0]]), S, z, threshold=9.0)
    with pytest.raises(ValueError, match="detections"):
        gate(z, S, np.array([[np.inf, 0.0]]), threshold=9.0)
    with pytest.raises(ValueError, match="detections"):
        gate(z, S, np.zeros((3, 3)), threshold=9.0)
    with pytest.raises(ValueError, match="S"):
        gate(z, np.eye(2), z, threshold=9.0)
    not_definite = S.copy()
    not_definite[1] = [[1.0, 2.0], [2.0, 1.0]]
    with pytest.raises(ValueError, match=r"S\[1\] is not positive definite"):
        gate(z, not_definite, z, threshold=9.0)
    asymmetric = S.copy()
    asymmetric[0, 0, 1] = 0.5
    with pytest.raises(ValueError, match=r"S\[0\] is not symmetric"):
        gate(z, asymmetric, z, threshold=9.0)
    for bad in (0.0, -1.0, np.inf):
        with pytest.raises(ValueError, match="threshold"):
            gate(z, S, z, threshold=bad)


def test_gate_refuses_inconsistent_pairs():
    with pytest.raises(ValueError, match="sorted"):
        Gate(2, 2, [1, 0], [0, 0], [0.1, 0.2], [-1.0, -1.0])
    with pytest.raises(ValueError, match="detection"):
        Gate(2, 2, [0], [2], [0.1], [-1.0])
    with pytest.raises(ValueError, match="d2"):
        Gate(2, 2, [0, 1], [0, 0], [0.1], [-1.0, -1.0])


def test_clusters_of_a_hand_example():
    # tracks 0, 1 share detection 1 (with 0 and 2 beside); track 2 alone with detection 4; track 3 gates nothing;
    # detection 3 is gated by nobody
    pairs = [(0, 0), (0, 1), (1, 1), (1, 2), (2, 4)]
    t, i = map(np.array, zip(*pairs))
    g = Gate(4, 5, t, i, np.ones(5), np.zeros(5))
    track_cluster, detection_cluster, count = clusters(g)
    assert count == 4
    np.testing.assert_array_equal(track_cluster, [0, 0, 1, 2])
    np.testing.assert_array_equal(detection_cluster, [0, 0, 0, 3, 1])
    layout = cluster_layout(g)
    np.testing.assert_array_equal(layout.cluster_tracks, [2, 1, 1, 0])
    np.testing.assert_array_equal(layout.cluster_detections, [3, 1, 0, 1])
    tracks, detections, edges = layout.members(0)
    np.testing.assert_array_equal(tracks, [0, 1])
    np.testing.assert_array_equal(detections, [0, 1, 2])
    np.testing.assert_array_equal(edges, [0, 1, 2, 3])


def test_clusters_of_a_chain_join_everything():
    """Track k gates detections k and k + 1: one cluster holding all tracks and detections."""
    T = 50
    t = np.repeat(np.arange(T), 2)
    i = t + np.tile([0, 1], T)
    track_cluster, detection_cluster, count = clusters(Gate(T, T + 1, t, i, np.ones(2 * T), np.zeros(2 * T)))
    assert count == 1 and (track_cluster == 0).all() and (detection_cluster == 0).all()


@pytest.mark.parametrize("dense_pairs", [0, 10**9])
@pytest.mark.parametrize("m", [1, 2, 3])
def test_the_k_d_tree_and_the_all_pairs_search_find_the_same_pairs(monkeypatch, dense_pairs, m):
    """Both candidate searches (k-d trees beyond _DENSE_PAIRS track–detection pairs, every distance below) against
    the dense reference, on a scene large enough for several radius bands."""
    import hybridtrack.algorithms.multitarget.gating as gating

    monkeypatch.setattr(gating, "_DENSE_PAIRS", dense_pairs)
    rng = np.random.default_rng(40 + m)
    T, N = 120, 150
    predicted, detections = rng.uniform(-50, 50, (T, m)), rng.uniform(-50, 50, (N, m))
    S = random_covariances(rng, T, m, elongation=8.0) * rng.uniform(0.1, 20.0, (T, 1, 1))
    velocities, offsets = rng.normal(0, 1, (T, m)), rng.uniform(-2, 0, N)
    gamma = gate_threshold(0.99, m)
    got = gate(predicted, S, detections, threshold=gamma, velocities=velocities, offsets=offsets)
    t, i, d2, ll = dense(predicted, S, detections, gamma, velocities, offsets)
    assert got.pairs > 50
    np.testing.assert_array_equal(got.track, t)
    np.testing.assert_array_equal(got.detection, i)
    np.testing.assert_allclose(got.d2, d2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.log_likelihood, ll, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("small_graph", [0, 10**9])
@pytest.mark.parametrize("seed", range(4))
def test_clusters_by_label_propagation_and_by_scipy_agree(monkeypatch, small_graph, seed):
    """Both cluster searches against scipy's connected components of the same bipartite graph."""
    import scipy.sparse
    from scipy.sparse.csgraph import connected_components

    import hybridtrack.algorithms.multitarget.gating as gating

    monkeypatch.setattr(gating, "_SMALL_GRAPH", small_graph)
    rng = np.random.default_rng(seed)
    T, N = int(rng.integers(5, 300)), int(rng.integers(5, 300))
    key = np.unique(rng.integers(0, T, 2 * T) * N + rng.integers(0, N, 2 * T))
    t, i = key // N, key % N
    track_cluster, detection_cluster, count = clusters(Gate(T, N, t, i, np.ones(t.size), np.zeros(t.size)))
    graph = scipy.sparse.coo_matrix((np.ones(t.size), (t, T + i)), shape=(T + N, T + N))
    expected_count, expected = connected_components(graph, directed=False)
    assert count == expected_count
    np.testing.assert_array_equal(np.concatenate([track_cluster, detection_cluster]), expected)


@pytest.mark.parametrize("shifted", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_gate_and_cluster_layout_equal_the_numpy_ones(monkeypatch, shifted, seed):
    """numba's m = 2 all-pairs gate and cluster layout (_association_kernels) against the numpy code they replace,
    bit for bit: the same pairs, d², log-likelihoods, labels and orders."""
    import hybridtrack.algorithms.multitarget.gating as gating

    pytest.importorskip("numba")
    rng = np.random.default_rng(70 + seed)
    T, N = int(rng.integers(1, 40)), int(rng.integers(1, 60))
    predicted, detections = rng.uniform(-30, 30, (T, 2)), rng.uniform(-30, 30, (N, 2))
    S = random_covariances(rng, T, 2, elongation=4.0) * rng.uniform(1.0, 30.0, (T, 1, 1))
    moved = dict(velocities=rng.normal(0, 2, (T, 2)), offsets=rng.uniform(-3, 0, N)) if shifted else {}
    gamma = gate_threshold(0.999, 2)
    compiled = gate(predicted, S, detections, threshold=gamma, **moved)
    compiled_layout = cluster_layout(compiled)
    monkeypatch.setattr(gating, "NUMBA_AVAILABLE", False)
    reference = gate(predicted, S, detections, threshold=gamma, **moved)
    assert compiled.pairs == reference.pairs and reference.pairs > 0
    for name in ("track", "detection", "d2", "log_likelihood"):
        np.testing.assert_array_equal(getattr(compiled, name), getattr(reference, name), err_msg=name)
    reference_layout = cluster_layout(reference)
    assert compiled_layout.count == reference_layout.count
    for name in ("track_cluster", "detection_cluster", "edge_cluster", "edge_order", "edge_start", "track_order", "track_start"):
        np.testing.assert_array_equal(getattr(compiled_layout, name), getattr(reference_layout, name), err_msg=name)
    np.testing.assert_array_equal(compiled_layout.detection_order, reference_layout.detection_order)
    np.testing.assert_array_equal(compiled_layout.detection_start, reference_layout.detection_start)
