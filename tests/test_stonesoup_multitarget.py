"""experiments/stonesoup_multitarget.py: Stone Soup 1.9.1's trackers on a tiny hand-made scene (issue 23, item 7c).

Three straight targets, no clutter, P_D = 1, 30 scans of 1 s, σ = 10 m: the Stone Soup GNN confirms each target
at its third detection (min_points = 3) and follows it; rows are one per scan per held track; ``max_scans``
keeps the first scans; JPDA's exhaustive enumeration and EHM give the same tracks (Stone Soup's EHM example).
"""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stonesoup")

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
SIGMA = 10.0
COMMON = {"sigma": SIGMA, "noise_density": 0.1, "detection_probability": 0.9, "clutter_density": 1e-8}


def load():
    spec = importlib.util.spec_from_file_location("_stonesoup_multitarget", EXPERIMENTS / "stonesoup_multitarget.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up while the module runs
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def stonesoup():
    return load()


def scene(scans=30, targets=3, seed=1):
    """Straight targets x(t) = x0 + v t, one detection each per scan (P_D = 1, no clutter), noise σ."""
    rng = np.random.default_rng(seed)
    times = np.arange(scans, dtype=float)
    start = np.array([[0.0, 0.0], [0.0, 1000.0], [500.0, -500.0]])[:targets]
    velocity = np.array([[10.0, 0.0], [10.0, -5.0], [0.0, 12.0]])[:targets]
    truth = start[None] + times[:, None, None] * velocity[None]  # (K, targets, 2)
    scan = np.repeat(np.arange(scans), targets)
    z = truth.reshape(-1, 2) + rng.normal(0.0, SIGMA, (scans * targets, 2))
    return times, scan, z, truth, velocity


@pytest.fixture(scope="module")
def gnn_run(stonesoup):
    times, scan, z, truth, velocity = scene()
    return stonesoup.run_stonesoup(times, scan, z, method="gnn", **COMMON), times, truth, velocity


def test_gnn_finds_the_targets_and_keeps_their_identities(gnn_run):
    run, times, truth, velocity = gnn_run
    assert run.tracks_created == 3 and run.detections == 90
    k = np.searchsorted(times, run.time)
    distance = np.hypot(truth[k, :, 0] - run.x[:, None], truth[k, :, 1] - run.y[:, None])  # (rows, targets)
    nearest = distance.argmin(axis=1)
    for track in range(3):  # each track follows one target all along, each target has its own track
        assert len(set(nearest[run.track_id == track])) == 1
    assert sorted(nearest[run.time == times[-1]]) == [0, 1, 2]
    error = distance.min(axis=1)
    assert error.max() < 4 * SIGMA  # confirmation from a zero-velocity prior: a few σ at first
    settled = run.time >= 10
    assert np.sqrt(np.mean(error[settled] ** 2)) < 1.5 * SIGMA
    target = nearest[settled]
    speed_error = np.hypot(run.vx[settled] - velocity[target, 0], run.vy[settled] - velocity[target, 1])
    assert np.median(speed_error) < 3.0


def test_rows_one_per_scan_per_track_held(gnn_run):
    run, times, _, _ = gnn_run
    assert {len(a) for a in (run.time, run.track_id, run.x, run.y, run.vx, run.vy)} == {84}
    assert run.track_id.dtype.kind == "i" and set(run.track_id) == {0, 1, 2}
    assert set(run.time) <= set(times)
    per_scan = np.array([np.sum(run.time == t) for t in times])
    np.testing.assert_array_equal(per_scan, [0, 0] + [3] * 28)  # confirmed at the 3rd detection (min_points = 3)
    pairs = list(zip(run.time, run.track_id))
    assert pairs == sorted(set(pairs))  # by scan then track id, no (scan, track) twice


def test_max_scans_keeps_the_first_scans(stonesoup, gnn_run):
    full, times, _, _ = gnn_run
    _, scan, z, _, _ = scene()
    part = stonesoup.run_stonesoup(times, scan, z, method="gnn", max_scans=10, **COMMON)
    assert part.detections == 30 and part.time.max() == times[9]
    head = full.time < times[10]
    for name in ("time", "track_id", "x", "y", "vx", "vy"):
        np.testing.assert_allclose(getattr(part, name), getattr(full, name)[head], rtol=0, atol=1e-9)
    more = stonesoup.run_stonesoup(times, scan, z, method="gnn", max_scans=100, **COMMON)
    assert more.detections == 90 and len(more.time) == len(full.time)


def test_empty_scans_are_steps_and_the_deleters_remove_a_vanished_target(stonesoup):
    times, scan, z, _, _ = scene()
    gone = (np.arange(scan.size) % 3 == 2) & (scan >= 15)  # the third target stops being detected at scan 15
    quiet = (scan >= 25) & (scan < 27)  # two empty scans
    keep = ~gone & ~quiet
    by_time = stonesoup.run_stonesoup(times, scan[keep], z[keep], method="gnn", deleter="time", time_since_update=3.0, **COMMON)
    per_scan = np.array([np.sum(by_time.time == t) for t in times])
    assert per_scan[14] == 3 and np.all(per_scan[19:25] == 2)  # last update at 14, deleted when 14 + 3 s is passed
    assert np.all(per_scan[25:27] == 2) and per_scan[-1] == 2  # empty scans: the tracks coast and stay rows
    assert by_time.detections == int(keep.sum())
    by_covariance = stonesoup.run_stonesoup(times, scan[keep], z[keep], method="gnn", covariance_threshold=300.0, **COMMON)
    per_scan = np.array([np.sum(by_covariance.time == t) for t in times])
    assert per_scan[14] == 3 and per_scan[-1] == 2 and by_covariance.tracks_created == 3


def test_jpda_exhaustive_and_ehm_agree_and_follow_the_targets(stonesoup):
    times, scan, z, truth, _ = scene(scans=12, targets=2, seed=2)
    exhaustive = stonesoup.run_stonesoup(times, scan, z, method="jpda", **COMMON)
    ehm = stonesoup.run_stonesoup(times, scan, z, method="jpda_ehm", **COMMON)
    for name in ("time", "track_id", "x", "y", "vx", "vy"):
        np.testing.assert_allclose(getattr(ehm, name), getattr(exhaustive, name), rtol=0, atol=1e-6)
    assert exhaustive.tracks_created == 2
    k = np.searchsorted(times, ehm.time)
    error = np.min(np.hypot(truth[k, :, 0] - ehm.x[:, None], truth[k, :, 1] - ehm.y[:, None]), axis=1)
    assert error.max() < 4 * SIGMA


def test_nearest_neighbour_runs_the_same_components(stonesoup):
    times, scan, z, _, _ = scene(scans=8)
    nn = stonesoup.run_stonesoup(times, scan, z, method="nn", **COMMON)
    gnn = stonesoup.run_stonesoup(times, scan, z, method="gnn", **COMMON)
    np.testing.assert_allclose(np.column_stack([nn.x, nn.y]), np.column_stack([gnn.x, gnn.y]), atol=1e-9)  # well-separated: no conflict


@pytest.mark.parametrize(
    ("change", "error", "match"),
    [
        ({"method": "mht"}, ValueError, "method"),
        ({"sigma": 0.0}, ValueError, "sigma"),
        ({"detection_probability": 1.5}, ValueError, "detection_probability"),
        ({"method": "jpda", "clutter_density": 0.0}, ValueError, "clutter_density"),
        ({"max_scans": 0}, ValueError, "max_scans"),
        ({"max_scans": 2.5}, TypeError, "max_scans"),
        ({"gate": 3}, TypeError, "unknown option"),
        ({"deleter": "score"}, ValueError, "deleter"),
        ({"min_points": 0}, ValueError, "min_points"),
    ],
)
def test_bad_parameters_are_named(stonesoup, change, error, match):
    times, scan, z, _, _ = scene(scans=3)
    arguments = {"method": "gnn", **COMMON, **change}
    with pytest.raises(error, match=match):
        stonesoup.run_stonesoup(times, scan, z, **arguments)


@pytest.mark.parametrize(
    ("which", "match"),
    [("times", "scan_times"), ("scan_range", "scan"), ("scan_float", "scan"), ("z_shape", "z"), ("z_nan", "z")],
)
def test_bad_arrays_are_named(stonesoup, which, match):
    times, scan, z, _, _ = scene(scans=3)
    if which == "times":
        times = times[::-1]
    elif which == "scan_range":
        scan = scan + 1
    elif which == "scan_float":
        scan = scan.astype(float)
    elif which == "z_shape":
        z = z[:, :1]
    else:
        z = z.copy()
        z[0, 0] = np.nan
    with pytest.raises(ValueError, match=match):
        stonesoup.run_stonesoup(times, scan, z, method="gnn", **COMMON)


def test_the_multitarget_experiment_quick(tmp_path):
    """experiments/multitarget.py --quick: the issue's JSON layout, hybridtrack rows only (Stone Soup is slow)."""
    spec = importlib.util.spec_from_file_location("_small_multitarget", EXPERIMENTS / "multitarget.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = tmp_path / "mt.json"
    rows = module.main(["--json", str(out), "--quick", "--stonesoup-scans", "10", "--no-stonesoup"])
    keys = {"dataset", "method", "library", "gospa", "gospa_localisation", "gospa_missed", "gospa_false", "id_switches"}
    keys |= {"tracks_created", "detections_per_s"}
    assert all(keys <= set(r) for r in rows) and json.loads(out.read_text()) == rows
    assert {r["dataset"] for r in rows} == {"crossing_20", "solent_first_10"}
    for r in rows:
        assert r["gospa"] == pytest.approx(r["gospa_localisation"] + r["gospa_missed"] + r["gospa_false"])
    crossing = [r for r in rows if r["dataset"] == "crossing_20"]
    assert all(r["gospa_false"] < 10 and r["tracks_created"] <= 22 for r in crossing)
