"""experiments/real_tracks.py run small (two Solent vessels, their first 150 reports): the JSON layout the issue
names, every tracker scored, and the scores where they can be told in advance."""

import importlib.util
import json
from pathlib import Path

import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
TRACKERS = [
    "sprt",
    "fixed_radius_imm",
    "turn_rate_imm",
    "turn_rate_imm_smoothed",
    "ships",
    "ships_smoothed",
    "ships_lag_15s",
    "cv",
    "turn_rate_ekf",
    "turn_rate_ekf_course_speed",
    "always_straight",
]
SCORES = {
    "accuracy",
    "balanced_accuracy",
    "recall",
    "median_onset_delay_s",
    "detected_onsets",
    "false_turns_per_hour",
    "stopped_in_turn",
    "stationary_in_turn",
    "rmse_m",
    "us_per_report",
}


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    spec = importlib.util.spec_from_file_location("_small_real_tracks", EXPERIMENTS / "real_tracks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path = tmp_path_factory.mktemp("real_tracks") / "r.json"
    module.main(["--vessels", "2", "--max-reports", "150", "--json", str(path), "--plot", "--plot-path", str(path.with_suffix(".png"))])
    assert path.with_suffix(".md").read_text().count("\n") == 2 + len(TRACKERS) and path.with_suffix(".png").stat().st_size > 10_000
    return json.loads(path.read_text())


def test_layout_and_every_tracker(small):
    assert set(small) == {"protocol", "rows", "command"}
    assert small["protocol"]["vessels"] == 2 and small["protocol"]["reports"] == 300 and small["protocol"]["sigma_m"] == 10.0
    assert sum(small["protocol"]["labels"].values()) == 300
    assert [row["tracker"] for row in small["rows"]] == TRACKERS
    for row in small["rows"]:
        assert set(row) == SCORES | {"tracker"}, row
        assert 0.0 <= row["accuracy"] <= 1.0 and 0.0 <= row["balanced_accuracy"] <= 1.0
        assert set(row["recall"]) == {"straight", "left_turn", "right_turn", "stop"}


def test_scores_that_are_known_in_advance(small):
    rows = {row["tracker"]: row for row in small["rows"]}
    straight = rows["always_straight"]
    labels = small["protocol"]["labels"]
    assert straight["accuracy"] == pytest.approx(labels["straight"] / 300)
    assert straight["false_turns_per_hour"] == 0.0 and straight["recall"]["straight"] == 1.0
    assert 12.0 < straight["rmse_m"] < 16.5  # the added noise itself: σ √2 = 14.1 m
    assert rows["cv"]["rmse_m"] < straight["rmse_m"]  # a filter beats the raw reports
    for name in ("sprt", "fixed_radius_imm", "cv", "always_straight"):  # no stop mode: never "stop"
        assert rows[name]["recall"]["stop"] in (None, 0.0), name
    assert rows["ships"]["rmse_m"] < rows["turn_rate_imm"]["rmse_m"]  # the reported velocity helps the positions
