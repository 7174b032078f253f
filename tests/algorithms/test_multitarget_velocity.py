"""Detections that report a velocity (AIS course and speed): the joint gate picks the detection whose velocity agrees,
the reported velocity starts and updates a track, duplicate tracks of one object are deleted, and bad input is named."""

import numpy as np
import pytest

from hybridtrack import MultipleModelEstimator
from hybridtrack.algorithms.multitarget.management import MofN
from hybridtrack.algorithms.multitarget.tracker import MultiTargetTracker
from hybridtrack.core.plugins import resolve
from hybridtrack.engine.detections import Detections

SIGMA = 10.0
VELOCITY = (10.0, 0.0)  # m/s east


def _estimator(velocity=True, second=None):
    sensors = [resolve("sensor", ("position", {"noise_cov": SIGMA**2 * np.eye(2)}))]
    if velocity:
        sensors.append(resolve("sensor", second or ("velocity", {"speed_sigma": 0.5, "course_sigma": np.radians(5.0)})))
    return MultipleModelEstimator([("straight", {"noise_density": 0.1})], [[1.0]], sensors=sensors)


def _target_with_decoys(scans=40, seed=1):
    """One target moving east at 10 m/s, seen every 1 s scan with σ = 10 m and its reported velocity, and in each
    scan one decoy 5 m from its true position (nearer the track than its own detection, ≈ 14 m on average)
    reporting the opposite velocity.  Returns the detections and the rows of the target's own."""
    rng = np.random.default_rng(seed)
    t = np.arange(scans, dtype=float)
    truth = np.column_stack([1000.0 + VELOCITY[0] * t, 2000.0 + VELOCITY[1] * t])
    own = truth + SIGMA * rng.standard_normal(truth.shape)
    angle = rng.uniform(0, 2 * np.pi, scans)
    decoy = truth + 5.0 * np.column_stack([np.cos(angle), np.sin(angle)])
    v_own = np.array(VELOCITY) + 0.5 * rng.standard_normal((scans, 2))
    v_decoy = -np.array(VELOCITY) + 0.5 * rng.standard_normal((scans, 2))
    times = np.repeat(t, 2)
    z = np.empty((2 * scans, 2))
    z[0::2], z[1::2] = own, decoy
    v = np.empty((2 * scans, 2))
    v[0::2], v[1::2] = v_own, v_decoy
    detections = Detections.from_times(times, z, scan=np.repeat(np.arange(scans), 2), velocity=v)
    return detections, detections.z, truth


def _own_share(result, detections, truth):
    """Of the detections the longest track took, the share that are the target's own (farther than 5 m from the truth
    at that scan: the decoys are exactly 5 m away)."""
    history = max(result.tracks, key=lambda h: h.detections.size)
    taken = history.detections
    miss = np.linalg.norm(detections.z[taken] - truth[detections.scan[taken]], axis=1)
    return float(np.mean(np.abs(miss - 5.0) > 1e-6)), history


def test_the_reported_velocity_picks_the_targets_own_detection():
    detections, _, truth = _target_with_decoys()
    options = dict(clutter_density=1e-6, management=MofN(3, 4, 3), max_speed=30.0)
    with_velocity = MultiTargetTracker(_estimator(), **options).run(detections)
    share, history = _own_share(with_velocity, detections, truth)
    assert share >= 0.95
    assert history.detections.size >= 35
    # the same detections without their velocities: the nearer decoy wins most scans
    positions_only = Detections(detections.scan_times, detections.scan, detections.times, detections.z)
    share_positions, _ = _own_share(MultiTargetTracker(_estimator(False), **options).run(positions_only), detections, truth)
    assert share_positions < 0.6
    # the estimated velocity follows the reported one, not the decoys' opposite
    rows = with_velocity.track_id == history.id
    vx = with_velocity.means[rows, with_velocity.layout.index("vx")]
    assert np.all(np.abs(vx[2:] - VELOCITY[0]) < 1.5)


def test_a_new_track_starts_from_the_reported_velocity():
    """Two reports 100 s apart of a ship moored (speed 0) and a neighbour 60 m away: velocity-consistent pairing
    joins each ship's own reports (not one ship's first with the other's second), and the tracks start at rest."""
    t = np.array([0.0, 1.0, 100.0, 101.0, 200.0, 201.0, 300.0, 301.0])
    a, b = np.array([0.0, 0.0]), np.array([60.0, 0.0])
    rng = np.random.default_rng(4)
    z = np.array([a, b] * 4) + 1.0 * rng.standard_normal((8, 2))
    v = np.zeros((8, 2))
    detections = Detections.from_times(t, z, scan_window=10.0, velocity=v)
    tracker = MultiTargetTracker(_estimator(), clutter_density=1e-9, management=MofN(2, 30, 60), max_speed=30.0, seed_window=150.0)
    result = tracker.run(detections)
    assert len(result.tracks) == 2
    for history in result.tracks:
        own = detections.z[history.detections]
        assert np.ptp(own[:, 0]) < 10.0  # every report of one ship
        rows = result.track_id == history.id
        speed = np.hypot(result.means[rows, result.layout.index("vx")], result.means[rows, result.layout.index("vy")])
        assert np.all(speed < 0.5)


def _one_object_reporting_four_times_a_scan(scans=30, seed=2):
    rng = np.random.default_rng(seed)
    t = np.repeat(np.arange(scans) * 10.0, 4) + np.tile([0.0, 2.5, 5.0, 7.5], scans)
    truth = np.column_stack([VELOCITY[0] * t, VELOCITY[1] * t])
    z = truth + SIGMA * rng.standard_normal(truth.shape)
    v = np.array(VELOCITY) + 0.5 * rng.standard_normal(truth.shape)
    return Detections.from_times(t, z, scan_window=10.0, velocity=v)


@pytest.mark.parametrize("velocity", [True, False])
def test_duplicate_tracks_of_one_object_are_deleted(velocity):
    """One ship reporting four times in each 10 s scan: its first four reports pair with its next four and start four
    tracks at once, each then taking one report per round; with duplicate_probability the later three are deleted
    and the one left takes every report (with and without reported velocity)."""
    detections = _one_object_reporting_four_times_a_scan()
    if not velocity:
        detections = Detections(detections.scan_times, detections.scan, detections.times, detections.z)
    options = dict(clutter_density=1e-9, management=MofN(2, 4, 6), max_speed=30.0, updates_per_scan=4)
    plain = MultiTargetTracker(_estimator(velocity), **options).run(detections)
    assert len(plain.tracks) == 4  # the duplicates this option is for
    cleaned = MultiTargetTracker(_estimator(velocity), **options, duplicate_probability=0.9, duplicate_scans=3).run(detections)
    (history,) = cleaned.tracks
    assert history.deleted is None
    assert history.detections.size >= detections.size - 8  # all but the first scans' reports


def test_bad_velocity_input_is_named():
    detections = _one_object_reporting_four_times_a_scan(5)
    positions_only = Detections(detections.scan_times, detections.scan, detections.times, detections.z)
    with pytest.raises(ValueError, match="measures the velocity, the detections report none"):
        MultiTargetTracker(_estimator(), clutter_density=1e-9).run(positions_only)
    with pytest.raises(ValueError, match="second sensor"):
        MultiTargetTracker(_estimator(second=("position", {"noise_cov": np.eye(2), "name": "second_position"})), clutter_density=1e-9)
    with pytest.raises(ValueError, match="duplicate_probability"):
        MultiTargetTracker(_estimator(), duplicate_probability=1.5)
    with pytest.raises(ValueError, match=r"velocity: expected shape \(4, 2\)"):
        Detections(np.array([0.0]), np.zeros(4, dtype=int), np.zeros(4), np.zeros((4, 2)), velocity=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="velocity"):
        Detections.from_times(np.zeros(4), np.zeros((4, 2)), scan_window=1.0, velocity=np.zeros((4, 3)))


def test_a_quiet_moored_ship_beside_a_busy_one_gets_its_own_track():
    """Ship A moored, reporting every 6 s (some scans two reports); ship B moored 100 m away, reporting every 180 s,
    both at speed 0, tracked by the IMM of straight motion and stop.  B's reports wait minutes for their second
    point; A's track, whose velocity the stop mode leaves uncertain after a scan's second report, retrodicted minutes
    back along that velocity would explain them away (B then starts late, in pieces); retrodicted along the velocity
    both report, B's reports are 100 m from A's and B gets one track with all of them."""
    rng = np.random.default_rng(7)
    t_a = np.arange(0.0, 1800.0, 6.0) + 1.0
    t_b = np.arange(0.0, 1800.0, 180.0) + 7.0
    z = np.vstack([np.tile([1000.0, 1000.0], (t_a.size, 1)), np.tile([1100.0, 1000.0], (t_b.size, 1))])
    z = z + 2.0 * rng.standard_normal(z.shape)
    times = np.concatenate([t_a, t_b])
    detections = Detections.from_times(times, z, scan_window=10.0, velocity=np.zeros((times.size, 2)))
    sensors = [
        resolve("sensor", ("position", {"noise_cov": SIGMA**2 * np.eye(2)})),
        resolve("sensor", ("velocity", {"speed_sigma": 0.5, "course_sigma": np.radians(10.0)})),
    ]
    models = [("straight", {"noise_density": 0.001}), ("stop", {"noise_density": 0.01})]
    estimator = MultipleModelEstimator(models, sojourn=[120.0, 3600.0], sensors=sensors)
    tracker = MultiTargetTracker(
        estimator,
        clutter_density=1e-9,
        detection_probability=0.5,
        management=MofN(2, 30, 60, max_coast=600.0),
        seed_window=600.0,
        updates_per_scan=2,
        duplicate_probability=0.9,
    )
    result = tracker.run(detections)
    assert len(result.tracks) == 2
    b = min(result.tracks, key=lambda h: h.detections.size)
    assert np.all(np.abs(detections.z[b.detections, 0] - 1100.0) < 10.0)
    assert b.detections.size == t_b.size


def test_a_ship_heard_again_after_a_silence_gets_its_id_back():
    """One ship at 5 m/s east, silent for 900 s (its track deleted after max_coast = 300 s), then heard again where it
    should be: with reacquire_window its new track takes the old id (one track, every report); without, two tracks.
    A second ship 20 km away, reporting all the while, keeps an id of its own."""
    rng = np.random.default_rng(8)
    t = np.concatenate([np.arange(0.0, 300.0, 10.0), np.arange(1200.0, 1500.0, 10.0)])
    truth = np.column_stack([5.0 * t, np.zeros_like(t)])
    other_t = np.arange(5.0, 1500.0, 10.0)
    other = np.column_stack([np.full(other_t.size, 20_000.0), -3.0 * other_t])
    times = np.concatenate([t, other_t])
    z = np.vstack([truth, other]) + SIGMA * rng.standard_normal((times.size, 2))
    v = np.vstack([np.tile([5.0, 0.0], (t.size, 1)), np.tile([0.0, -3.0], (other_t.size, 1))]) + 0.3 * rng.standard_normal((times.size, 2))
    detections = Detections.from_times(times, z, scan_window=10.0, velocity=v)
    options = dict(clutter_density=1e-9, management=MofN(2, 4, 30, max_coast=300.0), max_speed=30.0)
    apart = MultiTargetTracker(_estimator(), **options).run(detections)
    assert len(apart.tracks) == 3
    joined = MultiTargetTracker(_estimator(), **options, reacquire_window=3600.0).run(detections)
    assert len(joined.tracks) == 2
    first = min(joined.tracks, key=lambda h: h.id)
    assert first.deleted is None and first.detections.size >= t.size - 4  # the two start points of the second part
    assert np.all(detections.z[first.detections, 0] < 10_000.0)
    with pytest.raises(ValueError, match="reacquire_window"):
        MultiTargetTracker(_estimator(), reacquire_window=-1.0)


def test_a_further_report_of_the_scan_takes_no_time_step():
    """A moored ship reporting twice in each 10 s scan (2 s apart, speed 0): its second report of a scan updates the
    track at the scan's time without stepping the motion model, so the stop mode keeps the velocity its first update
    gave it (a 1 ms step would reset it to the walk's q/Δt = 10 (m/s)², and straight would win the mode) and the
    track is in stop; its position variance shrinks with each report."""
    rng = np.random.default_rng(8)
    scans = 30
    t = np.repeat(10.0 * np.arange(scans), 2) + np.tile([0.0, 2.0], scans)
    z = SIGMA * rng.standard_normal((2 * scans, 2)) + 5.0e5  # map-grid coordinates
    v = 0.1 * rng.standard_normal((2 * scans, 2))
    detections = Detections.from_times(t, z, scan_window=10.0, velocity=v)
    sensors = [
        resolve("sensor", ("position", {"noise_cov": SIGMA**2 * np.eye(2)})),
        resolve("sensor", ("velocity", {"speed_sigma": 0.5, "course_sigma": np.radians(10.0)})),
    ]
    models = [("straight", {"noise_density": 0.01}), ("stop", {"noise_density": 0.01})]
    estimator = MultipleModelEstimator(models, sojourn=[120.0, 3600.0], sensors=sensors)
    options = dict(clutter_density=1e-9, management=MofN(2, 30, 60), max_speed=30.0, updates_per_scan=2)
    result = MultiTargetTracker(estimator, **options, duplicate_probability=0.9, duplicate_scans=2).run(detections)
    assert len(result.tracks) == 1 and result.tracks[0].detections.size >= 2 * scans - 4
    assert np.mean(np.array(result.modes)[result.mode[5:]] == "stop") >= 0.9
    variance = result.position_covs[:, 0, 0]
    assert variance[-1] < 0.5 * SIGMA**2 / 2  # far below one report's share of two per scan
