"""Recordings: round trip, validity after errors, determinism, offline inspection."""

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule
from hybridtrack.inspection import RecordingFile, format_summary
from hybridtrack.pipeline import Pipeline
from hybridtrack.recording import NullRecorder, RerunRecorder, ellipse_outlines, open_recorder, recording_id
from hybridtrack.simulate import simulate
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])


def run(path, seed=3, steps=40):
    schedule = Schedule.from_rows([("straight", steps // 2), ("right_turn", steps // 2, 5.0)])
    sensors = [PositionSensor(name="a")]
    with RerunRecorder(path, {"seed": seed, "steps": steps}) as recorder:
        truth, z = simulate(schedule, X0, 0.1, sensors, seed=seed, recorder=recorder)
        pipeline = Pipeline(
            models=["straight", ("right_turn", {"radius": 5.0})],
            estimator="kalman",
            sensors=sensors,
            measurements=z,
            prior=Gaussian(X0, np.eye(4)),
            tau=0.1,
            recorder=recorder,
        )
        result = pipeline.run()
        recorder.log_event(7, "a decision", 0.7)
    return truth, z, result


def test_round_trip_is_exact_for_float64_series_and_float32_for_positions(tmp_path, rerun_cli):
    path = tmp_path / "run.rrd"
    truth, z, result = run(path)
    rec = RecordingFile(path)
    steps, nis = rec.series("estimator/straight/nis")
    assert np.array_equal(steps, np.arange(41))
    assert np.array_equal(nis, result.nis[:, 0])  # float64 exactly
    _, loglik = rec.series("/estimator/right_turn_r5/loglik")
    assert np.array_equal(loglik, result.loglik[:, 1])
    _, innovation = rec.series("estimator/straight/innovation")
    assert np.array_equal(innovation, result.innovations[:, 0])
    _, positions = rec.points("world/truth")
    np.testing.assert_allclose(positions, truth.positions, rtol=np.finfo(np.float32).eps, atol=1e-6)
    _, measured = rec.points("world/measurements/a")
    np.testing.assert_allclose(measured, z["a"], rtol=np.finfo(np.float32).eps, atol=1e-6)
    _, ellipses = rec.strips("world/estimate/straight/ellipse")
    assert len(ellipses) == 41 and ellipses[0][0].shape == (33, 2)
    assert rec.events() == [(7, "INFO", "a decision")]
    summary = rec.summary()
    assert summary["application_id"] == "hybridtrack" and summary["configuration"] == {"seed": 3, "steps": 40}
    assert summary["recording_id"] == recording_id({"seed": 3, "steps": 40})
    assert summary["step_range"] == [0, 40]
    assert set(summary["final_estimates"]) == {"straight", "right_turn_r5"}
    assert "application id: hybridtrack" in format_summary(summary)
    assert rerun_cli("rrd", "verify", path).returncode == 0


def test_same_seed_recordings_compare_equal_and_different_seeds_do_not(tmp_path, rerun_cli):
    run(tmp_path / "a.rrd", seed=5)
    run(tmp_path / "b.rrd", seed=5)
    run(tmp_path / "c.rrd", seed=6)
    same = rerun_cli("rrd", "compare", tmp_path / "a.rrd", tmp_path / "b.rrd")
    assert same.returncode == 0, same.stdout + same.stderr
    different = rerun_cli("rrd", "compare", tmp_path / "a.rrd", tmp_path / "c.rrd")
    assert different.returncode != 0


def test_an_exception_midway_leaves_a_valid_file_with_what_was_logged(tmp_path, rerun_cli):
    path = tmp_path / "broken.rrd"
    with pytest.raises(RuntimeError, match="midway"):
        with RerunRecorder(path, {"broken": True}) as recorder:
            recorder.log_scalars("detector/x/statistic", np.arange(5), np.arange(5.0))
            raise RuntimeError("midway")
    assert rerun_cli("rrd", "verify", path).returncode == 0
    steps, values = RecordingFile(path).series("detector/x/statistic")
    assert np.array_equal(values, np.arange(5.0))


def test_ellipse_outline_is_the_two_sigma_contour():
    P = np.array([[4.0, 1.2], [1.2, 1.0]])
    outline = ellipse_outlines(np.array([[1.0, -2.0]]), P[None], sigmas=2.0)[0]
    d = outline - [1.0, -2.0]
    np.testing.assert_allclose(np.einsum("ki,ij,kj->k", d, np.linalg.inv(P), d), 4.0)


def test_null_recorder_and_open_recorder(tmp_path):
    assert isinstance(open_recorder(None), NullRecorder)
    with open_recorder(tmp_path / "x.rrd", {"a": 1}) as recorder:
        assert isinstance(recorder, RerunRecorder)
    with NullRecorder() as null:
        null.log_lines("x", [0], [[0, 0]], [[1, 1]])


def test_inspection_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        RecordingFile(tmp_path / "missing.rrd")
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(b"not a recording")
    with pytest.raises(ValueError, match="not a readable rerun recording"):
        RecordingFile(bad)
    path = tmp_path / "ok.rrd"
    with RerunRecorder(path) as recorder:
        recorder.log_scalars("detector/x", [0, 1], [1.0, 2.0])
    with pytest.raises(KeyError, match="no entity '/nope'"):
        RecordingFile(path).series("nope")
