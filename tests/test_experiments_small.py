"""The seed 003 dynamic-threshold and the unknown-change-time reproduction scripts, run small (issue 7)."""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def load(name):
    spec = importlib.util.spec_from_file_location(f"_small_{name}", EXPERIMENTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_ship_truth_straight_then_a_slowing_circulation_of_the_given_diameter():
    dt = load("dynamic_threshold")
    p = {k: dt.DEFAULTS[k] for k in dt.SCENARIO_KEYS}
    p.update(straight=100.0, turn=300.0)
    truth = dt.ship_truth(np.random.default_rng(0), 3, **p)
    speed = np.hypot(truth[..., 2], truth[..., 3])
    np.testing.assert_allclose(speed[:, :101], p["speed"], rtol=1e-12)
    v_end = p["speed"] * (1 - p["speed_loss"] * (1 - math.exp(-300.0 / p["loss_time"])))
    np.testing.assert_allclose(speed[:, -1], v_end, rtol=1e-9)
    course = np.unwrap(np.arctan2(truth[..., 3], truth[..., 2]), axis=1)
    np.testing.assert_allclose(np.diff(course[:, :101], axis=1), 0.0, atol=1e-12)
    rate = np.abs(np.diff(course[:, -20:], axis=1)) / p["tau"]  # steady circulation: ω = v / (D/2)
    np.testing.assert_allclose(rate, v_end / (p["diameter"] / 2), rtol=1e-3)
    step = np.hypot(*np.diff(truth[:, -2:, :2], axis=1)[:, 0].T)  # chord of an arc of length v τ
    np.testing.assert_allclose(step, v_end * p["tau"], rtol=1e-3)


def test_dynamic_threshold_script_small(tmp_path):
    out = tmp_path / "dt.json"
    load("dynamic_threshold").main(
        [
            "--json",
            str(out),
            "--sigma",
            "3",
            "15",
            "--batches",
            "1",
            "--batch",
            "4",
            "--independent-batches",
            "1",
            "--calibration-runs",
            "100",
            "--turn",
            "60",
            "--executor",
            "inline",
            "--out",
            str(tmp_path / "runs"),
            "--no-progress",
        ]
    )
    written = json.loads(out.read_text())
    rows = written["rows"]
    assert [(r["sigma_noise"], r["threshold"]) for r in rows] == [
        (3.0, "calibrated"),
        (15.0, "calibrated"),
        (3.0, "independent"),
        (15.0, "independent"),
    ]
    for r in rows:
        assert r["runs"] == 4 and 0 <= r["detected_static"] <= r["detected_dynamic"] <= 1
        assert r["delay_dynamic"] is None or r["delay_static"] is None or r["delay_dynamic"] <= r["delay_static"] + 60
        assert 0 <= r["cue_straight"] <= 1 and 0 <= r["cue_turn"] <= 1
    assert rows[0]["seed_gain"] == 1.09 and rows[1]["seed_gain"] == 2.308
    # thresholds from independent N(0,1) input on the autocorrelated ω̂: many more false alarms
    assert rows[2]["false_alarms_per_hour_static"] > 10 * max(rows[0]["false_alarms_per_hour_static"], 1.0)
    assert written["protocol"]["detector"]["alpha_1"] == pytest.approx(0.01)
    assert "seed's gain" in out.with_suffix(".md").read_text()


def test_seed001_unknown_change_script_small(tmp_path):
    out = tmp_path / "uc.json"
    load("seed001_unknown_change").main(
        [
            "--json",
            str(out),
            "--n",
            "2",
            "--R",
            "0.01",
            "--steps-scale",
            "0.3",
            "--modes",
            "table1",
            "--bank-size",
            "12",
            "--executor",
            "inline",
            "--out",
            str(tmp_path / "runs"),
            "--no-progress",
        ]
    )
    written = json.loads(out.read_text())
    (row,) = written["rows"]
    assert row["R"] == 0.01 and row["runs"] == 2 and len(row["detection_delay"]) == 6 and len(row["detected"]) == 6
    assert 0 < row["optimal_nrmse"] < row["known_switch_nrmse"] and 0 < row["optimal_nrmse"] < row["unknown_change_nrmse"]
    assert row["max_bank"] <= 12 + 6 + 1 and 0 <= row["modes_correct"] <= 1
    assert all(d is None or 0 < d <= 23 for d in row["detection_delay"])  # inside its (scaled) segment
    assert written["protocol"]["modes"] == {"set": "table1", "r_min": 3.0, "r_max": 5.0, "n": 3, "count": 7}
