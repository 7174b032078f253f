"""read_tracks beyond CSV: GPX 1.0/1.1 (gpxpy), raw AIS NMEA (pyais), pandas DataFrames; the format keyword and
the extension dispatch; a missing optional package; ``hybridtrack track`` on a GPX file."""

import json
import math
import sys
import warnings
from datetime import UTC, datetime

import attrs
import numpy as np
import pytest

import hybridtrack
from hybridtrack.apps.tracking import CONFIG_KEYS, load_config
from hybridtrack.cli import main
from hybridtrack.io.track_files import DATA_FRAME, MissingExtraError, read_tracks

pd = pytest.importorskip("pandas")
pyais = pytest.importorskip("pyais")
pytest.importorskip("gpxpy")

KNOT = 1852.0 / 3600.0
EPOCH = datetime(2016, 1, 12, 13, 2, 11, tzinfo=UTC)
UNIX = 1452603731  # EPOCH as Unix seconds


def read(path, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_tracks(path, **kwargs)


def kinds(data):
    return [(p.line, p.kind, p.action) for p in data.problems]


# --- GPX ---------------------------------------------------------------------------------------------------

GPX_11 = """<?xml version="1.0" encoding="UTF-8"?>
<gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">
  <wpt lat="50.0" lon="-1.0"><time>2016-01-12T12:00:00Z</time></wpt>
  <rte><rtept lat="50.5" lon="-1.5"/></rte>
  <trk><name>walk</name>
    <trkseg>
      <trkpt lat="50.7730" lon="-1.0929"><ele>10</ele><time>2016-01-12T13:02:11Z</time></trkpt>
      <trkpt lat="50.7731" lon="-1.0928"><ele>11</ele><time>2016-01-12T14:02:21+01:00</time></trkpt>
      <trkpt lat="50.7732" lon="-1.0927"><ele>11</ele></trkpt>
    </trkseg>
    <trkseg>
      <trkpt lat="50.7733" lon="-1.0926"><ele>12</ele><time>2016-01-12T13:02:41Z</time></trkpt>
    </trkseg>
  </trk>
  <trk>
    <trkseg>
      <trkpt lat="50.7740" lon="-1.0920"><ele>1</ele><time>2016-01-12T13:02:15Z</time></trkpt>
      <trkpt lat="50.7741" lon="-1.0920"><ele>1</ele><time>soon</time></trkpt>
    </trkseg>
  </trk>
  <trk><name>walk</name><trkseg><trkpt lat="50.7750" lon="-1.0910"><ele>2</ele><time>2016-01-12T13:03:00Z</time></trkpt></trkseg></trk>
</gpx>
"""

GPX_10 = """<?xml version="1.0"?>
<gpx version="1.0" creator="logger" xmlns="http://www.topografix.com/GPX/1/0">
  <trk><name>car</name><trkseg>
    <trkpt lat="50.7730" lon="-1.0929"><time>2016-01-12T13:02:11Z</time><speed>3.5</speed><course>45</course></trkpt>
    <trkpt lat="50.7731" lon="-1.0928"><ele>5</ele><time>2016-01-12T13:02:13Z</time></trkpt>
    <trkpt lat="50.7732" lon="-1.0927"><time>2016-01-12T13:02:15Z</time></trkpt>
  </trkseg></trk>
</gpx>
"""


def test_gpx_11_one_track_per_trk_with_elevation_and_the_points_without_time_reported(tmp_path):
    path = tmp_path / "walk.gpx"
    path.write_text(GPX_11)
    with pytest.warns(UserWarning, match="2 bad_time"):
        data = read_tracks(path)
    assert list(data.tracks) == ["walk", "track 2", "walk #2"]  # the unnamed second <trk>, the repeated name
    assert data.epoch == EPOCH and data.origin == (50.7730, -1.0929, 10.0)
    walk = data.tracks["walk"]
    assert walk.times.tolist() == [0.0, 10.0, 30.0]  # +01:00 read as such; the two segments joined
    assert walk.lines.tolist() == [7, 8, 12]  # the lines of the <trkpt> start tags
    assert walk.positions.shape == (3, 3) and walk.course is None and walk.speed is None
    assert walk.positions[0].tolist() == [0.0, 0.0, 0.0] and walk.positions[1, 2] == pytest.approx(1.0, abs=1e-3)
    assert kinds(data) == [(9, "bad_time", "dropped"), (18, "bad_time", "dropped")]
    no_time, bad_time = data.problems
    assert no_time.message == f"{path}:9: track 'walk', point 3 has no <time>; point dropped" and no_time.id == "walk"
    assert "track 'track 2', point 2 has <time> 'soon', not an ISO-8601 time" in bad_time.message
    assert data.reports == 5  # no waypoint, no route point


def test_gpx_10_without_elevation_on_every_point_is_two_dimensional(tmp_path):
    path = tmp_path / "car.gpx"
    path.write_text(GPX_10)
    data = read_tracks(path, warn=False)
    car = data.tracks["car"]
    assert car.positions.shape == (3, 2) and car.times.tolist() == [0.0, 2.0, 4.0]
    assert car.speed is None and car.course is None  # GPX 1.0's <speed>/<course> are not read
    assert data.problems == ()


def test_gpx_keywords_of_every_format_still_apply(tmp_path):
    path = tmp_path / "walk.gpx"
    path.write_text(GPX_11)
    far = read(path, origin=(50.0, -1.0), projection="equirectangular", max_speed=0.5)
    assert far.origin == (50.0, -1.0, 0.0) and far.projection == "equirectangular"
    assert any(p.kind == "speed_jump" for p in far.problems)  # 1.4 m/s between the walk's first fixes


@pytest.mark.parametrize(
    "text, message",
    [
        ('<?xml version="1.0"?>\n<kml><Document/></kml>\n', "not a GPX file: the root element is <kml>"),
        ("time,x,y\n0,1,2\n", r":1: not a GPX file: not well-formed XML"),
        ('<gpx version="1.1"><trk><trkseg><trkpt lat="50" lon="-1"><time>2016', r":1: not a GPX file: not well-formed XML"),
        ('<gpx version="1.1"><wpt lat="50" lon="-1"/><rte><rtept lat="50" lon="-1"/></rte></gpx>', "no track points"),
        ('<gpx version="1.1"><trk><trkseg><trkpt lat="north" lon="-1"/></trkseg></trk></gpx>', "not a valid GPX file"),
    ],
)
def test_not_gpx_is_an_error_naming_the_file(tmp_path, text, message):
    path = tmp_path / "bad.gpx"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"bad.gpx.*{message}"):
        read_tracks(path)


# --- NMEA ----------------------------------------------------------------------------------------------------


def checksum(text: str) -> str:
    """The NMEA checksum of ``text``: the XOR of its characters, two hex digits."""
    value = 0
    for char in text:
        value ^= ord(char)
    return f"{value:02X}"


def sentences(fields: dict, channel: str = "A", seq_id=None) -> list[str]:
    """The !AIVDM sentence(s) of one AIS message: the payload by pyais's encoder, the talker, sequence id and channel
    set here, the checksum computed again (and verified by pyais's parser)."""
    encoded = []
    for sentence in pyais.encode_dict(fields):
        parts = sentence[1 : sentence.rindex("*")].split(",")
        parts[0], parts[3], parts[4] = "AIVDM", "" if seq_id is None else str(seq_id), channel
        body = ",".join(parts)
        encoded.append(f"!{body}*{checksum(body)}")
    assert all(pyais.NMEAMessage(s.encode()).is_valid for s in encoded)
    return encoded


def tag_block(fields: str) -> str:
    """An NMEA 4.0 tag block ``\\fields*hh\\``."""
    return f"\\{fields}*{checksum(fields)}\\"


FERRY, YACHT, TUG = 235070762, 235000001, 235000002
POSITION = {"type": 1, "mmsi": FERRY, "lat": 50.77, "lon": -1.09, "course": 157.8, "speed": 5.9}


def nmea_log() -> list[str]:
    static = sentences({"type": 5, "mmsi": FERRY, "shipname": "FERRY", "destination": "COWES"}, seq_id=3)
    assert len(static) == 2  # type 5: two sentences
    moved = {**POSITION, "lat": 50.7702, "course": 158.0}
    return [
        tag_block(f"s:station1,c:{UNIX}") + sentences(POSITION)[0],  # 1: tag-block time
        "2016-01-12T13:02:21Z " + sentences({**POSITION, "lat": 50.7701}, channel="B")[0],  # 2: leading ISO time
        tag_block(f"g:1-2-77,c:{UNIX + 5}") + static[0],  # 3, 4: type 5, assembled and ignored
        tag_block("g:2-2-77") + static[1],
        f"{UNIX + 20}.5," + sentences({"type": 18, "mmsi": YACHT, "lat": 50.78, "lon": -1.1, "course": 360, "speed": 102.3})[0],  # 5
        sentences({"type": 19, "mmsi": TUG, "lat": 50.79, "lon": -1.11, "course": 10, "speed": 3.0, "shipname": "TUG"})[0],  # 6: no time
        sentences(moved)[0][:-2] + "00",  # 7: bad checksum
        tag_block(f"c:{(UNIX + 30) * 1000}") + sentences(moved)[0],  # 8: milliseconds
        "\\c:1452603745*00\\" + sentences(moved)[0],  # 9: bad tag-block checksum
        "",  # 10: blank, skipped
        "$GPRMC,130211,A,5046.38,N,00105.58,W,5.9,157.8,120116,,*00",  # 11: not AIS
        "2016-01-12 13:02:51.5," + sentences({**POSITION, "lat": 91.0, "lon": 181.0})[0],  # 12: not available
        "2016-01-12 13:03:01 " + sentences({"type": 5, "mmsi": YACHT, "shipname": "YACHT"}, seq_id=4)[1],  # 13: a lone second part
        tag_block(f"c:{UNIX + 60}") + sentences({"type": 5, "mmsi": TUG, "shipname": "TUG2"}, seq_id=5)[0],  # 14: no second part
        "no sentence here",  # 15
        tag_block(f"c:{UNIX + 70}") + sentences({**POSITION, "type": 3, "lat": 50.7703})[0],  # 16
        "noon " + sentences(moved)[0],  # 17: a leading stamp that is no time
        tag_block(f"c:{UNIX + 75}") + sentences({"type": 5, "mmsi": TUG, "shipname": "TUG3"}, seq_id=6)[0],  # 18, 19: the second type 5
        tag_block(f"c:{UNIX + 75}") + sentences({"type": 5, "mmsi": TUG, "shipname": "TUG3"}, seq_id=6)[1],
    ]


def test_known_pyais_sample_sentence_is_valid():
    sample = "!AIVDM,1,1,,B,15NG6V0P01G?cFhE`R2IU?wn28R>,0*05"  # the pyais README's
    assert pyais.NMEAMessage(sample.encode()).is_valid
    assert pyais.decode(sample).mmsi == 367380120


def test_nmea_log_positions_times_and_every_line_not_used(tmp_path):
    path = tmp_path / "log.nmea"
    path.write_text("\n".join(nmea_log()) + "\n")
    with pytest.warns(UserWarning, match="problems"):
        data = read_tracks(path)
    assert data.epoch == EPOCH and list(data.tracks) == [str(FERRY), str(YACHT)]
    ferry = data.tracks[str(FERRY)]
    assert ferry.times.tolist() == [0.0, 10.0, 30.0, 70.0] and ferry.lines.tolist() == [1, 2, 8, 16]
    assert np.allclose(ferry.course, [157.8, 157.8, 158.0, 157.8]) and np.allclose(ferry.speed, 5.9 * KNOT)
    assert ferry.positions[1, 1] == pytest.approx(11.1, abs=0.2)  # 0.0001° of latitude north
    yacht = data.tracks[str(YACHT)]
    assert yacht.times.tolist() == [20.5] and math.isnan(yacht.course[0]) and math.isnan(yacht.speed[0])
    by_line = {(p.line, p.kind): p for p in data.problems}
    assert sorted(by_line) == [
        (3, "not_position"),
        (5, "not_available"),
        (6, "bad_time"),
        (7, "bad_checksum"),
        (9, "bad_checksum"),
        (11, "not_position"),
        (12, "out_of_range"),
        (13, "bad_row"),
        (14, "bad_row"),
        (15, "bad_row"),
        (17, "bad_time"),
    ]
    assert sum(p.kind == "not_available" for p in data.problems) == 2  # course 360 and speed 102.3
    assert "2 AIS message(s) of type 5 (static and voyage data), not a position report" in by_line[3, "not_position"].message
    assert "1 $GPRMC sentence(s), not AIS" in by_line[11, "not_position"].message
    assert by_line[6, "bad_time"].message.startswith(f"{path}:6: AIS position report (type 19) of MMSI {TUG} without a time")
    assert by_line[6, "bad_time"].id == str(TUG)
    assert "checksum *00 does not match" in by_line[7, "bad_checksum"].message
    assert "tag block 'c:1452603745*00'" in by_line[9, "bad_checksum"].message
    assert "column 'lat' holds 91.0, outside [-90, 90] degrees" in by_line[12, "out_of_range"].message
    assert "2-sentence AIS message (sequence id 4" in by_line[13, "bad_row"].message
    assert "(sequence id 5" in by_line[14, "bad_row"].message
    assert "'no sentence here' is no NMEA sentence" in by_line[15, "bad_row"].message
    assert "the leading 'noon' is neither an ISO-8601 time nor Unix seconds" in by_line[17, "bad_time"].message


def test_nmea_by_format_keyword_and_refused_column_keywords(tmp_path):
    path = tmp_path / "log.txt"  # not an NMEA ending: format says it
    path.write_text("\n".join(nmea_log()[:2]) + "\n")
    data = read_tracks(path, format="nmea", max_speed=30.0, warn=False)
    assert data.tracks[str(FERRY)].times.tolist() == [0.0, 10.0]
    same = read_tracks(path, format="nmea", course="course", speed="speed", speed_unit="knots", warn=False)  # its own names
    assert same.tracks == data.tracks
    with pytest.raises(ValueError, match="lat='Latitude': format 'nmea' has no columns .*MMSI"):
        read_tracks(path, format="nmea", lat="Latitude", lon="Longitude")
    with pytest.raises(ValueError, match="time_unit='ms': format 'nmea' has no columns"):
        read_tracks(path, format="nmea", time_unit="ms")
    with pytest.raises(ValueError, match=r"log.txt: unknown extension '.txt'; expected one of .csv, .csv.gz, .gpx, .nmea, .ais"):
        read_tracks(path)
    with pytest.raises(ValueError, match="format: 'kml'; expected one of"):
        read_tracks(path, format="kml")


@pytest.mark.parametrize(
    "text, message",
    [("", "empty file"), ("time,x,y\n0,1,2\n", "no NMEA sentence in the file .*'time,x,y'")],
)
def test_not_nmea_is_an_error_naming_the_file(tmp_path, text, message):
    path = tmp_path / "bad.ais"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"bad.ais.*{message}"):
        read_tracks(path)


def test_nmea_of_which_no_report_is_left(tmp_path):
    path = tmp_path / "static.nmea"
    path.write_text("\n".join(nmea_log()[2:4]) + "\n")
    with pytest.raises(ValueError, match=r"static.nmea: no report left of 2 lines \(1 not_position\)"):
        read_tracks(path)


# --- DataFrames ---------------------------------------------------------------------------------------------

CSV = """time,MMSI,lat,lon,speed
2016-01-12 13:02:11,235070762,50.7730,-1.0929,5.9
2016-01-12 13:02:21,235070762,50.7731,-1.0928,6.0
2016-01-12 13:02:31,235000001,50.7800,-1.1000,
2016-01-12 13:02:41,235070762,50.7732,-1.0927,6.1
2016-01-12 13:02:41,235070762,50.7732,-1.0927,6.1
"""
COLUMNS = dict(id="MMSI", lat="lat", lon="lon", speed="speed", speed_unit="knots")


def without_messages(data):
    return {key: attrs.evolve(track, problems=[attrs.evolve(p, message="") for p in track.problems]) for key, track in data.tracks.items()}


@pytest.mark.parametrize("times", ["iso", "timestamps", "aware"])
def test_data_frame_reads_as_the_same_csv(tmp_path, times):
    path = tmp_path / "ships.csv"
    path.write_text(CSV)
    expected = read(path, **COLUMNS)
    frame = pd.read_csv(path)
    if times == "timestamps":
        frame["time"] = pd.to_datetime(frame["time"])
    elif times == "aware":
        frame["time"] = pd.to_datetime(frame["time"]).dt.tz_localize("UTC").dt.tz_convert("Europe/Paris")
    got = read(frame, **COLUMNS)
    assert without_messages(got) == without_messages(expected)
    assert got.epoch == expected.epoch == EPOCH and got.origin == expected.origin and got.path == DATA_FRAME
    assert kinds(got) == kinds(expected) == [(4, "not_a_number", "set_nan"), (6, "duplicate_time", "dropped")]  # row + 2
    assert got.problems[0].message == "<DataFrame>:4: column 'speed' holds '', not a finite number; set to NaN"


def test_data_frame_numeric_times_and_refusals():
    frame = pd.DataFrame({"t": [0.0, 1.5, 3.0], "x": [0, 1, 2], "y": [0.0, 0.0, np.nan]})
    data = read(frame, time="t")
    assert data.epoch is None and data.tracks[""].times.tolist() == [0.0, 1.5]
    assert kinds(data) == [(4, "not_a_number", "dropped")]
    with pytest.raises(ValueError, match=r"<DataFrame>:1: no column 'time' in the header; the columns are \['t', 'x', 'y'\]"):
        read_tracks(frame)
    with pytest.raises(ValueError, match="format: 'gpx' is a file format; a DataFrame is read by its columns"):
        read_tracks(frame, time="t", format="gpx")
    with pytest.raises(TypeError, match=r"source: expected a file path \(str or os.PathLike\) or a pandas DataFrame, got list"):
        read_tracks([1, 2])


# --- the optional packages ----------------------------------------------------------------------------------


@pytest.mark.parametrize("module, extra, name, text", [("gpxpy", "gpx", "walk.gpx", GPX_11), ("pyais", "ais", "log.nmea", "!AIVDM")])
def test_a_missing_package_names_its_extra(tmp_path, monkeypatch, module, extra, name, text):
    path = tmp_path / name
    path.write_text(text)
    monkeypatch.setitem(sys.modules, module, None)  # its import now fails
    with pytest.raises(MissingExtraError, match=rf"{name}\) needs the {module} package.*pip install hybridtrack\[{extra}\]") as info:
        read_tracks(path)
    assert isinstance(info.value, ImportError) and isinstance(info.value, ValueError)


def test_read_tracks_export_and_the_reader_config_keys():
    from hybridtrack.io import track_files

    assert hybridtrack.read_tracks is track_files.read_tracks
    assert "format" in CONFIG_KEYS["reader"] and "source" not in CONFIG_KEYS["reader"]
    cfg = load_config(
        {"reader": {"format": "gpx"}, "measurement": {"sigma": 5.0}, "estimator": {"algorithm": "imm", "modes": ["straight"]}}
    )
    assert cfg["reader"]["format"] == "gpx"


# --- hybridtrack track on a GPX file -------------------------------------------------------------------------

TRACK_CONFIG = """
[measurement]
sigma = 5.0

[estimator]
algorithm = "imm"
noise_density = 0.01
modes = ["straight"]
"""


def test_track_command_on_a_gpx_file(tmp_path, capsys):
    points = "\n".join(
        f'<trkpt lat="{50.77 + k * 0.00045:.6f}" lon="-1.09"><time>2016-01-12T13:{2 + k // 6:02d}:{k % 6 * 10:02d}Z</time></trkpt>'
        for k in range(12)
    )
    gpx, cfg, out = tmp_path / "walk.gpx", tmp_path / "c.toml", tmp_path / "out"
    gpx.write_text(
        f'<?xml version="1.0"?>\n<gpx version="1.1" creator="t"><trk><name>north</name><trkseg>\n{points}\n</trkseg></trk></gpx>\n'
    )
    cfg.write_text(TRACK_CONFIG)  # no [reader] at all: the format from the extension
    status = main(["track", str(gpx), "--config", str(cfg), "--out", str(out), "--no-progress", "--geojson"])
    assert status == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert [entry["id"] for entry in summary["objects"]] == ["north"] and summary["problems"] == []
    assert (out / "north.npz").exists() and (out / "north.rrd").stat().st_size > 0
    assert summary["epoch_utc"] == "2016-01-12T13:02:00Z"
    features = json.loads((out / "tracks.geojson").read_text())["features"]
    assert [f["properties"]["kind"] for f in features] == ["track", "segment"]
    lon, lat = np.array(features[0]["geometry"]["coordinates"]).T
    assert np.allclose(lon, -1.09, atol=1e-4) and lat[0] < lat[-1]  # [lon, lat], going north


def test_track_command_on_an_nmea_log_with_geojson(tmp_path, capsys):
    """Raw AIS NMEA to summary.json, .rrd and GeoJSON in one command; the log's type 5 messages are no fault."""
    lines = []
    for k in range(12):
        fields = {**POSITION, "lat": round(50.77 - k * 0.0004, 6), "lon": -1.09, "course": 180.0, "speed": 8.6}
        lines.append(tag_block(f"c:{UNIX + 10 * k}") + sentences(fields)[0])
    lines.insert(3, tag_block(f"c:{UNIX + 25}") + sentences({"type": 5, "mmsi": FERRY, "shipname": "FERRY"}, seq_id=1)[0])
    lines.insert(4, sentences({"type": 5, "mmsi": FERRY, "shipname": "FERRY"}, seq_id=1)[1])
    log, cfg, out = tmp_path / "ais.nmea", tmp_path / "c.toml", tmp_path / "out"
    log.write_text("\n".join(lines) + "\n")
    cfg.write_text(TRACK_CONFIG)
    status = main(["track", str(log), "--config", str(cfg), "--out", str(out), "--no-progress", "--geojson", "--strict"])
    assert status == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert [entry["id"] for entry in summary["objects"]] == [str(FERRY)]
    assert summary["problem_counts"] == {"not_position": 1}
    assert (out / f"{FERRY}.rrd").stat().st_size > 0
    (track, segment) = json.loads((out / "tracks.geojson").read_text())["features"]
    assert track["properties"]["id"] == str(FERRY) and segment["properties"]["mode"] == "straight"


def test_track_file_on_a_data_frame(tmp_path):
    """A DataFrame to summary.json, .rrd and GeoJSON in one call; messages name it <DataFrame>."""
    from hybridtrack.apps.tracking import track_file

    pd = pytest.importorskip("pandas")
    start = pd.Timestamp("2016-01-12 13:02:00", tz="UTC")
    frame = pd.DataFrame(
        {
            "time": [start + pd.Timedelta(seconds=10 * k) for k in range(12)],
            "lat": [50.77 + k * 0.00045 for k in range(12)],
            "lon": [-1.09] * 12,
        }
    )
    cfg = tmp_path / "c.toml"
    cfg.write_text('[reader]\nlat = "lat"\nlon = "lon"\n' + TRACK_CONFIG)
    summary = track_file(frame, cfg, tmp_path / "out", geojson=True)
    assert [entry["id"] for entry in summary["objects"]] == [""] and summary["epoch_utc"] == "2016-01-12T13:02:00Z"
    assert (tmp_path / "out" / "track.rrd").exists() and (tmp_path / "out" / "tracks.geojson").exists()
    with pytest.raises(ValueError, match="--id 'x': no such object in <DataFrame>"):
        track_file(frame, cfg, tmp_path / "out", ids=["x"])
