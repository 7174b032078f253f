"""Reading unlabelled detections: CSV and DataFrame alike, scans by window and by column, the truth column, problems
reported like read_tracks, and lat/lon projected exactly as read_tracks projects the same rows."""

import gzip
import warnings
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hybridtrack.engine.detections import Detections
from hybridtrack.io.detection_files import read_detections
from hybridtrack.io.track_files import SOLENT_AIS, read_tracks

ROOT = Path(__file__).resolve().parents[2]
SOLENT = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"

XY = """time,x,y,label,who
3.0,30,-3,1,b
0.0,0,0,0,a
9.5,95,-9.5,0,a
10.0,100,-10,1,
21.0,210,-21,2,c
12.0,120,-12,1,b
"""


def write(tmp_path, text, name="d.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def read(source, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_detections(source, **kwargs)


def same(a: Detections, b: Detections) -> bool:
    return all(
        np.array_equal(getattr(a, n), getattr(b, n)) if getattr(a, n) is not None else getattr(b, n) is None
        for n in ("scan_times", "scan", "times", "z", "origin")
    )


def test_window_grouping_of_a_csv(tmp_path):
    data = read(write(tmp_path, XY), scan_window=10.0)
    d = data.detections
    assert d.scan_times.tolist() == [10.0, 20.0, 21.0]
    assert d.scan.tolist() == [0, 0, 0, 1, 1, 2]
    assert d.times.tolist() == [0.0, 3.0, 9.5, 10.0, 12.0, 21.0]
    assert d.z.tolist() == [[t * 10, -t] for t in d.times.tolist()]
    assert data.lines.tolist() == [3, 2, 4, 5, 7, 6]
    assert d.origin is None and data.truth_names is None and data.origin is None and data.projection is None and data.epoch is None
    expected = Detections.from_times([3.0, 0.0, 9.5, 10.0, 21.0, 12.0], [[30, -3], [0, 0], [95, -9.5], [100, -10], [210, -21], [120, -12]], scan_window=10.0)  # fmt: skip
    assert same(d, expected)


def test_scan_column_and_truth_id(tmp_path):
    data = read(write(tmp_path, XY), scan="label", truth_id="who")
    d = data.detections
    assert d.scan_times.tolist() == [9.5, 12.0, 21.0]  # each scan's latest time
    assert d.scan.tolist() == [0, 0, 1, 1, 1, 2]
    assert d.times.tolist() == [0.0, 9.5, 3.0, 10.0, 12.0, 21.0]
    assert data.truth_names == ("b", "a", "c")  # in order of first appearance in the file
    assert d.origin.tolist() == [1, 1, 0, -1, 0, 2]  # the empty cell: no known object
    assert [(p.line, p.column, p.kind, p.action) for p in data.problems] == [(5, "who", "missing_id", "flagged")]


def test_reported_course_and_speed_are_kept_as_velocity(tmp_path):
    text = "time,x,y,cog,sog\n0,0,0,90,10\n1,5,0,0,2\n2,9,1,360,3\n3,12,2,45,102.3\n4,15,3,180,\n"
    data = read(
        write(tmp_path, text),
        scan_window=10.0,
        course="cog",
        speed="sog",
        speed_unit="knots",
        course_not_available=360.0,
        speed_not_available=102.3,
    )
    v = data.detections.velocity
    knot = 1852.0 / 3600.0
    np.testing.assert_allclose(v[:2], [[10 * knot, 0.0], [0.0, 2 * knot]], atol=1e-12)  # east, north
    assert np.isnan(v[2:]).all()  # course n/a, speed n/a, speed empty: no velocity, the position kept
    assert data.detections.z.shape == (5, 2)
    assert read(write(tmp_path, text), scan_window=10.0).detections.velocity is None
    head = data.detections.head(1)
    np.testing.assert_array_equal(head.velocity, v[:5])


def test_csv_and_data_frame_give_the_same_detections(tmp_path):
    path = write(tmp_path, XY)
    frame = pd.read_csv(path, dtype={"who": str})
    for kwargs in (dict(scan_window=10.0), dict(scan="label", truth_id="who")):
        a, b = read(path, **kwargs), read(frame, **kwargs)
        assert same(a.detections, b.detections) and a.truth_names == b.truth_names
        assert a.lines.tolist() == b.lines.tolist() and b.path == "<DataFrame>"
    gz = tmp_path / "d.csv.gz"
    gz.write_bytes(gzip.compress(XY.encode()))
    assert same(read(gz, scan_window=10.0).detections, read(path, scan_window=10.0).detections)


def test_timestamps_give_seconds_after_the_epoch(tmp_path):
    text = "t,x,y\n2016-01-12 13:00:05,1,1\n2016-01-12 13:00:00,0,0\n2016-01-12T13:00:12Z,2,2\n"
    data = read(write(tmp_path, text), time="t", scan_window=10.0)
    assert data.epoch == datetime(2016, 1, 12, 13, 0, 0, tzinfo=UTC)
    assert data.detections.times.tolist() == [0.0, 5.0, 12.0] and data.detections.scan_times.tolist() == [10.0, 12.0]
    frame = pd.DataFrame(
        {"t": pd.to_datetime(["2016-01-12 13:00:05", "2016-01-12 13:00:00", "2016-01-12 13:00:12"]), "x": [1, 0, 2], "y": [1, 0, 2]}
    )
    assert same(read(frame, time="t", scan_window=10.0).detections, data.detections)


def test_bad_rows_are_reported_and_dropped(tmp_path):
    text = "time,x,y,scan\n0,0,0,0\nsoon,1,1,0\n1,nan,1,0\n2,2,2,x\n3,3,3,1\n4,4\n"
    with pytest.warns(UserWarning, match="4 problems"):
        data = read_detections(write(tmp_path, text), scan="scan")
    assert [(p.line, p.column, p.kind, p.action) for p in data.problems] == [
        (3, "time", "bad_time", "dropped"),
        (4, "x", "not_a_number", "dropped"),
        (5, "scan", "not_a_number", "dropped"),
        (7, None, "bad_row", "dropped"),
    ]
    assert data.detections.times.tolist() == [0.0, 3.0] and data.lines.tolist() == [2, 6]
    with pytest.raises(ValueError, match="no report left of 2 data rows"):
        read(write(tmp_path, "time,x,y\nsoon,1,1\nlater,2,2\n"), scan_window=1.0)


def test_earliest_time_on_a_dropped_row_is_not_the_epoch(tmp_path):
    text = "t,x,y,s\n2016-01-12 13:00:00,0,0,x\n2016-01-12 13:00:04,1,1,1\n2016-01-12 13:00:06,2,2,1\n"
    data = read(write(tmp_path, text), time="t", scan="s")
    assert data.epoch == datetime(2016, 1, 12, 13, 0, 4, tzinfo=UTC) and data.detections.times.tolist() == [0.0, 2.0]
    assert data.epoch + timedelta(seconds=2) == datetime(2016, 1, 12, 13, 0, 6, tzinfo=UTC)


def test_repeated_reports_are_kept_not_deduplicated(tmp_path):
    data = read(write(tmp_path, "time,x,y\n0,5,5\n0,5,5\n0,7,7\n"), scan_window=1.0)
    assert data.detections.size == 3 and data.problems == ()


GEO = """when,id,lat,lon
2016-01-12 13:00:00,1,50.80,-1.10
2016-01-12 13:00:02,2,50.75,-1.20
2016-01-12 13:00:04,1,50.801,-1.099
2016-01-12 13:00:09,2,50.7505,-1.1995
2016-01-12 13:00:11,3,50.70,-1.00
"""


@pytest.mark.parametrize("origin", ["first", "mean", (50.7, -1.15, 10.0)])
@pytest.mark.parametrize("projection", ["enu", "equirectangular"])
def test_lat_lon_projected_as_read_tracks(tmp_path, origin, projection):
    path = write(tmp_path, GEO)
    tracks = read_tracks(path, time="when", id="id", lat="lat", lon="lon", origin=origin, projection=projection)
    data = read(path, time="when", lat="lat", lon="lon", origin=origin, projection=projection, scan_window=5.0, truth_id="id")
    assert data.origin == tracks.origin and data.projection == projection and data.epoch == tracks.epoch
    by_line = {int(line): p for t in tracks.tracks.values() for line, p in zip(t.lines, t.positions)}
    np.testing.assert_array_equal(data.detections.z, np.array([by_line[int(line)] for line in data.lines]))
    assert data.truth_names == ("1", "2", "3") and data.detections.origin.tolist() == [0, 1, 0, 1, 2]
    assert data.detections.scan_times.tolist() == [5.0, 10.0, 11.0]


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        (dict(), ValueError, "scan and scan_window: give exactly one"),
        (dict(scan="label", scan_window=10.0), ValueError, "scan and scan_window: give exactly one"),
        (dict(scan_window=-1.0), ValueError, "scan_window: expected a finite number of seconds > 0"),
        (dict(scan_window=10.0, lat="x"), ValueError, "lat/lon: give both"),
        (dict(scan_window=10.0, projection="utm"), ValueError, "projection: 'utm'"),
        (dict(scan_window=10.0, time_unit="h"), ValueError, "time_unit: 'h'"),
        (dict(scan_window=10.0, origin="middle"), ValueError, "origin: 'middle'"),
        (dict(scan="nope"), ValueError, "no column 'nope' in the header"),
        (dict(scan_window=10.0, truth_id="nope"), ValueError, "no column 'nope' in the header"),
        (dict(scan_window=10.0, truth_id=3), TypeError, "truth_id: expected a column name"),
        (dict(scan_window=10.0, format="gpx"), ValueError, "read_detections reads CSV files and DataFrames"),
        (dict(scan_window=10.0, course="label"), ValueError, "course/speed: give both"),
        (dict(scan_window=10.0, course="label", speed="y", speed_unit="mph"), ValueError, "speed_unit: 'mph'"),
    ],
)
def test_errors(tmp_path, kwargs, error, message):
    with pytest.raises(error, match=message):
        read(write(tmp_path, XY), **kwargs)


def test_sources_refused(tmp_path):
    with pytest.raises(TypeError, match="source: expected a file path"):
        read_detections(3, scan_window=1.0)
    with pytest.raises(FileNotFoundError, match="no such file"):
        read_detections(tmp_path / "none.csv", scan_window=1.0)


@pytest.mark.skipif(not SOLENT.exists(), reason="the Solent AIS file is not in data/solent_ais")
def test_solent_without_its_mmsi():
    columns = {k: SOLENT_AIS[k] for k in ("time", "lat", "lon")}
    data = read_detections(SOLENT, **columns, scan_window=10.0, truth_id="MMSI")
    d = data.detections
    assert (d.size, d.scans, len(data.truth_names)) == (18623, 508, 91)
    assert data.problems == () and data.epoch == datetime(2016, 1, 12, 13, 2, 11, 218000, tzinfo=UTC)
    assert data.origin == (50.7730133333333, -1.092935, 0.0)  # the first fix, as read_tracks
    assert np.all(np.diff(d.scan_times[:-1]) == 10.0) and d.scan_times[-1] == d.times.max()
