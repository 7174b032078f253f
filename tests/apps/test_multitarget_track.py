"""``hybridtrack track`` on unlabelled detections ([association]): the examples on a time,x,y file and on Solent."""

import csv
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from hybridtrack import gospa_over_time
from hybridtrack.apps.multitarget import track_detections
from hybridtrack.apps.tracking import ConfigError, track_file
from hybridtrack.cli import main
from hybridtrack.recording.inspection import RecordingFile

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "data" / "multitarget" / "crossing_scene.csv"
TRUTH = ROOT / "data" / "multitarget" / "crossing_scene_truth.csv"
SOLENT = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _gospa(rows):
    truth = np.loadtxt(TRUTH, delimiter=",", skiprows=1)
    time = np.array([float(r["time"]) for r in rows])
    ids = np.array([int(r["track_id"]) for r in rows])
    xy = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    return gospa_over_time(truth[:, 0], truth[:, 1].astype(int), truth[:, 2:], time, ids, xy, c=100.0)


@pytest.mark.parametrize("example", ["multitarget.toml", "multitarget_modes.toml"])
def test_the_examples_track_a_file_of_detections(tmp_path, example):
    out = tmp_path / "out"
    assert main(["track", str(SCENE), "--config", str(ROOT / "examples" / example), "--out", str(out), "--no-progress"]) == 0
    rows = _rows(out / "tracks.csv")
    assert list(rows[0]) == ["time", "track_id", "x", "y", "vx", "vy", "mode"]
    keys = [(r["time"], r["track_id"]) for r in rows]
    assert len(keys) == len(set(keys))  # one row per scan per track
    summary = json.loads((out / "summary.json").read_text())
    assert sorted(o["id"] for o in summary["objects"]) == sorted({r["track_id"] for r in rows})
    assert all(o["segments"] for o in summary["objects"] if o["detections"] >= 3)
    assert {r["mode"] for r in rows} <= {"straight", "left_turn", "right_turn", "stop"}
    series = _gospa(rows)
    assert series.distance.mean() < 200.0 and series.track_quality().id_switches <= 4
    paths = set(RecordingFile(out / "tracks.rrd").entity_paths)
    assert "/world/detections" in paths
    assert {f"/world/tracks/{o['id']}" for o in summary["objects"]} <= paths


def test_the_solent_file_without_its_ids(tmp_path):
    config = tomllib.loads((ROOT / "examples" / "multitarget.toml").read_text())
    config["reader"] = {"time": "Time", "lat": "Latitude_degrees", "lon": "Longitude_degrees", "max_speed": 30.0}
    config["association"].pop("scan")
    config["association"] |= {"scan_window": 10.0, "updates_per_scan": 4, "detection_probability": 0.5, "max_coast": 600.0}
    head = tmp_path / "solent_head.csv"
    head.write_text("".join(SOLENT.read_text().splitlines(keepends=True)[:2500]))  # the first ≈ 10 minutes
    summary = track_detections(head, config, tmp_path / "out")
    rows = _rows(tmp_path / "out" / "tracks.csv")
    assert list(rows[0])[-2:] == ["lat", "lon"]
    lat = np.array([float(r["lat"]) for r in rows])
    assert np.all((lat > 50.4) & (lat < 51.1))  # the Solent
    assert summary["epoch_utc"].startswith("2016-01-12T13:")
    assert len(summary["objects"]) > 10


def test_configuration_faults_are_named(tmp_path, capsys):
    config = tomllib.loads((ROOT / "examples" / "multitarget.toml").read_text())
    with pytest.raises(ConfigError, match=r"\[reader\] id"):
        track_detections(SCENE, config | {"reader": config["reader"] | {"id": "target"}}, tmp_path)
    with pytest.raises(ConfigError, match="scan_window"):
        track_detections(SCENE, config | {"association": config["association"] | {"scan_window": 5.0}}, tmp_path)
    with pytest.raises(ConfigError, match="method"):
        track_detections(SCENE, config | {"association": config["association"] | {"method": "pmht"}}, tmp_path)
    course = config["reader"] | {"course": "vx", "speed": "vy"}
    with pytest.raises(ConfigError, match=r"\[reader\] course = 'vx' with \[association\].*speed_sigma"):
        track_detections(SCENE, config | {"reader": course}, tmp_path)
    mht = config["association"] | {"method": "mht", "duplicate_probability": 0.9}
    with pytest.raises(ConfigError, match="duplicate_probability is for method"):
        track_detections(SCENE, config | {"association": mht}, tmp_path)
    mht = config["association"] | {"method": "mht", "reacquire_window": 600.0}
    with pytest.raises(ConfigError, match="reacquire_window is for method"):
        track_detections(SCENE, config | {"association": mht}, tmp_path)
    with pytest.raises(ConfigError, match="reacquire_window = -1.0"):
        track_detections(SCENE, config | {"association": config["association"] | {"reacquire_window": -1.0}}, tmp_path)
    with pytest.raises(ConfigError, match="duplicate_probability"):
        track_detections(SCENE, config | {"association": config["association"] | {"duplicate_probability": 1.0}}, tmp_path)
    with pytest.raises(ConfigError, match="track_detections"):
        track_file(SCENE, config, tmp_path)
    example = str(ROOT / "examples" / "multitarget.toml")
    assert main(["track", str(SCENE), "--config", example, "--out", str(tmp_path / "o"), "--geojson"]) == 2
    assert "--geojson with [association]" in capsys.readouterr().err


def test_the_solent_example_runs_on_the_file_as_written(tmp_path):
    """examples/multitarget_solent.toml unchanged on the first ≈ 10 minutes of the file: moored ships (the stop mode)
    and moving ones each get a track, in lat/lon."""
    head = tmp_path / "solent_head.csv"
    head.write_text("".join(SOLENT.read_text().splitlines(keepends=True)[:2500]))
    out = tmp_path / "out"
    assert (
        main(["track", str(head), "--config", str(ROOT / "examples" / "multitarget_solent.toml"), "--out", str(out), "--no-progress"]) == 0
    )
    rows = _rows(out / "tracks.csv")
    assert list(rows[0])[-2:] == ["lat", "lon"]
    summary = json.loads((out / "summary.json").read_text())
    assert 30 < len(summary["objects"]) < 100  # 78 vessels report in these minutes (60 tracks when written)
    assert {r["mode"] for r in rows} >= {"stop", "straight"}
