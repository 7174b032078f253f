"""Exact JPDA (hybridtrack.algorithms.multitarget.jpda) against brute-force enumeration of the joint events, both
hypothesis-net implementations and orientations, a dense cluster, and Stone Soup's JPDA on one small scene."""

import math
import time

import numpy as np
import pytest

import hybridtrack.algorithms.multitarget.jpda as jpda_module
from hybridtrack.algorithms.multitarget.gating import Gate, clusters, gate, gate_threshold
from hybridtrack.algorithms.multitarget.jpda import jpda


def brute_force(g: Gate, scores, miss):
    """β (E,), β_miss (T,) by enumerating every joint event, weights exp(Σ s + Σ miss) in the log domain."""
    options = [[-1, *np.flatnonzero(g.track == t).tolist()] for t in range(g.tracks)]
    events = []

    def extend(t, used, chosen):
        if t == g.tracks:
            events.append(list(chosen))
            return
        for e in options[t]:
            if e >= 0 and g.detection[e] in used:
                continue
            extend(t + 1, used | ({int(g.detection[e])} if e >= 0 else set()), chosen + [e])

    extend(0, frozenset(), [])
    log_w = np.array([sum(scores[e] if e >= 0 else miss[t] for t, e in enumerate(ev)) for ev in events])
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    beta, beta_miss = np.zeros(g.pairs), np.zeros(g.tracks)
    for ev, p in zip(events, w):
        for t, e in enumerate(ev):
            if e >= 0:
                beta[e] += p
            else:
                beta_miss[t] += p
    return beta, beta_miss


def random_scene(seed, T=None, N=None, spread=10.0, scale=3.0):
    rng = np.random.default_rng(seed)
    T = int(rng.integers(2, 7)) if T is None else T
    N = int(rng.integers(2, 8)) if N is None else N
    predicted = rng.uniform(0, spread, (T, 2))
    detections = rng.uniform(0, spread, (N, 2))
    A = rng.normal(size=(T, 2, 2))
    S = 3.0 * (A @ A.transpose(0, 2, 1) + 0.5 * np.eye(2))
    g = gate(predicted, S, detections, threshold=gate_threshold(0.99, 2))
    return g, rng.normal(0.0, scale, g.pairs), rng.normal(0.0, 1.0, T)


def assert_rows_sum_to_one(g, beta, beta_miss):
    np.testing.assert_allclose(np.bincount(g.track, weights=beta, minlength=g.tracks) + beta_miss, 1.0, atol=1e-12)


@pytest.mark.parametrize("small_net", [0, 10**9], ids=["numpy_net", "python_net"])
@pytest.mark.parametrize("seed", range(12))
def test_jpda_equals_brute_force(seed, small_net, monkeypatch):
    monkeypatch.setattr(jpda_module, "SMALL_NET", small_net)
    g, scores, miss = random_scene(seed, spread=8.0)
    beta, beta_miss = jpda(g, scores, miss_scores=miss)
    expected, expected_miss = brute_force(g, scores, miss)
    np.testing.assert_allclose(beta, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(beta_miss, expected_miss, rtol=0, atol=1e-12)
    assert_rows_sum_to_one(g, beta, beta_miss)


@pytest.mark.parametrize("seed", range(4))
def test_scores_of_hundreds(seed):
    g, scores, miss = random_scene(seed, spread=6.0, scale=150.0)
    beta, beta_miss = jpda(g, scores, miss_scores=miss * 100)
    expected, expected_miss = brute_force(g, scores, miss * 100)
    np.testing.assert_allclose(beta, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(beta_miss, expected_miss, rtol=0, atol=1e-12)
    assert np.isfinite(beta).all() and np.isfinite(beta_miss).all()


def net_marginals(implementation, tracks_first, row, col, gain, Tc, Nc, ordering="greedy"):
    """One cluster through one net implementation, one orientation (items = tracks or detections) and one item
    order (the net is exact in any order)."""
    item, partner, n_items, n_partners = (row, col, Tc, Nc) if tracks_first else (col, row, Nc, Tc)
    if ordering == "greedy":
        order = jpda_module._greedy_order(jpda_module._partner_masks(item, partner, n_items), n_partners)
    elif ordering == "bandwidth":
        order = jpda_module._bandwidth_order(item, partner, n_items, n_partners)
    else:
        order = np.random.default_rng(len(gain)).permutation(n_items).tolist()
    assert sorted(order) == list(range(n_items))
    if implementation == "python":
        edge, none, free = jpda_module._small_net(item, partner, gain, n_items, n_partners, order, not tracks_first, 10**9, "")
    else:
        net = jpda_module._Net(item, partner, gain, n_items, n_partners, order)
        net.forward(10**9, "")
        edge, none, free = net.marginals(partner_free=not tracks_first)
    return edge, none if tracks_first else free


@pytest.mark.parametrize("ordering", ["greedy", "bandwidth", "random"])
@pytest.mark.parametrize("implementation", ["numpy", "python"])
@pytest.mark.parametrize("tracks_first", [True, False], ids=["tracks_as_items", "detections_as_items"])
@pytest.mark.parametrize("seed", range(2))
def test_both_orientations_of_the_net(seed, tracks_first, implementation, ordering):
    g, scores, miss = random_scene(seed + 100, T=5, N=6, spread=5.0)
    expected, expected_miss = brute_force(g, scores, miss)
    keep = np.unique(g.track)  # tracks gating something: their marginals come from the net
    row = np.searchsorted(keep, g.track)
    gain = scores - miss[g.track]
    edge, missed = net_marginals(implementation, tracks_first, row, g.detection, gain, keep.size, g.detections, ordering)
    np.testing.assert_allclose(edge, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(missed, expected_miss[keep], rtol=0, atol=1e-12)


def test_net_keys_wider_than_one_word():
    """Two tracks gating the same 70 detections, tracks as items: a frontier of 70 detections (two 64-bit words)."""
    rng = np.random.default_rng(3)
    N = 70
    g = Gate(2, N, np.repeat([0, 1], N), np.tile(np.arange(N), 2), np.zeros(2 * N), np.zeros(2 * N))
    scores, miss = rng.normal(0, 2, 2 * N), np.array([0.3, -0.2])
    expected, expected_miss = brute_force(g, scores, miss)
    row, col, gain = g.track, g.detection, scores - miss[g.track]
    net = jpda_module._Net(row, col, gain, 2, N, [0, 1])
    assert net.words == 2
    for implementation in ("numpy", "python"):
        edge, missed = net_marginals(implementation, True, row, col, gain, 2, N)
        np.testing.assert_allclose(edge, expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(missed, expected_miss, rtol=0, atol=1e-12)
    beta, beta_miss = jpda(g, scores, miss_scores=miss)
    np.testing.assert_allclose(beta, expected, rtol=0, atol=1e-12)


def test_trivial_clusters_closed_forms():
    # t0 alone with detections 0, 1; tracks 1, 2 share detection 2 (t1 dominant: g = 40); t3 gates nothing
    g = Gate(4, 4, [0, 0, 1, 2], [0, 1, 2, 2], np.zeros(4), np.zeros(4))
    s = np.array([1.0, -0.5, 40.0, 2.0])
    miss = np.array([0.2, 0.0, 0.5, -1.0])
    beta, beta_miss = jpda(g, s, miss_scores=miss)
    z0 = math.exp(0.2) + math.exp(1.0) + math.exp(-0.5)
    np.testing.assert_allclose(beta[:2], [math.exp(1.0) / z0, math.exp(-0.5) / z0], rtol=1e-14)
    assert beta_miss[0] == pytest.approx(math.exp(0.2) / z0, rel=1e-14)
    g1, g2 = 40.0, 2.0 - 0.5
    z = 1 + math.exp(g1) + math.exp(g2)
    np.testing.assert_allclose(beta[2:], [math.exp(g1) / z, math.exp(g2) / z], rtol=1e-14)
    # P(t1 missed) ≈ 1e-17: kept to full relative precision (no 1 − Σ β)
    assert beta_miss[1] == pytest.approx((1 + math.exp(g2)) / z, rel=1e-13)
    assert beta_miss[2] == pytest.approx((1 + math.exp(g1)) / z, rel=1e-13)
    assert beta_miss[3] == 1.0
    expected, expected_miss = brute_force(g, s, miss)
    np.testing.assert_allclose(beta, expected, atol=1e-12)
    assert_rows_sum_to_one(g, beta, beta_miss)


def test_small_miss_probabilities_keep_their_relative_precision():
    """A crowded cluster where every track surely took a detection: β_miss ~ e^{-60}, not 0 or negative."""
    g, scores, _ = random_scene(4, T=4, N=6, spread=3.0)
    scores = scores + 60.0
    track_cluster, _, _ = clusters(g)
    assert (track_cluster == 0).all()
    beta, beta_miss = jpda(g, scores, miss_scores=np.zeros(g.tracks))
    _, expected_miss = brute_force(g, scores, np.zeros(g.tracks))
    assert (beta_miss > 0).all()
    np.testing.assert_allclose(beta_miss, expected_miss, rtol=1e-9)


def test_dense_cluster_of_12_tracks_and_20_detections():
    """Every track gates every detection.  The marginals do not depend on the order of the tracks."""
    rng = np.random.default_rng(5)
    T, N = 12, 20
    g = Gate(T, N, np.repeat(np.arange(T), N), np.tile(np.arange(N), T), np.zeros(T * N), np.zeros(T * N))
    scores, miss = rng.normal(0, 2, T * N), rng.normal(0, 1, T)
    start = time.perf_counter()
    beta, beta_miss = jpda(g, scores, miss_scores=miss)
    print(f"jpda on a dense cluster of {T} tracks × {N} detections: {time.perf_counter() - start:.3f} s")
    assert_rows_sum_to_one(g, beta, beta_miss)
    np.testing.assert_array_less(np.bincount(g.detection, weights=beta, minlength=N), 1 + 1e-12)
    permutation = rng.permutation(T)  # track k of the permuted gate is track permutation[k]
    s2 = scores.reshape(T, N)[permutation].reshape(-1)
    beta2, beta_miss2 = jpda(g, s2, miss_scores=miss[permutation])
    np.testing.assert_allclose(beta2.reshape(T, N), beta.reshape(T, N)[permutation], atol=1e-12)
    np.testing.assert_allclose(beta_miss2, beta_miss[permutation], atol=1e-12)


def test_too_large_a_net_is_refused_with_the_cluster_size():
    T, N = 12, 20
    g = Gate(T, N, np.repeat(np.arange(T), N), np.tile(np.arange(N), T), np.zeros(T * N), np.zeros(T * N))
    with pytest.raises(ValueError, match="12 tracks × 20 detections"):
        jpda(g, np.zeros(T * N), max_hypotheses=1000)


def test_empty_and_bad_inputs():
    beta, beta_miss = jpda(Gate.empty(3, 2), [])
    assert beta.shape == (0,) and beta_miss.tolist() == [1.0, 1.0, 1.0]
    g, scores, miss = random_scene(0)
    with pytest.raises(ValueError, match="scores"):
        jpda(g, scores[:-1])
    with pytest.raises(ValueError, match="miss_scores"):
        jpda(g, scores, miss_scores=np.full(g.tracks, np.inf))
    with pytest.raises(ValueError, match="max_hypotheses"):
        jpda(g, scores, max_hypotheses=0)


def test_stone_soup_jpda_marginals():
    """Three crossing tracks and five detections through Stone Soup 1.9.1's exhaustive JPDA (PDAHypothesiser:
    missed 1 − P_D P_G, detection P_D N(z; ẑ, S) / λ, gated at the χ² quantile of P_G) and through ours with
    s = ln(P_D N / (λ (1 − P_D P_G))) on ẑ, S computed here from the same models."""
    pytest.importorskip("stonesoup")
    from datetime import datetime, timedelta

    from stonesoup.dataassociator.probability import JPDA
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.updater.kalman import KalmanUpdater

    q, sigma, dt = 0.5, 3.0, 1.0
    PD, PG, lam = 0.9, 0.99, 1e-3
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    measurement = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * sigma**2)
    t0 = datetime(2024, 1, 1)
    means = np.array([[0.0, 5.0, 0.0, 1.0], [12.0, -5.0, 1.0, 0.5], [5.0, 0.0, 8.0, -4.0]])
    P = np.diag([25.0, 4.0, 25.0, 4.0])
    tracks = [Track([GaussianState(m.reshape(-1, 1), P, timestamp=t0)]) for m in means]
    z = np.array([[6.0, 1.5], [5.0, 2.5], [9.0, 3.0], [4.0, -1.0], [30.0, 30.0]])
    detections = {Detection(v.reshape(-1, 1), timestamp=t0 + timedelta(seconds=dt), measurement_model=measurement) for v in z}
    ordered = sorted(detections, key=lambda d: tuple(d.state_vector.ravel()))
    hypothesiser = PDAHypothesiser(KalmanPredictor(transition), KalmanUpdater(measurement), lam, prob_detect=PD, prob_gate=PG)
    result = JPDA(hypothesiser).associate(tracks, detections, t0 + timedelta(seconds=dt))

    F1 = np.array([[1.0, dt], [0.0, 1.0]])
    Q1 = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    F, Q = np.kron(np.eye(2), F1), np.kron(np.eye(2), Q1)
    H = np.zeros((2, 4))
    H[0, 0] = H[1, 2] = 1.0
    x = means @ F.T
    Pp = F @ P @ F.T + Q
    S = np.tile(H @ Pp @ H.T + sigma**2 * np.eye(2), (3, 1, 1))
    zs = np.array([d.state_vector.ravel() for d in ordered])
    g = gate(x @ H.T, S, zs, threshold=gate_threshold(PG, 2))
    s = math.log(PD) + g.log_likelihood - math.log(lam) - math.log(1 - PD * PG)
    beta, beta_miss = jpda(g, s)
    track_cluster, _, _ = clusters(g)
    assert (track_cluster == track_cluster[0]).all()  # one cluster of the three tracks
    for t, track in enumerate(tracks):
        theirs = {}
        for hypothesis in result[track]:
            if hypothesis:
                theirs[ordered.index(hypothesis.measurement)] = float(hypothesis.probability)
            else:
                assert float(hypothesis.probability) == pytest.approx(beta_miss[t], abs=1e-9)
        ours = {int(i): float(b) for i, b in zip(g.detection[g.track == t], beta[g.track == t])}
        assert set(ours) == {i for i, p in theirs.items() if p > 0}
        for i, p in ours.items():
            assert theirs[i] == pytest.approx(p, abs=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_the_compiled_simple_clusters_equal_the_numpy_ones(seed, monkeypatch):
    """The one-track and one-detection clusters in numba (_association_kernels.simple_marginals) against the numpy
    code, on sparse scenes with many of both (and a few larger clusters), to rounding."""
    import hybridtrack.algorithms.multitarget.gating as gating

    pytest.importorskip("numba")
    g, scores, miss = random_scene(100 + seed, T=150, N=150, spread=200.0, scale=20.0)
    layout = gating.cluster_layout(g)
    Tc, Nc = layout.cluster_tracks, layout.cluster_detections
    assert ((Tc == 1) & (Nc >= 1)).sum() > 20 and ((Tc >= 2) & (Nc == 1)).sum() >= 3 and ((Tc >= 2) & (Nc >= 2)).sum() > 5
    compiled = jpda(g, scores, miss_scores=miss)
    monkeypatch.setattr(gating, "NUMBA_AVAILABLE", False)
    reference = jpda(g, scores, miss_scores=miss)
    np.testing.assert_allclose(compiled[0], reference[0], rtol=1e-14, atol=0)
    np.testing.assert_allclose(compiled[1], reference[1], rtol=1e-14, atol=0)
