"""experiments/imm_vs_sprt.py (issue #15 item 5): the JSON layout, run small, and the references it relies on."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
KEYS = {"dataset", "method", "rmse", "rmse_manoeuvre", "mode_accuracy", "median_delay_s", "false_changes_per_hour", "us_per_step"}


def load(name):
    spec = importlib.util.spec_from_file_location(f"_small_{name}", EXPERIMENTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_script_small_writes_the_agreed_json_layout(tmp_path):
    out = tmp_path / "imm_vs_sprt.json"
    png = tmp_path / "imm_vs_sprt.png"
    args = ["--json", str(out), "--R", "0.1", "--n-seed001", "1", "--steps-scale", "0.1", "--n-example1", "2"]
    load("imm_vs_sprt").main(args + ["--vessels", "1", "--draws", "1", "--solent-max-steps", "25", "--plot", "--plot-path", str(png)])
    report = json.loads(out.read_text())
    assert set(report) == {"rows", "protocol"}
    rows = report["rows"]
    assert {r["dataset"] for r in rows} == {"seed001_R0.1", "example1", "solent"}
    assert {r["method"] for r in rows} == {"known_switch", "unknown_change", "imm", "gpb2", "cv"}
    assert len(rows) == 15
    for row in rows:
        assert KEYS <= set(row), sorted(KEYS - set(row))
        assert isinstance(row["dataset"], str) and isinstance(row["method"], str)
        for key in ("rmse", "mode_accuracy", "false_changes_per_hour", "us_per_step"):
            assert isinstance(row[key], float) and np.isfinite(row[key]) and row[key] >= 0, (key, row)
        assert row["median_delay_s"] is None or row["median_delay_s"] >= 0
        assert 0.0 <= row["mode_accuracy"] <= 1.0
    cv = [r for r in rows if r["method"] == "cv"]
    assert all(r["median_delay_s"] is None for r in cv)  # a CV filter never decides a turn
    assert "command" in report["protocol"] and "settings" in report["protocol"]
    assert out.with_suffix(".md").read_text().startswith("### SPRT banks vs IMM")
    assert png.stat().st_size > 10_000


def test_cv_baseline_is_the_kalman_filter_of_filterpy():
    """The CV row is a one-model MultipleModelEstimator (Π = [[1]]): exactly filterpy's KF with F, Q = G q Gᵀ."""
    kalman = pytest.importorskip("filterpy.kalman")
    module = load("imm_vs_sprt")
    cases = module.example1_cases(1, 3)
    case = cases[0]
    (positions, types, _, probs) = module.run_cv(cases, 0.05)[0]
    assert set(types) == {"straight"} and probs is None
    kf = kalman.KalmanFilter(dim_x=4, dim_z=2)
    tau = 0.1
    kf.F = np.kron(np.eye(2), [[1.0, tau], [0.0, 1.0]])
    G = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    kf.Q = G @ (0.05 * np.eye(2)) @ G.T
    kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    kf.R = 0.01 * np.eye(2)
    kf.x, kf.P = case.prior[0].copy(), case.prior[1].copy()
    kf.update(case.z[0])
    expected = [kf.x[[0, 2]].copy()]
    for k in range(1, len(case.times)):
        kf.predict()
        kf.update(case.z[k])
        expected.append(kf.x[[0, 2]].copy())
    np.testing.assert_allclose(positions, np.array(expected), atol=1e-9)


def test_scores_by_hand():
    """A 6-step case: straight, then a left turn from step 3; decisions hand-placed."""
    module = load("imm_vs_sprt")
    times = np.arange(6.0)
    truth = np.zeros((6, 2))
    positions = truth.copy()
    positions[1:, 0] = [1.0, 0.0, 2.0, 0.0, 0.0]  # squared errors 1, 0, 4, 0, 0
    types = ["straight", "straight", "straight", "left_turn", "left_turn", "left_turn"]
    case = module.Case("hand", times, truth, truth, types, None, [], {})
    assert case.changes == [3] and case.change_times == [2.0] and case.segments() == [2, 3]
    decided = ["straight", "straight", "right_turn", "straight", "left_turn", "left_turn"]
    s = module.score_run(case, positions, decided, 0.5, None, window=3.0)
    assert s["se"] == 5.0 and s["n"] == 5 and s["se_turn"] == 4.0 and s["n_turn"] == 3
    assert s["delays"] == [2.0]  # left turn decided at step 4, change at t = 2
    assert s["hits"] == 3 and s["scored"] == 5  # steps 1, 4, 5
    assert s["false"] == 2  # to right_turn at 2 (before the change), back to straight at 3 (not the reference)
    row = module.row_of("hand", "x", [s])
    assert row["rmse"] == pytest.approx(1.0) and row["rmse_manoeuvre"] == pytest.approx(np.sqrt(4 / 3))
    assert row["false_changes_per_hour"] == pytest.approx(2 / (5 / 3600))
    assert row["us_per_step"] == pytest.approx(1e5)
    # with type probabilities (IMM): the onset is detected when the turn's probability passes 0.9
    probs = np.tile([0.8, 0.1, 0.1], (6, 1))
    probs[5] = [0.05, 0.95, 0.0]
    s = module.score_run(case, positions, decided, 0.5, probs, window=3.0)
    assert s["delays"] == [3.0]


def test_type_probabilities_sum_the_modes_of_a_type():
    module = load("imm_vs_sprt")
    labels = ("straight", "left_turn_r1", "left_turn_r2", "right_turn_r1")
    mu = np.array([[0.1, 0.2, 0.3, 0.4]])
    np.testing.assert_allclose(module.type_probabilities(np.log(mu), labels), [[0.1, 0.5, 0.4]])


def test_solent_thinning_and_noise():
    """Irregular 5–30 s (at least) intervals from the 2–10 s AIS reports; measurement errors of σ = 25 m."""
    module = load("imm_vs_sprt")
    from hybridtrack.apps.tracking import load_config

    vessels = module.solent_vessels(1)
    assert vessels and len(vessels[0][1]) > 50
    cases = module.solent_cases(vessels, 3, 0, load_config(module.SHIPS))
    dt = np.concatenate([np.diff(c.times) for c in cases])
    assert dt.min() >= 5.0 and np.median(dt) < 35.0
    errors = np.concatenate([c.z - c.truth for c in cases])
    assert errors.std() == pytest.approx(25.0, rel=0.15)
    assert all("stop" not in c.types for c in cases)
