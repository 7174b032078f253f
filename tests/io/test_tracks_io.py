"""Reading real position files: the Solent AIS data, malformed input, and the projection against exact geodesy."""

import gzip
import math
import warnings
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.io.track_files import (
    SOLENT_AIS,
    geodesic_inverse,
    geodetic_to_ecef,
    project,
    projection_error,
    read_tracks,
)

ROOT = Path(__file__).resolve().parents[2]
SOLENT = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"
KNOT = 1852.0 / 3600.0


def read(tmp_path, text, name="t.csv", **kwargs):
    path = tmp_path / name
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_tracks(path, **kwargs)


def kinds(result):
    return [(p.line, p.column, p.kind, p.action) for p in result.problems]


# --- the Solent AIS file ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def solent():
    with pytest.warns(UserWarning, match="9 problems"):
        return read_tracks(SOLENT, **SOLENT_AIS, max_speed=30.0, jump_tolerance=50.0)


def test_solent_counts_and_exactly_what_is_dropped(solent):
    assert len(solent.tracks) == 91
    dropped = [(p.line, p.kind) for p in solent.problems if p.action == "dropped"]
    # three rows repeating the previous report of the same vessel exactly, and one position 3 600 km away
    assert dropped == [(426, "duplicate_time"), (2798, "duplicate_time"), (8209, "speed_jump"), (11907, "duplicate_time")]
    assert solent.reports == 18_623 - 4
    assert "identical" in solent.problems[[p.line for p in solent.problems].index(426)].message
    assert solent.epoch == datetime(2016, 1, 12, 13, 2, 11, 218000, tzinfo=UTC)
    assert solent.origin == (50.7730133333333, -1.092935, 0.0)  # the first fix


def test_solent_without_a_speed_limit_keeps_the_outlier(tmp_path):
    with pytest.warns(UserWarning):
        result = read_tracks(SOLENT, **SOLENT_AIS)
    assert len(result.tracks) == 91 and result.reports == 18_623 - 3
    far = result.tracks["245188000"]
    assert np.abs(far.positions).max() > 3e6  # longitude 54.8° E in a Solent track


def test_solent_columns(solent):
    ferry = solent.tracks["235007473"]
    assert ferry.positions.shape == (len(ferry), 2) and ferry.course.shape == ferry.speed.shape == (len(ferry),)
    assert np.all(np.diff(ferry.times) > 0)
    # course 360 is AIS "not available": 1027 rows of the file, all NaN now
    assert sum(int(np.isnan(t.course).sum()) for t in solent.tracks.values()) == 1027
    assert max(np.nanmax(t.speed) for t in solent.tracks.values()) == pytest.approx(36.3 * KNOT)
    gaps = np.concatenate([np.diff(t.times) for t in solent.tracks.values()])
    assert 2.0 <= np.median(gaps) <= 10.0
    # the first line of the file is the first fix of vessel 235070762: at the origin, time 0
    first = solent.tracks["235070762"]
    assert first.lines[0] == 2 and first.times[0] == 0.0 and np.allclose(first.positions[0], 0.0)


def test_solent_positions_match_pymap3d(solent):
    pymap3d = pytest.importorskip("pymap3d")
    text = SOLENT.read_text().splitlines()
    lat0, lon0, _ = solent.origin
    ferry = solent.tracks["235013375"]
    for k in (0, 100, len(ferry) - 1):
        cells = text[ferry.lines[k] - 1].split(",")
        e, n, _ = pymap3d.geodetic2enu(float(cells[2]), float(cells[3]), 0.0, lat0, lon0, 0.0)
        np.testing.assert_allclose(ferry.positions[k], [e, n], atol=1e-6)


def test_gzip_reads_the_same(tmp_path, solent):
    packed = tmp_path / "solent.csv.gz"
    packed.write_bytes(gzip.compress(SOLENT.read_bytes()))
    with pytest.warns(UserWarning):
        again = read_tracks(packed, **SOLENT_AIS, max_speed=30.0, jump_tolerance=50.0)
    assert again.reports == solent.reports and again.tracks["235007473"] == solent.tracks["235007473"]


# --- the projection against exact geodesy -------------------------------------------------------------------


def dms(d, m, s):
    return math.copysign(abs(d) + m / 60 + s / 3600, d)


def test_vincenty_reproduces_the_published_example():
    # Flinders Peak → Buninyong (Geoscience Australia's worked example of Vincenty's inverse formula, GRS80)
    s, azimuth = geodesic_inverse(dms(-37, 57, 3.72030), dms(144, 25, 29.52440), dms(-37, 39, 10.15610), dms(143, 55, 35.38390))
    assert s == pytest.approx(54_972.271, abs=1e-3)
    assert azimuth == pytest.approx(dms(306, 52, 5.37), abs=0.01 / 3600)


def test_vincenty_matches_pymap3d():
    vincenty = pytest.importorskip("pymap3d.vincenty")
    rng = np.random.default_rng(3)
    lat2, lon2 = rng.uniform(49, 53, 20), rng.uniform(-3, 1, 20)
    s, azimuth = geodesic_inverse(50.8, -1.2, lat2, lon2)
    reference = np.array([vincenty.vdist(50.8, -1.2, a, b) for a, b in zip(lat2, lon2)])
    np.testing.assert_allclose(s, reference[:, 0], atol=1e-6)
    np.testing.assert_allclose(azimuth, reference[:, 1], atol=1e-9)


def test_enu_error_over_100_km():
    err = projection_error((50.8, -1.2), 100e3, projection="enu")
    assert err["range"] == pytest.approx(100e3, rel=0.01)
    # the tangent plane shortens ranges by the chord-versus-arc amount s − R sin(s/R) ≈ s³/(6R²)
    radius = 6_371e3
    assert err["distance"] == pytest.approx(-(100e3**3) / (6 * radius**2), rel=0.05)
    assert err["position"] < 4.5 and err["bearing"] < 1e-4 and err["scale"] < 1.5e-4
    near = projection_error((50.8, -1.2), 10e3, projection="enu")
    assert near["position"] < 0.01  # cubic: 1000× smaller at a tenth of the range


def test_equirectangular_error_over_100_km_is_far_larger():
    err = projection_error((50.8, -1.2), 100e3, projection="equirectangular")
    assert 500 < err["position"] < 2000 and err["scale"] > 0.01


def test_enu_with_height_matches_pymap3d():
    pymap3d = pytest.importorskip("pymap3d")
    enu = project([51.0, 50.5], [-1.0, -1.5], [120.0, -5.0], origin=(50.8, -1.2, 30.0))
    for k, (a, b, h) in enumerate([(51.0, -1.0, 120.0), (50.5, -1.5, -5.0)]):
        np.testing.assert_allclose(enu[k], pymap3d.geodetic2enu(a, b, h, 50.8, -1.2, 30.0), atol=1e-6)
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 0.0), [6_378_137.0, 0.0, 0.0])


# --- layouts ------------------------------------------------------------------------------------------------


def test_xy_numeric_times_one_track(tmp_path):
    result = read(tmp_path, "time,x,y\n0,0,0\n1.5,3,4\n3,6,8\n")
    (track,) = result.tracks.values()
    assert track.id == "" and result.origin is None and result.epoch is None and result.problems == ()
    np.testing.assert_array_equal(track.times, [0, 1.5, 3])
    np.testing.assert_array_equal(track.positions, [[0, 0], [3, 4], [6, 8]])
    assert track.course is None and track.speed is None and list(track.lines) == [2, 3, 4]


def test_configurable_names_altitude_ids_and_speed_units(tmp_path):
    text = "id;t;east;north;z;cog;sog\nb;0;0;0;1;90;10\na;0;5;5;2;0;0\nb;1;1;0;1;90;10\n"
    result = read(tmp_path, text, time="t", x="east", y="north", alt="z", id="id", course="cog", speed="sog", speed_unit="km/h")
    assert list(result.tracks) == ["b", "a"]
    b = result.tracks["b"]
    assert b.positions.shape == (2, 3)
    np.testing.assert_allclose(b.speed, [10 / 3.6, 10 / 3.6])
    np.testing.assert_array_equal(b.course, [90, 90])


def test_iso_times_with_zones_and_origin_choices(tmp_path):
    text = "time,lat,lon\n2024-01-01T00:00:01+01:00,50.0,-1.0\n2024-01-01T00:00:00Z,50.001,-1.0\n2023-12-31 23:00:02,50.002,-1.0\n"
    result = read(tmp_path, text, lat="lat", lon="lon")
    track = result.tracks[""]
    # 00:00:01+01:00 is 23:00:01 UTC, the earliest; naive stamps are UTC
    assert result.epoch == datetime(2023, 12, 31, 23, 0, 1, tzinfo=UTC)
    np.testing.assert_array_equal(track.times, [0.0, 1.0, 3599.0])
    np.testing.assert_array_equal(track.lines, [2, 4, 3])
    assert result.origin == (50.0, -1.0, 0.0)  # the first fix in file order
    assert track.positions[1, 1] == pytest.approx(222.4, abs=0.5)  # 0.002° of latitude north
    assert [p.kind for p in result.problems] == ["unsorted"]
    mean = read(tmp_path, text, lat="lat", lon="lon", origin="mean")
    assert mean.origin == pytest.approx((50.001, -1.0, 0.0))
    fixed = read(tmp_path, text, lat="lat", lon="lon", origin=(50.0, -1.0))
    np.testing.assert_allclose(fixed.tracks[""].positions, track.positions)


def test_unsorted_rows_are_sorted_per_object(tmp_path):
    result = read(tmp_path, "time,x,y,id\n2,2,0,a\n0,0,0,a\n5,9,9,b\n1,1,0,a\n", id="id")
    a = result.tracks["a"]
    np.testing.assert_array_equal(a.times, [0, 1, 2])
    np.testing.assert_array_equal(a.lines, [3, 5, 2])
    assert kinds(result) == [(3, "time", "unsorted", "sorted")] and a.problems == result.problems


# --- malformed input: refused -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, kwargs, message",
    [
        ("", {}, "empty file"),
        ("\n\n", {}, "empty file"),
        ("time,x,y\n", {}, "header only"),
        ("time,x\n0,1\n", {}, r":1: no column 'y' in the header; the columns are \['time', 'x'\]"),
        ("t,x,y\n0,1,2\n", {}, "no column 'time'"),
        ("time,x,y\n0,1,2\n", {"lat": "lat", "lon": "lon"}, "no column 'lat'"),
        ("time,x,y\n0,1,2\n", {"id": "vessel"}, "no column 'vessel'"),
        ("time,x,x,y\n0,1,2,3\n", {}, "column 'x' appears 2 times"),
    ],
)
def test_refused_files(tmp_path, text, kwargs, message):
    with pytest.raises(ValueError, match=message) as info:
        read(tmp_path, text, **kwargs)
    assert str(info.value).startswith(str(tmp_path / "t.csv"))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"lat": "x"}, "give both latitude and longitude"),
        ({"speed_unit": "mph"}, "speed_unit"),
        ({"max_speed": -1}, "max_speed"),
        ({"jump_tolerance": -1}, "jump_tolerance"),
        ({"projection": "utm"}, "projection"),
        ({"origin": "median"}, "origin"),
        ({"origin": (95, 0)}, "origin"),
    ],
)
def test_refused_arguments(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        read(tmp_path, "time,x,y\n0,1,2\n", **kwargs)


def test_refused_paths_and_encodings(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        read_tracks(tmp_path / "missing.csv")
    with pytest.raises(IsADirectoryError):
        read_tracks(tmp_path)
    with pytest.raises(TypeError, match="path"):
        read_tracks(3)
    (tmp_path / "u16.csv").write_bytes("time,x,y\n".encode("utf-16"))
    with pytest.raises(ValueError, match="UTF-16"):
        read_tracks(tmp_path / "u16.csv")
    (tmp_path / "bad.csv.gz").write_bytes(b"not gzip")
    with pytest.raises(ValueError, match="gzip"):
        read_tracks(tmp_path / "bad.csv.gz")


# --- malformed rows: reported, naming file, line and column -------------------------------------------------


@pytest.mark.parametrize(
    "row, kwargs, expected",
    [
        ("yesterday,1,1", {}, (3, "time", "bad_time", "dropped")),
        ("inf,1,1", {}, (3, "time", "bad_time", "dropped")),
        ("1,abc,1", {}, (3, "x", "not_a_number", "dropped")),
        ("1,1,", {}, (3, "y", "not_a_number", "dropped")),
        ("1,1e999,1", {}, (3, "x", "not_a_number", "dropped")),
        ("1,1", {}, (3, None, "bad_row", "dropped")),
        ("1,1,1,extra", {}, (3, None, "bad_row", "dropped")),
        ("0,0,0", {}, (3, "time", "duplicate_time", "dropped")),
    ],
)
def test_reported_rows(tmp_path, row, kwargs, expected):
    result = read(tmp_path, f"time,x,y\n0,0,0\n{row}\n2,2,2\n", **kwargs)
    assert kinds(result) == [expected]
    problem = result.problems[0]
    assert problem.message.startswith(f"{tmp_path / 't.csv'}:3: ")
    assert list(result.tracks[""].lines) == [2, 4]
    # a row with the wrong cell count belongs to no track (its id cannot be trusted); the others are the track's
    assert result.tracks[""].problems == (() if expected[2] == "bad_row" else result.problems)


def test_unparseable_iso_time(tmp_path):
    result = read(tmp_path, "time,x,y\n2024-01-01 00:00:00,0,0\n2024-13-01 00:00:00,1,1\n12.5,1,1\n")
    assert kinds(result) == [(3, "time", "bad_time", "dropped"), (4, "time", "bad_time", "dropped")]
    assert "ISO-8601" in result.problems[0].message and "'2024-13-01 00:00:00'" in result.problems[0].message


def test_conflicting_duplicates_are_refused(tmp_path):
    """Two reports of one time 1 km apart: neither is used (not the first in file order)."""
    result = read(tmp_path, "time,x,y\n0,0,0\n0,1000,0\n1,1,1\n")
    assert kinds(result) == [(2, "time", "conflicting_duplicate", "dropped"), (3, "time", "conflicting_duplicate", "dropped")]
    assert "lines 2, 3" in result.problems[0].message
    np.testing.assert_array_equal(result.tracks[""].positions, [[1, 1]])


def test_repeat_with_other_speed_keeps_the_first(tmp_path):
    result = read(tmp_path, "time,x,y,s\n0,0,0,1\n0,0,0,2\n1,1,1,1\n", speed="s")
    assert kinds(result) == [(3, "time", "duplicate_time", "dropped")]
    assert "other course or speed" in result.problems[0].message and "repeats line 2" in result.problems[0].message
    np.testing.assert_array_equal(result.tracks[""].speed, [1, 1])


@pytest.mark.parametrize(
    "cells, column, value",
    [("91,0", "lat", "91.0"), ("-90.5,0", "lat", "-90.5"), ("0,180.01", "lon", "180.01"), ("0,-200", "lon", "-200.0")],
)
def test_latitude_longitude_out_of_range(tmp_path, cells, column, value):
    result = read(tmp_path, f"time,lat,lon\n0,50,-1\n1,{cells}\n", lat="lat", lon="lon")
    assert kinds(result) == [(3, column, "out_of_range", "dropped")]
    assert value in result.problems[0].message and "outside" in result.problems[0].message


def test_course_and_speed_cells_are_set_to_nan(tmp_path):
    text = "time,x,y,c,s\n0,0,0,10,1\n1,1,0,abc,1\n2,2,0,361,1\n3,3,0,360,-1\n4,4,0,360,102.3\n"
    result = read(tmp_path, text, course="c", speed="s", course_not_available=360, speed_not_available=102.3)
    track = result.tracks[""]
    assert len(track) == 5  # course/speed faults never drop a position
    np.testing.assert_array_equal(track.course, [10, np.nan, np.nan, np.nan, np.nan])
    np.testing.assert_array_equal(track.speed, [1, 1, 1, np.nan, np.nan])
    assert kinds(result) == [
        (3, "c", "not_a_number", "set_nan"),
        (4, "c", "out_of_range", "set_nan"),
        (5, "c", "not_available", "set_nan"),
        (5, "s", "out_of_range", "set_nan"),
        (6, "s", "not_available", "set_nan"),
    ]
    assert "in 2 rows (lines 5, 6)" in result.problems[2].message


def test_missing_id_cell(tmp_path):
    result = read(tmp_path, "time,x,y,id\n0,0,0,a\n1,1,1,\n", id="id")
    assert kinds(result) == [(3, "id", "missing_id", "dropped")] and result.problems[0].id is None
    assert list(result.tracks) == ["a"]


# --- the speed limit ---------------------------------------------------------------------------------------


def test_single_outlier_is_dropped(tmp_path):
    result = read(tmp_path, "time,x,y\n0,0,0\n1,1,0\n2,500,0\n3,3,0\n4,4,0\n", max_speed=10)
    assert kinds(result) == [(4, "time", "speed_jump", "dropped")]
    assert (
        "(499.0 m in 1 s) takes 499.0 m/s > max_speed 10 m/s" in result.problems[0].message and "from line 3" in result.problems[0].message
    )
    np.testing.assert_array_equal(result.tracks[""].times, [0, 1, 3, 4])


def test_burst_of_outliers_is_dropped(tmp_path):
    result = read(tmp_path, "time,x,y\n0,0,0\n1,1,0\n2,500,0\n3,501,0\n4,4,0\n", max_speed=10)
    assert [(p.line, p.action) for p in result.problems] == [(4, "dropped"), (5, "dropped")]


def test_first_fix_outlier_is_dropped(tmp_path):
    result = read(tmp_path, "time,x,y\n0,900,0\n1,1,0\n2,2,0\n3,3,0\n", max_speed=10)
    assert kinds(result) == [(2, "time", "speed_jump", "dropped")]
    np.testing.assert_array_equal(result.tracks[""].times, [1, 2, 3])


def test_lasting_jump_is_flagged_and_kept(tmp_path):
    text = "time,x,y\n0,0,0\n1,1,0\n2,500,0\n3,501,0\n4,502,0\n5,503,0\n6,504,0\n"
    result = read(tmp_path, text, max_speed=10)
    assert kinds(result) == [(4, "time", "speed_jump", "flagged")]
    assert len(result.tracks[""]) == 7


def test_jump_tolerance_absorbs_time_stamp_jitter(tmp_path):
    text = "time,x,y\n0,0,0\n0.3,12,0\n2,24,0\n"  # 12 m in 0.3 s (40 m/s) at a true 12 m/s
    assert kinds(read(tmp_path, text, max_speed=30))[0][2:] == ("speed_jump", "dropped")
    assert read(tmp_path, text, max_speed=30, jump_tolerance=20).problems == ()


def test_speed_check_in_geographic_coordinates(tmp_path):
    text = "time,lat,lon,id\n0,50.0,-1.0,v\n10,50.0001,-1.0,v\n20,50.2,-1.0,v\n30,50.0003,-1.0,v\n"
    result = read(tmp_path, text, lat="lat", lon="lon", id="id", max_speed=20)
    assert kinds(result) == [(4, "time", "speed_jump", "dropped")] and result.problems[0].id == "v"


def test_problems_are_warned_once(tmp_path):
    path = tmp_path / "w.csv"
    path.write_text("time,x,y\n0,0,0\nx,1,1\n0,0,0\n")
    with pytest.warns(UserWarning, match=r"w.csv: 2 problems: 1 bad_time \(dropped\), 1 duplicate_time \(dropped\)"):
        read_tracks(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_tracks(path, warn=False)


def test_every_row_dropped_is_an_error_naming_the_column(tmp_path):
    with pytest.raises(
        ValueError, match=r"no report left of 2 data rows \(1 bad_time, 1 out_of_range\); the first: .*column 'time' holds 'noon'"
    ):
        read(tmp_path, "time,lat,lon\nnoon,50,-1\n1,95,-1\n", lat="lat", lon="lon")


def test_day_month_year_times_need_time_format(tmp_path):
    text = "time,x,y\n12/01/2016 13:02:11,0,0\n12/01/2016 13:02:21,10,0\n"
    with pytest.raises(ValueError, match=r"no report left of 2 data rows \(2 bad_time\).*'12/01/2016 13:02:11'.*time_format"):
        read(tmp_path, text)
    result = read(tmp_path, text, time_format="%d/%m/%Y %H:%M:%S")
    assert list(result.tracks[""].times) == [0.0, 10.0] and result.epoch.isoformat() == "2016-01-12T13:02:11+00:00"
    with pytest.raises(ValueError, match="time_format"):
        read(tmp_path, text, time_format="dd/mm/yyyy")


def test_swapped_latitude_and_longitude_get_a_hint(tmp_path):
    text = "time,lat,lon\n0,-122.4,37.8\n1,-122.41,37.8\n"
    with pytest.raises(ValueError, match="latitude and longitude swapped"):
        read(tmp_path, text, lat="lat", lon="lon")


def test_epoch_milliseconds_need_time_unit(tmp_path):
    text = "time,x,y\n1452603731218,0,0\n1452603741218,10,0\n"
    with pytest.raises(ValueError, match=r"t.csv:2: column 'time' holds 1452603731218.*time_unit = 'ms'"):
        read(tmp_path, text)
    np.testing.assert_allclose(read(tmp_path, text, time_unit="ms").tracks[""].times, [1452603731.218, 1452603741.218])
    assert read(tmp_path, "time,x,y\n0,0,0\n2500,10,0\n", time_unit="ms").tracks[""].times[1] == 2.5
    with pytest.raises(ValueError, match="time_unit: 'min'"):
        read(tmp_path, text, time_unit="min")


def test_object_class_sets_the_speed_limit(tmp_path):
    text = "time,x,y\n0,0,0\n10,100,0\n20,5000000,0\n30,300,0\n40,400,0\n"
    result = read(tmp_path, text, object_class="ship")
    assert kinds(result) == [(4, "time", "speed_jump", "dropped")] and "max_speed 35 m/s" in result.problems[0].message
    assert read(tmp_path, text).problems == ()  # no class, no limit: the reader keeps what it is told
    with pytest.raises(ValueError, match="object_class: 'boat'"):
        read(tmp_path, text, object_class="boat")


def test_positions_far_from_the_earth_are_dropped(tmp_path):
    result = read(tmp_path, "time,x,y\n0,0,0\n1,1e202,0\n2,2,0\n")
    assert kinds(result) == [(3, "x", "out_of_range", "dropped")] and "1e+202" in result.problems[0].message
