"""Results out as GeoJSON and DataFrames (issue 25): ``hybridtrack track --geojson`` (:mod:`hybridtrack.apps.geojson`),
:meth:`hybridtrack.engine.results.RunResult.to_pandas` and :func:`hybridtrack.apps.tracking.segments_frame`."""

import json
import math
import sys
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from hybridtrack import Gaussian, Pipeline
from hybridtrack.algorithms.multiple_model import MultipleModelEstimator
from hybridtrack.apps.geojson import tracks_geojson
from hybridtrack.apps.tracking import ConfigError, segments_frame, track_file
from hybridtrack.cli import main
from hybridtrack_plugins.sensors.position import PositionSensor

pd = pytest.importorskip("pandas")

LAT0, LON0 = 50.8, -1.2  # the Solent: longitudes near −1.2, latitudes near 50.8, never to be confused
EPOCH = datetime(2016, 1, 12, 13, 0, tzinfo=UTC)
CONFIG = """
[reader]
time = "time"
id = "id"
{columns}
min_reports = 5

[measurement]
sigma = 5.0

[estimator]
algorithm = "imm"
noise_density = 0.001
modes = ["straight", "left_turn"]
radii = [200.0]
sojourn = 60.0
"""
TRACK_PROPERTIES = {"id", "kind", "mode", "start_utc", "end_utc"}
SEGMENT_PROPERTIES = TRACK_PROPERTIES | {"start", "end"}


def ship(count=30, dt=10.0, speed=5.0, radius=200.0):
    """(east, north) m of a ship going east at ``speed`` for half the reports, then turning left on ``radius``."""
    t = np.arange(count) * dt
    half = count // 2
    east, north = speed * t, np.zeros(count)
    angle = speed / radius * (t[half:] - t[half])
    east[half:] = east[half] + radius * np.sin(angle)
    north[half:] = radius * (1.0 - np.cos(angle))
    return t, east, north


def write_files(tmp_path, geographic=True):
    t, east, north = ship()
    rows = ["time,id,lat,lon" if geographic else "time,id,x,y"]
    for name, offset in (("a", 0.0), ("b", 2000.0)):
        for k in range(t.size):
            if geographic:  # a local sphere of 6371 km is enough for a test file
                lat = LAT0 + math.degrees((north[k] + offset) / 6371e3)
                lon = LON0 + math.degrees(east[k] / (6371e3 * math.cos(math.radians(LAT0))))
                stamp = (EPOCH + timedelta(seconds=float(t[k]))).isoformat().replace("+00:00", "Z")
                rows.append(f"{stamp},{name},{lat:.7f},{lon:.7f}")
            else:
                rows.append(f"{t[k]:g},{name},{east[k]:.3f},{north[k] + offset:.3f}")
    csv, cfg = tmp_path / "ships.csv", tmp_path / "c.toml"
    csv.write_text("\n".join(rows) + "\n")
    cfg.write_text(CONFIG.format(columns='lat = "lat"\nlon = "lon"' if geographic else 'x = "x"\ny = "y"'))
    return csv, cfg


def no_nan(text):
    raise ValueError(f"not JSON: {text}")


def test_geojson_of_a_lat_lon_file_is_a_feature_collection_of_tracks_and_segments(tmp_path, capsys):
    csv, cfg = write_files(tmp_path)
    out = tmp_path / "out"
    status = main(["track", str(csv), "--config", str(cfg), "--out", str(out), "--no-progress", "--geojson"])
    assert status == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    collection = json.loads((out / "tracks.geojson").read_text(), parse_constant=no_nan)  # no NaN / Infinity
    assert set(collection) == {"type", "features"} and collection["type"] == "FeatureCollection"
    features = collection["features"]
    assert len(features) == sum(1 + len(o["segments"]) for o in summary["objects"]) and len(summary["objects"]) == 2
    for feature in features:
        assert set(feature) == {"type", "geometry", "properties"} and feature["type"] == "Feature"
        assert set(feature["geometry"]) == {"type", "coordinates"} and feature["geometry"]["type"] == "LineString"
        coordinates = feature["geometry"]["coordinates"]
        assert len(coordinates) >= 2 and all(len(p) == 2 and all(isinstance(v, float) for v in p) for p in coordinates)
        lon, lat = np.array(coordinates).T  # RFC 7946: [longitude, latitude]
        assert np.all(np.abs(lon - LON0) < 0.1) and np.all(np.abs(lat - LAT0) < 0.1)
    for obj in summary["objects"]:
        mine = [f for f in features if f["properties"]["id"] == obj["id"]]
        track, segments = mine[0], mine[1:]
        with np.load(out / f"{obj['id']}.npz") as npz:
            times, lat_lon = npz["times"], npz["lat_lon"]
        assert track["properties"] == {
            "id": obj["id"],
            "kind": "track",
            "mode": None,
            "start_utc": "2016-01-12T13:00:00Z",
            "end_utc": "2016-01-12T13:04:50Z",
        }
        np.testing.assert_allclose(track["geometry"]["coordinates"], lat_lon[:, ::-1], atol=1e-7)
        assert [s["properties"]["kind"] for s in segments] == ["segment"] * len(obj["segments"])
        for feature, segment in zip(segments, obj["segments"]):
            assert set(feature["properties"]) == SEGMENT_PROPERTIES
            assert feature["properties"] == {"id": obj["id"], "kind": "segment"} | {
                k: segment[k] for k in SEGMENT_PROPERTIES - {"id", "kind"}
            }
            coordinates = np.array(feature["geometry"]["coordinates"])
            first, last = np.searchsorted(times, [segment["start"], segment["end"]])
            np.testing.assert_allclose(coordinates, lat_lon[first : last + 1, ::-1], atol=1e-7)  # to the next one's start
        for a, b in zip(segments, segments[1:]):  # segments end where the next starts
            assert a["geometry"]["coordinates"][-1] == b["geometry"]["coordinates"][0]
        assert segments[0]["geometry"]["coordinates"][0] == track["geometry"]["coordinates"][0]
        assert segments[-1]["geometry"]["coordinates"][-1] == track["geometry"]["coordinates"][-1]
        assert {s["properties"]["mode"] for s in segments} <= {"straight", "left_turn"}


def test_a_segment_of_one_report_ends_at_the_next_report_and_the_last_one_repeats_its_point(tmp_path):
    """Hand-made outputs: reports at 0, 10, 20, 30 s; segments [0, 10] straight, [10, 20] left (one report), [20, 30]
    straight, and [30, 30] left (the mode changes at the last report: one report, no next one)."""
    lat_lon = np.array([[50.0, -1.0], [50.1, -1.1], [50.2, -1.2], [50.3, -1.3]])
    np.savez(tmp_path / "x_1.npz", times=np.array([0.0, 10.0, 20.0, 30.0]), lat_lon=lat_lon)
    cuts = [(0.0, 10.0, "straight"), (10.0, 20.0, "left_turn"), (20.0, 30.0, "straight"), (30.0, 30.0, "left_turn")]
    summary = {
        "objects": [{"id": "x 1", "output": "x_1", "segments": [{"start": a, "end": b, "mode": m, "radius": None} for a, b, m in cuts]}]
    }
    track, *segments = tracks_geojson(summary, tmp_path)["features"]  # the id's file name: x_1.npz
    assert track["geometry"]["coordinates"] == [[-1.0, 50.0], [-1.1, 50.1], [-1.2, 50.2], [-1.3, 50.3]]
    assert track["properties"] == {"id": "x 1", "kind": "track", "mode": None, "start_utc": None, "end_utc": None}
    assert [s["geometry"]["coordinates"] for s in segments] == [
        [[-1.0, 50.0], [-1.1, 50.1]],
        [[-1.1, 50.1], [-1.2, 50.2]],
        [[-1.2, 50.2], [-1.3, 50.3]],
        [[-1.3, 50.3], [-1.3, 50.3]],
    ]
    assert segments[1]["properties"] == {
        "id": "x 1",
        "kind": "segment",
        "mode": "left_turn",
        "start": 10.0,
        "end": 20.0,
        "start_utc": None,
        "end_utc": None,
    }


def test_tracks_geojson_refuses_outputs_without_lat_lon(tmp_path):
    np.savez(tmp_path / "a.npz", times=np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match=r"a\.npz: no lat_lon"):
        tracks_geojson({"objects": [{"id": "a", "output": "a", "segments": []}]}, tmp_path)
    with pytest.raises(FileNotFoundError, match="object 'b': no such output file"):
        tracks_geojson({"objects": [{"id": "b", "output": "b", "segments": []}]}, tmp_path)
    with pytest.raises(ValueError, match="summary: expected track_file's summary"):
        tracks_geojson([], tmp_path)


def test_geojson_of_an_x_y_file_is_refused_before_tracking(tmp_path, capsys):
    csv, cfg = write_files(tmp_path, geographic=False)
    out = tmp_path / "out"
    status = main(["track", str(csv), "--config", str(cfg), "--out", str(out), "--no-progress", "--geojson"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "--geojson needs latitude/longitude positions" in err and "ships.csv was read as x/y metres" in err
    assert not out.exists()  # nothing tracked, nothing written
    with pytest.raises(ConfigError, match="--geojson needs latitude/longitude"):
        track_file(csv, cfg, out, geojson=True)


def test_segments_frame_has_a_row_per_segment(tmp_path):
    csv, cfg = write_files(tmp_path)
    summary = track_file(csv, cfg, tmp_path / "out")
    frame = segments_frame(summary)
    segments = [(o["id"], s) for o in summary["objects"] for s in o["segments"]]
    assert list(frame.columns) == ["id", *summary["objects"][0]["segments"][0]]
    assert list(frame.columns[-2:]) == ["start_utc", "end_utc"] and len(frame) == len(segments)
    assert list(frame["id"]) == [i for i, _ in segments] and list(frame["mode"]) == [s["mode"] for _, s in segments]
    np.testing.assert_array_equal(frame["end"], [s["end"] for _, s in segments])
    assert segments_frame(tmp_path / "out" / "summary.json").equals(frame)  # summary.json read back: the same table
    empty = segments_frame({"objects": []})
    assert len(empty) == 0 and list(empty.columns)[:3] == ["id", "start", "end"]
    with pytest.raises(ValueError, match="summary: expected track_file's summary.*got keys"):
        segments_frame({"tracks": []})


SENSORS = [PositionSensor(name="a")]
PRIOR = Gaussian(np.array([0.0, 0.0, 0.0, 2.0]), np.eye(4))


def measurements(steps=12, tau=0.1):
    rng = np.random.default_rng(4)
    y = 2.0 * tau * np.arange(steps)
    return {"a": np.column_stack([np.zeros(steps), y]) + rng.normal(0.0, 0.1, (steps, 2))}


def test_to_pandas_of_a_fixed_bank_is_long_with_a_filter_column():
    run = Pipeline(
        models=["straight", ("left_turn", {"radius": 3.0})],
        estimator="kalman",
        sensors=SENSORS,
        measurements=measurements(),
        prior=PRIOR,
        tau=0.1,
    ).run()
    frame = run.to_pandas()
    assert run.means.shape == (12, 2, 4) and run.mode is None
    assert list(frame.columns) == ["time", "filter", "x", "vx", "y", "vy"] and len(frame) == 24  # no covariance, no mode
    assert list(frame["filter"][:2]) == list(run.modes) == ["straight", "left_turn_r3"]
    for j, name in enumerate(run.modes):
        rows = frame[frame["filter"] == name]
        np.testing.assert_array_equal(rows["time"], run.times)
        np.testing.assert_array_equal(rows[list(run.layout)].to_numpy(), run.means[:, j])
    frame.loc[0, "x"] = 99.0  # a copy: the pipeline's read-only arrays are untouched
    assert run.means[0, 0, 0] != 99.0


def test_to_pandas_of_a_multiple_model_run_has_the_followed_mode():
    estimator = MultipleModelEstimator(["straight", ("left_turn", {"radius": 3.0})], sojourn=1.0, sensors=SENSORS, tau=0.1)
    run = estimator.run(measurements(), PRIOR)
    frame = run.to_pandas()
    assert list(frame.columns) == ["time", *run.layout, "mode"] and len(frame) == run.steps
    np.testing.assert_array_equal(frame["time"], run.times)
    np.testing.assert_array_equal(frame[list(run.layout)].to_numpy(), run.means)
    assert list(frame["mode"]) == [run.modes[i] for i in run.mode]


def test_without_pandas_the_frames_say_how_to_install_it(monkeypatch):
    run = MultipleModelEstimator(["straight"], sojourn=1.0, sensors=SENSORS, tau=0.1).run(measurements(), PRIOR)
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas now fails
    with pytest.raises(ImportError, match=r"RunResult\.to_pandas needs pandas.*pip install hybridtrack\[pandas\]"):
        run.to_pandas()
    with pytest.raises(ImportError, match=r"segments_frame needs pandas.*pip install hybridtrack\[pandas\]"):
        segments_frame({"objects": []})


def test_a_recording_of_motion_segments_shows_the_summary_modes_as_lanes(tmp_path):
    """``[segments] by = "motion"``: the recording has the summary's modes (straight, left_turn …) as a lane panel of
    their own beside the models' probabilities, one named lane per mode of the summary's segments."""
    from hybridtrack.recording.inspection import RecordingFile

    csv, cfg = write_files(tmp_path, geographic=False)
    config = cfg.read_text().replace('modes = ["straight", "left_turn"]\nradii = [200.0]', 'modes = ["straight", "coordinated_turn"]')
    cfg.write_text(config + '\n[segments]\nby = "motion"\n', encoding="utf-8")
    summary = track_file(csv, cfg, tmp_path / "out")
    (entry,) = [o for o in summary["objects"] if o["id"] == "a"]
    modes = list(dict.fromkeys(s["mode"] for s in entry["segments"]))
    assert "left_turn" in modes and "straight" in modes
    steps, lanes = RecordingFile(tmp_path / "out" / "a.rrd").series("estimator/track/segment")
    lanes = np.atleast_2d(lanes.T).T
    assert lanes.shape == (30, len(modes))
    assert (np.isfinite(lanes).sum(axis=1) == 1).all()  # every report in exactly one lane
