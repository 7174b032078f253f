"""Every example runs, at a small size, and writes a valid recording."""

import importlib.util
from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_demo_runs_small_and_writes_a_verified_recording(tmp_path, rerun_cli):
    out = tmp_path / "demo.rrd"
    summary = load("demo").main(["--out", str(out), "--steps-scale", "0.2"])
    assert out.stat().st_size > 0
    assert summary["steps"] == 72
    assert np.isfinite(summary["rmse_known_modes"]) and summary["rmse_known_modes"] < summary["rmse_straight_only"]
    assert np.isfinite(summary["rmse_adaptive"]) and len(summary["segments"]) == 6
    result = rerun_cli("rrd", "verify", out)
    assert result.returncode == 0, result.stderr
    from hybridtrack.recording.inspection import RecordingFile

    entities = set(RecordingFile(out).entity_paths)
    assert {
        "/world/truth",
        "/world/estimate/adaptive",
        "/world/estimate/known_modes",
        "/world/estimate/straight_only",
        "/world/measurements/plotter",
        "/detector/sprt_pairwise/upper",
    } <= entities


def test_demo_full_size_identifies_every_segment(tmp_path):
    summary = load("demo").main(["--out", str(tmp_path / "demo.rrd")])
    assert [row["identified"] for row in summary["segments"]] == [
        "left_turn_r3",
        "right_turn_r5",
        "straight",
        "left_turn_r3",
        "straight",
        "left_turn_r4",
    ]
    assert summary["rmse_known_modes"] < 0.2


def test_example1_unknown_change_runs_small_and_writes_a_verified_recording(tmp_path, rerun_cli):
    out = tmp_path / "example1.rrd"
    summary = load("example1_unknown_change").main(["--out", str(out), "--turn-steps", "15", "--seed", "1"])
    assert summary["steps"] == 36 and summary["max_bank_size"] <= 1 + 2 * 35
    assert out.stat().st_size > 0
    result = rerun_cli("rrd", "verify", out)
    assert result.returncode == 0, result.stderr


def test_monte_carlo_runs_small_and_resumes(tmp_path):
    module = load("monte_carlo")
    args = ["--n", "3", "--executor", "inline", "--steps-scale", "0.1", "--out", str(tmp_path / "mc"), "--no-progress"]
    first = module.main(args)
    assert (first["runs"], first["computed"], first["reused"]) == (3, 3, 0)
    assert 0 < first["rmse_known_modes"] < first["rmse_straight"]
    extended = module.main([*args[:1], "4", *args[2:]])
    assert (extended["computed"], extended["reused"]) == (1, 3)


def test_every_example_is_run_by_a_test():
    """A new script in examples/ needs a small run here (load("name")); a folder needs a test naming it."""
    source = Path(__file__).read_text(encoding="utf-8")
    tests = "".join(p.read_text(encoding="utf-8") for p in Path(__file__).parent.rglob("test_*.py"))
    for script in sorted(EXAMPLES.glob("*.py")):
        assert f'load("{script.stem}")' in source, f"examples/{script.name} is not run by tests/test_examples.py"
    for folder in sorted(p for p in EXAMPLES.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))):
        assert f'"{folder.name}"' in tests, f"examples/{folder.name}/ is not exercised by any test"


def test_bearings_only_runs_small_and_records_bearing_lines_and_solutions(tmp_path, rerun_cli):
    from hybridtrack.recording.inspection import RecordingFile

    out = tmp_path / "tma.rrd"
    summary = load("bearings_only").main(["--out", str(out), "--interval", "20", "--sigma", "0.2"])
    assert summary["solutions"]["levenberg_marquardt"]["range_pct"] < 5
    assert rerun_cli("rrd", "verify", out).returncode == 0
    recording = RecordingFile(out)
    assert {
        "/world/observer",
        "/world/bearings",
        "/world/truth",
        "/world/estimate/levenberg_marquardt",
        "/world/estimate/levenberg_marquardt/ellipse",
        "/solver/n_bearings/residual",
    } <= set(recording.entity_paths)
    steps, lines = recording.strips("world/bearings")
    assert len(steps) == 60 and all(len(step) == 1 and step[0].shape == (2, 2) for step in lines)
    _, residuals = recording.series("solver/levenberg_marquardt/residual")
    assert residuals.shape == (60,) and np.abs(residuals).max() < 1.5  # degrees, σ = 0.2°
    assert len(recording.events()) == 2
