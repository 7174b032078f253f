"""Detections in scans and the truth table: grouping by window and by column (hand examples, boundaries, a brute-force
reference), order invariance, and the errors naming the field."""

import numpy as np
import pytest

from hybridtrack.engine.detections import Detections, Truth, group_scans


def detections(**changes):
    fields = dict(
        scan_times=[0.0, 1.0, 2.0, 3.0],
        scan=[0, 0, 2, 2, 2, 3],
        times=[0.0, 0.0, 1.5, 2.0, 2.0, 3.0],
        z=np.arange(12.0).reshape(6, 2),
        origin=[0, -1, 1, 0, -1, 1],
        truth=Truth([0.0, 1.0, 2.0, 2.0, 3.0], [0, 0, 0, 1, 1], np.zeros((5, 4)), ("x", "vx", "y", "vy")),
    )
    return Detections(**(fields | changes))


# --- the value types --------------------------------------------------------------------------------------------


def test_scans_counts_bounds_and_at_with_an_empty_scan():
    d = detections()
    assert (d.scans, d.size, d.measurement_dim) == (4, 6, 2)
    assert d.counts().tolist() == [2, 0, 3, 1]
    assert d.bounds() == [slice(0, 2), slice(2, 2), slice(2, 5), slice(5, 6)]
    times, z = d.at(2)
    assert times.tolist() == [1.5, 2.0, 2.0] and z.tolist() == [[4, 5], [6, 7], [8, 9]]
    assert d.at(1)[1].shape == (0, 2) and d.at(-1)[0].tolist() == [3.0]
    with pytest.raises(IndexError, match="scan 4 of 4"):
        d.at(4)


def test_arrays_are_read_only_copies():
    z = np.zeros((6, 2))
    d = detections(z=z)
    z[0, 0] = 5.0
    assert d.z[0, 0] == 0.0
    for array in (d.scan_times, d.scan, d.times, d.z, d.origin, d.truth.states, d.truth.ids):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1
    assert d.scan.dtype == np.intp and d.origin.dtype == np.intp


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(scan_times=[0.0, 1.0, 1.0, 3.0]), "scan_times: expected strictly increasing"),
        (dict(scan=[0, 0, 2, 1, 2, 3]), "scan: expected non-decreasing"),
        (dict(scan=[0, 0, 2, 2, 2, 4]), r"scan: expected scan indices 0 … 3"),
        (dict(scan=[0, 0, 2.5, 2, 2, 3]), "scan: expected integers, got 2.5 at index 2"),
        (dict(times=[0.0, 0.0, 1.5, 2.0, 2.5, 3.0]), "times: detection 4 at time 2.5 is later than the time 2 of its scan 2"),
        (dict(times=[0.0, 0.0, 1.5]), r"times: expected shape \(6,\)"),
        (dict(z=np.zeros((5, 2))), r"z: expected shape \(6, m\)"),
        (dict(z=np.where(np.eye(6, 2) == 1, np.nan, 0.0)), r"z: contains NaN or inf at index \(0, 0\)"),
        (dict(scan_times=[0.0, np.nan, 2.0, 3.0]), "scan_times: contains NaN"),
        (dict(origin=[0, -2, 1, 0, -1, 1]), "origin: expected object indices ≥ 0 or −1"),
        (dict(origin=[0, -1, 1]), r"origin: expected shape \(6,\)"),
        (dict(origin=[0, -1, 7, 0, -1, 1]), "origin: detection 2 names object 7, which is not in truth.ids"),
        (dict(truth="truth"), "truth: expected a Truth"),
    ],
)
def test_detections_errors_name_the_field(changes, message):
    with pytest.raises((ValueError, TypeError), match=message):
        detections(**changes)


def test_truth_positions_and_errors():
    truth = Truth([0.0, 0.0, 1.0], [0, 1, 0], [[1, 2, 3, 4, 5, 6]] * 3, ("x", "vx", "y", "vy", "z", "vz"))
    assert truth.positions.tolist() == [[1, 3, 5]] * 3 and truth.objects == 2 and truth.size == 3
    ids, states = truth.at(0.0)
    assert ids.tolist() == [0, 1] and states.shape == (2, 6)
    assert Truth([0.0], [3], [[7.0, 8.0]], ("y", "x")).positions.tolist() == [[8.0, 7.0]]
    with pytest.raises(ValueError, match="object 1 appears twice at time 0"):
        Truth([1.0, 0.0, 0.0], [0, 1, 1], np.zeros((3, 2)), ("x", "y"))
    with pytest.raises(ValueError, match=r"states: expected shape \(2, 2\)"):
        Truth([0.0, 1.0], [0, 0], np.zeros((2, 3)), ("x", "y"))
    with pytest.raises(ValueError, match="layout: expected the position components"):
        Truth([0.0], [0], np.zeros((1, 2)), ("x", "vx"))
    with pytest.raises(ValueError, match="ids: expected object indices ≥ 0"):
        Truth([0.0], [-1], np.zeros((1, 2)), ("x", "y"))
    with pytest.raises(ValueError, match="states: contains NaN"):
        Truth([0.0], [0], [[np.nan, 0.0]], ("x", "y"))


def test_head_keeps_the_first_scans_and_their_truth():
    d = detections().head(3)
    assert d.scans == 3 and d.size == 5 and d.origin.tolist() == [0, -1, 1, 0, -1]
    assert d.truth.times.tolist() == [0.0, 1.0, 2.0, 2.0]
    assert detections().head(10).size == 6 and detections().head(0).size == 0


# --- grouping by a time window ------------------------------------------------------------------------------------


def test_window_hand_example_with_boundaries():
    # windows [0, 10), [10, 20), [20, 30]: 9.99 before the boundary, 10 on it, 30 the latest time closing the last
    times = [3.0, 0.0, 9.99, 10.0, 25.0, 30.0]
    d = Detections.from_times(times, np.column_stack([times, times]), scan_window=10.0)
    assert d.scan_times.tolist() == [10.0, 20.0, 30.0]
    assert d.scan.tolist() == [0, 0, 0, 1, 2, 2]
    assert d.times.tolist() == [0.0, 3.0, 9.99, 10.0, 25.0, 30.0]
    assert d.z[:, 0].tolist() == d.times.tolist()


@pytest.mark.parametrize(
    ("times", "scan_times", "scan"),
    [
        ([0.0, 12.0], [10.0, 12.0], [0, 1]),  # the last window's time capped at the latest time stamp
        ([0.0, 35.0], [10.0, 35.0], [0, 1]),  # empty windows [10, 20), [20, 30) are no scans
        ([0.0, 10.0], [10.0], [0, 0]),  # the latest time on a window's start closes the window before
        ([100.5, 101.0, 110.5], [110.5], [0, 0, 0]),  # t0 = the earliest time
        ([5.0, 5.0], [5.0], [0, 0]),  # one time: one scan at that time
        ([0.0, 10.0, 10.0, 15.0], [10.0, 15.0], [0, 1, 1, 1]),
    ],
)
def test_window_boundaries(times, scan_times, scan):
    d = Detections.from_times(times, np.zeros((len(times), 2)), scan_window=10.0)
    assert d.scan_times.tolist() == scan_times and d.scan.tolist() == scan


def test_window_matches_a_brute_force_assignment():
    rng = np.random.default_rng(4)
    w, t0 = 0.1, 0.3
    times = t0 + np.round(rng.uniform(0, 5, 400), 1)  # many times on (rounded) window boundaries
    times[0] = t0
    grouping = group_scans(times, scan_window=w)
    ordered = times[grouping.order]
    latest = ordered.max()
    expected = []
    for t in ordered:  # the window k with t0 + k w ≤ t < t0 + (k+1) w, the boundaries computed as t0 + k * w
        k = 0
        while not (t0 + k * w <= t < t0 + (k + 1) * w):
            k += 1
        expected.append(k)
    expected = np.array(expected)
    if latest == t0 + expected[-1] * w and expected[-1] > 0:
        expected[ordered == latest] -= 1
    windows = np.unique(expected)
    assert np.array_equal(np.searchsorted(windows, expected), grouping.scan)
    assert np.array_equal(grouping.scan_times, np.minimum(t0 + (windows + 1) * w, latest))
    d = Detections.from_times(times, np.zeros((times.size, 2)), scan_window=w)
    assert np.all(d.times <= d.scan_times[d.scan]) and np.all(np.diff(d.scan_times) > 0)


def test_grouping_is_invariant_to_the_input_order():
    rng = np.random.default_rng(7)
    times = rng.uniform(0, 100, 300)
    z = rng.normal(size=(300, 2))
    origin = rng.integers(-1, 5, 300)
    first = Detections.from_times(times, z, scan_window=7.5, origin=origin)
    for _ in range(3):
        p = rng.permutation(300)
        other = Detections.from_times(times[p], z[p], scan_window=7.5, origin=origin[p])
        for name in ("scan_times", "scan", "times", "z", "origin"):
            assert np.array_equal(getattr(first, name), getattr(other, name)), name
    labels = np.floor(times / 10.0)
    by_label = Detections.from_times(times, z, scan=labels)
    p = rng.permutation(300)
    other = Detections.from_times(times[p], z[p], scan=labels[p])
    assert np.array_equal(by_label.z, other.z) and np.array_equal(by_label.scan, other.scan)


def test_ties_keep_the_input_order():
    d = Detections.from_times([1.0, 0.0, 1.0, 1.0], [[1, 0], [0, 0], [2, 0], [3, 0]], scan_window=5.0)
    assert d.z[:, 0].tolist() == [0, 1, 2, 3]


# --- grouping by a scan column ------------------------------------------------------------------------------------


def test_scan_column_hand_example():
    times = [4.0, 1.0, 5.0, 3.5, 9.0]
    labels = [2, 0, 2, 0, 7]
    d = Detections.from_times(times, np.column_stack([times, labels]), scan=labels, origin=[0, 1, -1, 1, 0])
    assert d.scan_times.tolist() == [3.5, 5.0, 9.0]  # the latest time of each scan
    assert d.scan.tolist() == [0, 0, 1, 1, 2]
    assert d.times.tolist() == [1.0, 3.5, 4.0, 5.0, 9.0]
    assert d.origin.tolist() == [1, 1, 0, -1, 0]


def test_scan_column_must_end_at_increasing_times():
    with pytest.raises(ValueError, match="scan: scan 1 ends at time 2, not after scan 0"):
        Detections.from_times([5.0, 2.0], np.zeros((2, 2)), scan=[0, 1])


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        (dict(), ValueError, "scan and scan_window: give exactly one"),
        (dict(scan_window=1.0, scan=[0, 0]), ValueError, "scan and scan_window: give exactly one"),
        (dict(scan_window=0.0), ValueError, "scan_window: expected a finite number of seconds > 0"),
        (dict(scan_window=np.inf), ValueError, "scan_window: expected a finite number"),
        (dict(scan_window=True), TypeError, "scan_window: expected a number of seconds"),
        (dict(scan=[0.0, np.nan]), ValueError, "scan: contains NaN"),
        (dict(scan=[0, 1, 2]), ValueError, r"scan: expected shape \(2,\)"),
        (dict(scan_window=1.0, origin=[0]), ValueError, r"origin: expected shape \(2,\)"),
    ],
)
def test_from_times_errors(kwargs, error, message):
    with pytest.raises(error, match=message):
        Detections.from_times([0.0, 1.0], np.zeros((2, 2)), **kwargs)


def test_from_times_refuses_no_detections_and_bad_times():
    with pytest.raises(ValueError, match="times: no detections"):
        Detections.from_times([], np.zeros((0, 2)), scan_window=1.0)
    with pytest.raises(ValueError, match="times: contains NaN"):
        Detections.from_times([0.0, np.nan], np.zeros((2, 2)), scan_window=1.0)
    with pytest.raises(ValueError, match=r"z: expected shape \(2, \*\)"):
        Detections.from_times([0.0, 1.0], np.zeros((3, 2)), scan_window=1.0)
