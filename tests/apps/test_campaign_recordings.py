"""Recordings of a campaign: ``hybridtrack run … --record K`` replays chosen runs with a recorder, ``--summary-recording``."""

import json
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.experiment import ResultStore
from hybridtrack.apps.experiment.definition import load_experiment
from hybridtrack.apps.experiment.recordings import (
    accepts_recorder,
    check_run_indices,
    choose_runs,
    read_summary_recording,
    record_runs,
    run_recording_path,
    write_summary_recording,
)
from hybridtrack.cli import main
from hybridtrack.recording.inspection import RecordingFile

TOY = Path(__file__).with_name("_toy_experiments.py")
SMALL = ["--executor", "inline", "--param", "steps_scale=0.05", "--no-progress"]


def test_choose_runs_spreads_k_indices_evenly_first_and_last_included():
    assert choose_runs(10, 3) == [0, 4, 9]  # round(linspace(0, 9, 3)) = round([0, 4.5, 9]), half to even
    assert choose_runs(100, 5) == [0, 25, 50, 74, 99]
    assert choose_runs(7, 1) == [0]
    assert choose_runs(4, 10) == [0, 1, 2, 3]  # more than n: every run
    assert check_run_indices([5, 2, 5], 6) == [2, 5]
    with pytest.raises(ValueError, match="record_runs: run index 6"):
        check_run_indices([6], 6)
    with pytest.raises(ValueError, match="record"):
        choose_runs(5, 0)


def test_only_experiments_taking_a_recorder_can_record():
    assert accepts_recorder(load_experiment("demo_rmse"))
    assert not accepts_recorder(load_experiment(f"{TOY}:DRAWS"))
    with pytest.raises(TypeError, match="no 'recorder' keyword"):
        record_runs(f"{TOY}:DRAWS", [0], "unused", seed=0, parameters={"size": 3})


def test_cli_records_the_chosen_runs_and_a_summary(tmp_path, capsys, rerun_cli):
    out = tmp_path / "demo"
    args = ["run", "demo_rmse", "--n", "5", "--seed", "3", "--out", str(out), *SMALL, "--record", "2", "--summary-recording", "--json"]
    assert main(args) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["recordings"] == {"0": str(run_recording_path(out / "recordings", 0)), "4": str(out / "recordings" / "run_00004.rrd")}
    assert report["summary_recording"] == str(out / "summary.rrd")
    stored = ResultStore(out).load()

    # each recording is the stored run: same seed, so the logged estimate gives the stored squared error
    for index, path in report["recordings"].items():
        recording = RecordingFile(path)
        assert recording.configuration == {
            "experiment": "demo_rmse",
            "campaign_seed": 3,
            "run": int(index),
            "parameters": {"R": 0.01, "q": 0.001, "tau": 0.1, "steps_scale": 0.05},
        }
        assert {"/world/truth", "/world/measurements/sensor", "/world/estimate/known_modes"} <= set(recording.entity_paths)
        steps, truth = recording.points("world/truth")
        _, estimate = recording.points("world/estimate/known_modes")
        position_error = np.sum((estimate[1:] - truth[1:]) ** 2, axis=0)  # x and y (float32 in the file)
        np.testing.assert_allclose(position_error, stored["squared_error"][int(index)][[0, 2]], rtol=1e-4)
        assert rerun_cli("rrd", "verify", path).returncode == 0

    # the summary: every scalar result over the run index, a (4,) result as four series
    series = read_summary_recording(out / "summary.rrd")
    assert sorted(series) == ["mean_nis", "nrmse", "squared_error", "steps"]
    runs, nrmse = series["nrmse"]
    np.testing.assert_array_equal(runs, np.arange(5))
    np.testing.assert_array_equal(nrmse, stored["nrmse"])
    np.testing.assert_array_equal(series["squared_error"][1], stored["squared_error"])
    assert rerun_cli("rrd", "verify", out / "summary.rrd").returncode == 0


def test_record_runs_replays_the_stored_results_exactly(tmp_path):
    from hybridtrack.apps.experiment import run_campaign

    parameters = {"R": 0.1, "q": 0.001, "tau": 0.1, "steps_scale": 0.05}
    result = run_campaign("demo_rmse", 3, tmp_path / "c", seed=9, executor="inline", progress=False, parameters=parameters)
    written = record_runs("demo_rmse", [1, 2], tmp_path / "rec", seed=9, parameters=parameters)
    for index, (path, replayed) in written.items():
        assert path == tmp_path / "rec" / f"run_{index:05d}.rrd" and path.is_file()
        for name, value in replayed.items():
            np.testing.assert_array_equal(value, result.arrays[name][index], err_msg=name)


def test_summary_recording_leaves_out_higher_rank_results_and_needs_the_index(tmp_path):
    arrays = {"index": np.arange(3), "a": np.array([1.0, 2.0, 3.0]), "m": np.zeros((3, 2, 2))}
    assert write_summary_recording(arrays, tmp_path / "s.rrd", {"experiment": "x"}) == ["m"]
    assert list(read_summary_recording(tmp_path / "s.rrd")) == ["a"]
    with pytest.raises(ValueError, match="index"):
        write_summary_recording({"a": np.ones(3)}, tmp_path / "t.rrd", {})


def test_cli_record_errors_are_one_line_and_computed_nothing(tmp_path, capsys):
    out = tmp_path / "toy"
    assert main(["run", f"{TOY}:DRAWS", "--n", "3", "--out", str(out), "--executor", "inline", "--record", "1"]) == 2
    error = capsys.readouterr().err
    assert "--record" in error and "recorder" in error and len(error.strip().splitlines()) == 1
    assert not any(out.glob("*.npz"))
    assert main(["run", "demo_rmse", "--n", "3", "--out", str(out), *SMALL, "--record-runs", "1,7"]) == 2
    assert "run index 7" in capsys.readouterr().err
    assert main(["run", "demo_rmse", "--record", "2", "--record-runs", "1"]) == 2
    assert "not allowed with" in capsys.readouterr().err
    assert main(["run", "demo_rmse", "--record-runs", "a,b"]) == 2
    assert "run indices" in capsys.readouterr().err


def test_a_replay_that_differs_from_the_stored_run_is_reported(tmp_path, capsys):
    out = tmp_path / "impure"
    assert main(["run", f"{TOY}:IMPURE", "--n", "2", "--out", str(out), "--executor", "inline", "--record-runs", "1"]) == 0
    captured = capsys.readouterr()
    assert "warning: the recording of run 1" in captured.err and "outside the generator" in captured.err
    assert (out / "recordings" / "run_00001.rrd").is_file()
