"""experiments/aircraft_tracks.py run small (three flights): examples/aircraft.toml tracks an x/y file after only its
[reader] table is replaced, and the scores have the layout the note quotes."""

import importlib.util
import json
import tomllib
from pathlib import Path

import numpy as np

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def _module():
    spec = importlib.util.spec_from_file_location("_small_aircraft_tracks", EXPERIMENTS / "aircraft_tracks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_only_the_reader_table_changes(tmp_path):
    module = _module()
    changed = tomllib.loads(module.config_for_xy(tmp_path / "a.toml").read_text())
    original = tomllib.loads(module.AIRCRAFT.read_text())
    assert changed["reader"] == {"time": "time", "id": "flight", "x": "x", "y": "y", "min_reports": 20}
    assert {k: v for k, v in changed.items() if k != "reader"} == {k: v for k, v in original.items() if k != "reader"}


def test_flights_turn_at_varying_rate_and_are_tracked(tmp_path):
    module = _module()
    times, position, velocity, modes = module.flight(np.random.default_rng(0))
    speed = np.hypot(*velocity.T)
    assert np.allclose(speed, speed[0]) and set(modes) <= {"straight", "left_turn", "right_turn"}
    heading = np.unwrap(np.arctan2(velocity[:, 1], velocity[:, 0]))
    rate = np.diff(heading) / np.diff(times)
    turning = rate[np.abs(rate) > 1e-9]
    assert np.ptp(np.abs(turning)) > 0.5 * np.abs(turning).max()  # the rate ramps: not one radius
    path = tmp_path / "a.json"
    result = module.main(["--flights", "3", "--json", str(path)])
    assert json.loads(path.read_text())["protocol"]["flights"] == 3
    for key in ("causal", "smoothed", "turn_rate_ekf"):
        row = result[key]
        assert 0.0 <= row["accuracy"] <= 1.0 and set(row["recall"]) <= {"straight", "left_turn", "right_turn"}, row
    for key in ("causal", "smoothed"):
        assert result[key]["rmse_m"] < 120.0, result[key]  # σ = 30 m plus the along-track jitter
