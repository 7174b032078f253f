"""The multi-target tracker against references: a lone target equals its filter run alone; a crossing scene is found."""

import numpy as np
import pytest

from hybridtrack import MultipleModelEstimator, gospa_over_time
from hybridtrack.algorithms.multitarget.management import MofN, TrackScore
from hybridtrack.algorithms.multitarget.tracker import MultiTargetTracker, collapse
from hybridtrack.core.plugins import resolve
from hybridtrack.engine.detections import Detections
from hybridtrack.engine.scenes import crossing_scene
from hybridtrack.sdk.mixtures import moment_match

SIGMA = 10.0


def _estimator(modes=False):
    sensor = resolve("sensor", ("position", {"noise_cov": SIGMA**2 * np.eye(2)}))
    if not modes:
        return MultipleModelEstimator([("straight", {"noise_density": 1.0})], [[1.0]], sensors=[sensor])
    models = [("straight", {"noise_density": 0.05}), ("coordinated_turn", {"noise_density": 0.05})]
    return MultipleModelEstimator(models, sojourn=30.0, sensors=[sensor], missing_variance={"omega": 1e-4})


def _line(scans=30, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(scans, dtype=float)
    truth = np.column_stack([1000.0 + 12.0 * t, 2000.0 - 5.0 * t])
    return t, truth + SIGMA * rng.standard_normal(truth.shape)


def test_a_lone_target_is_its_filter_run_alone():
    t, z = _line()
    detections = Detections.from_times(t, z, scan=np.arange(t.size))
    tracker = MultiTargetTracker(_estimator(), clutter_density=1e-8, management=MofN(3, 4, 3))
    result = tracker.run(detections)
    assert [h.id for h in result.tracks] == [1]
    history = result.tracks[0]
    np.testing.assert_array_equal(history.detections, np.arange(t.size))
    # the reference: the two-point start at scan 1, then the estimator's own steps with every later detection
    est = tracker.estimator
    means, covs = tracker._two_point(z[:1], t[:1], z[1:2], t[1:2], t[1])
    state = est.start(means, covs, np.full((1, 2), np.nan), prior_layout=("x", "vx", "y", "vy"))
    expected = []
    for k in range(2, t.size):
        state = est.step(state, z[k : k + 1], 1.0)
        expected.append(state.mean[0])
    first = int(np.flatnonzero(result.scan == result.scan.min())[0])
    shown = result.means[first:]
    np.testing.assert_allclose(shown, np.array(expected)[-shown.shape[0] :], rtol=0, atol=1e-9)
    assert result.scan.min() == 2  # confirmed at its third detection (3 of 4)


def test_collapse_is_the_moment_match_of_the_hypotheses():
    rng = np.random.default_rng(3)
    t, z = _line(5)
    est = _estimator()
    state = est.start(np.array([[1000.0, 12.0, 2000.0, -5.0]]), np.diag([100.0, 4.0, 100.0, 4.0])[None], np.full((1, 2), np.nan))
    from hybridtrack.algorithms.multitarget.tracker import join_rows

    missed = est.step(state, np.full((1, 2), np.nan), 1.0)
    hits = [est.step(state, z[1:2] + rng.normal(0, 5, 2), 1.0) for _ in range(3)]
    hypotheses = join_rows([missed, *hits])
    weights = np.array([0.1, 0.5, 0.3, 0.1])
    merged = collapse(hypotheses, np.zeros(4, dtype=np.intp), np.log(weights), 1)
    mean, cov = moment_match(weights, hypotheses.mean, hypotheses.cov)
    np.testing.assert_allclose(merged.mean[0], mean, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(merged.cov[0], cov, rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize(("association", "modes"), [("gnn", False), ("jpda", False), ("jpda", True)])
def test_the_crossing_scene_is_tracked(association, modes):
    detections = crossing_scene(seed=11)
    tracker = MultiTargetTracker(_estimator(modes), association=association, clutter_density=10 / 25e6, max_speed=40.0)
    result = tracker.run(detections)
    truth = detections.truth
    series = gospa_over_time(truth.times, truth.ids, truth.positions, result.time, result.track_id, result.positions(), c=100.0)
    quality = series.track_quality()
    assert 20 <= len(result.tracks) <= 24
    assert series.distance.mean() < 200.0  # c = 100 m, 20 targets: ≈ 7 m each, a few scans to confirm
    assert series.false.mean() < 10.0
    assert quality.id_switches <= 4
    assert len(quality.lost_truths) == 0


def test_a_vanished_target_is_deleted_and_rows_are_per_scan():
    t, z = _line(20)
    keep = t < 12
    detections = Detections.from_times(t[keep], z[keep], scan=np.arange(keep.sum()))
    # scans 12…19 without detections: a scan column with no row for them does not exist, so append clutter far away
    far = np.column_stack([np.full(8, 1e6), np.linspace(0, 1e5, 8)])
    detections = Detections.from_times(np.concatenate([t[keep], t[~keep]]), np.vstack([z[keep], far]), scan=np.arange(20))
    tracker = MultiTargetTracker(_estimator(), clutter_density=1e-8, management=MofN(3, 4, 3), initiation="two_point")
    result = tracker.run(detections)
    (history,) = [h for h in result.tracks if h.id == 1]
    assert history.deleted == pytest.approx(14.0)  # three misses in a row: scans 12, 13, 14
    rows = result.track_id == 1
    assert np.array_equal(result.scan[rows], np.arange(2, 14))
    assert not result.hit[rows][-2:].any()


def test_score_management_confirms_and_bad_input_is_named():
    t, z = _line(15)
    detections = Detections.from_times(t, z, scan=np.arange(t.size))
    result = MultiTargetTracker(_estimator(), clutter_density=1e-8, management=TrackScore()).run(detections)
    assert len(result.tracks) == 1 and result.tracks[0].confirmed <= 3.0
    with pytest.raises(ValueError, match="association"):
        MultiTargetTracker(_estimator(), association="mht2")
    with pytest.raises(TypeError, match="estimator"):
        MultiTargetTracker("kalman")
    with pytest.raises(TypeError, match="Detections"):
        MultiTargetTracker(_estimator()).run(z)


def test_time_stamp_jitter_widens_the_gate_along_the_track():
    """A 155 m/s target whose reports carry a 3 s time-stamp error (≈ 465 m along the track, 5 m across): with the
    position sensor's time_jitter the gate, the start and the update use R + σ_t² v vᵀ and one track takes every
    report; with R alone the track is lost after its first reports."""
    rng = np.random.default_rng(5)
    t = np.arange(60) * 5.0
    v = np.array([150.0, 40.0])
    z = np.outer(t, v) + v * (3.0 * rng.standard_normal((t.size, 1))) + 5.0 * rng.standard_normal((t.size, 2))
    detections = Detections.from_times(t, z, scan=np.arange(t.size))
    found = {}
    for jitter in (0.0, 3.0):
        sensor = resolve("sensor", ("position", {"noise_cov": 25.0 * np.eye(2), "time_jitter": jitter}))
        estimator = MultipleModelEstimator([("straight", {"noise_density": 0.1})], [[1.0]], sensors=[sensor])
        tracker = MultiTargetTracker(estimator, clutter_density=1e-9, management=MofN(3, 4, 3), max_speed=300.0)
        found[jitter] = [h.detections.size for h in tracker.run(detections).tracks]
    assert found[3.0] == [t.size]
    assert max(found[0.0], default=0) < t.size // 2
