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
    result = rerun_cli("rrd", "verify", out)
    assert result.returncode == 0, result.stderr


def test_example1_unknown_change_runs_small_and_writes_a_verified_recording(tmp_path, rerun_cli):
    out = tmp_path / "example1.rrd"
    summary = load("example1_unknown_change").main(["--out", str(out), "--turn-steps", "15", "--seed", "1"])
    assert summary["steps"] == 36 and summary["max_bank_size"] <= 1 + 2 * 35
    assert out.stat().st_size > 0
    result = rerun_cli("rrd", "verify", out)
    assert result.returncode == 0, result.stderr
