"""Recordings: round trip, validity after errors, determinism, offline inspection."""

from datetime import UTC, datetime

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule
from hybridtrack.core.interfaces import Detector, DetectorStep
from hybridtrack.core.types import Decision
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import NullRecorder, RerunRecorder, ellipse_outlines, open_recorder, recording_id
from hybridtrack.recording.inspection import RecordingFile, format_summary
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
    assert summary["time_range"] == [0.0, 4.0] and summary["utc_range"] is None
    assert summary["decisions"] == [{"step": 7, "level": "INFO", "text": "a decision", "time": 0.7}]
    assert "times:          0..4 s" in format_summary(summary)
    assert rerun_cli("rrd", "verify", path).returncode == 0


def test_a_recording_of_real_time_stamps_has_the_utc_timeline(tmp_path, rerun_cli):
    """epoch + t on the ``utc`` timeline in exact nanoseconds (a 10⁹ s clock time in float64 would lose the
    microseconds), read back and printed by ``inspect``."""
    epoch = datetime(2016, 1, 12, 13, 2, 11, 218000, tzinfo=UTC)
    path = tmp_path / "utc.rrd"
    times = np.array([0.0, 10.000001, 3600.5])
    with RerunRecorder(path, {"utc": True}, epoch=epoch) as recorder:
        recorder.log_scalars("estimator/kf/nis", np.arange(3), np.ones(3), times)
        recorder.log_event(2, "late", 3600.5)
    rec = RecordingFile(path)
    assert rec.utc_range() == ("2016-01-12T13:02:11.218000Z", "2016-01-12T14:02:11.718000Z")
    text = format_summary(rec.summary())
    assert "utc:            2016-01-12T13:02:11.218000Z .. 2016-01-12T14:02:11.718000Z" in text and "3600.5 s" in text
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


class NisAbove(Detector):
    """A tiny detector: reports NIS of filter 0 and decides 'change' the first time it exceeds 5."""

    name = label = "nis_threshold"

    def __init__(self):
        self.reset()

    def reset(self):
        self.fired = False

    def step(self, step, innovation):
        nis = float(innovation.nis[0]) if innovation.measurement_dim else 0.0
        decision = None
        if nis > 5 and not self.fired:
            self.fired = True
            decision = Decision(step, self.name, "change", nis, "NIS above 5")
        return DetectorStep({"nis": nis}, {"threshold": 5.0}, decision)


def streamed_run(path, record_every, steps=60):
    schedule = Schedule.from_rows([("straight", steps // 2), ("right_turn", steps // 2, 5.0)])
    sensors = [PositionSensor(name="a")]
    truth, z = simulate(schedule, X0, 0.1, sensors, seed=11)
    with RerunRecorder(path, {"seed": 11}) as recorder:
        pipeline = Pipeline(
            models=["straight", ("right_turn", {"radius": 5.0})],
            estimator="kalman",
            sensors=sensors,
            measurements=z,
            prior=Gaussian(X0, np.eye(4)),
            tau=0.1,
            recorder=recorder,
            truth=truth,
            detectors=[NisAbove()],
            record_every=record_every,
            record_seconds=None,
        )
        result = pipeline.run()
    return pipeline, result


def test_streamed_recording_holds_the_same_values_in_more_chunks(tmp_path):
    """Streaming in chunks of 7 steps records exactly what one chunk records, and the static lines once."""
    _, result = streamed_run(tmp_path / "one.rrd", record_every=10_000)
    _, _ = streamed_run(tmp_path / "many.rrd", record_every=7)
    one, many = RecordingFile(tmp_path / "one.rrd"), RecordingFile(tmp_path / "many.rrd")
    assert one.entity_paths == many.entity_paths and not one.truncated and not many.truncated
    assert one.summary()["final_estimates"] == many.summary()["final_estimates"] and one.events() == many.events()
    assert len(one.events()) == 1
    for entity in ("estimator/straight/nis", "estimator/right_turn_r5/innovation", "detector/nis_threshold/nis"):
        for rec in (one, many):
            steps, values = rec.series(entity)
            assert np.array_equal(steps, np.arange(61))
        np.testing.assert_array_equal(one.series(entity)[1], many.series(entity)[1])
    np.testing.assert_array_equal(many.series("estimator/straight/nis")[1], result.nis[:, 0])
    for entity in ("world/truth", "world/estimate/straight"):
        np.testing.assert_array_equal(one.points(entity)[1], many.points(entity)[1])
    assert len(many.strips("world/estimate/straight/ellipse")[0]) == 61


def test_step_results_are_rebuilt_from_the_stored_arrays(tmp_path):
    pipeline, result = streamed_run(tmp_path / "r.rrd", record_every=10_000)
    assert len(pipeline.results) == 61 and pipeline.done
    last = pipeline.results[-1]
    assert last.step == 60 and np.array_equal(last.mean, result.means[60]) and np.array_equal(last.cov, result.covs[60])
    assert np.array_equal(last.innovation.nis, result.nis[60]) and last.innovation.S.shape == (2, 2, 2)
    assert last.detectors["nis_threshold"].statistics["nis"] == result.statistics["nis_threshold"]["nis"][60]
    assert [r.step for r in pipeline.results[58:]] == [58, 59, 60]
    assert not result.means.flags.writeable  # views of the pipeline's storage: read-only
    with pytest.raises(IndexError, match=r"results\[61\]: step out of range, 61 steps processed"):
        pipeline.results[61]
    with pytest.raises(TypeError, match=r"results\['a'\]"):
        pipeline.results["a"]


@pytest.mark.parametrize(
    "option, value, message",
    [
        ("record_every", 0, r"record_every: expected a whole number of steps ≥ 1, got 0"),
        ("record_every", 2.5, r"record_every: .* got 2.5"),
        ("record_seconds", -1.0, r"record_seconds: expected a positive number of seconds or None, got -1.0"),
        ("record_seconds", "2", r"record_seconds: .* got '2'"),
    ],
)
def test_bad_streaming_options_are_named(option, value, message):
    sensors = [PositionSensor(name="a")]
    with pytest.raises(ValueError, match=message):
        Pipeline(
            models=["straight"],
            estimator="kalman",
            sensors=sensors,
            measurements={"a": np.zeros((3, 2))},
            prior=(X0, np.eye(4)),
            tau=0.1,
            **{option: value},
        )


def test_memory_benchmark_runs_at_a_tiny_size(tmp_path):
    import json
    import subprocess
    import sys
    from pathlib import Path

    out = tmp_path / "memory.json"
    script = Path(__file__).resolve().parents[2] / "benchmarks" / "memory.py"
    done = subprocess.run([sys.executable, str(script), "--steps", "300", "--json", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    cases = {case["name"]: case for case in json.loads(out.read_text())["cases"]}
    assert set(cases) == {"run", "run_recorded", "inspect"}
    for case in cases.values():
        assert case["peak_bytes"] >= 0 and case["reference_bytes"] > 0 and case["ratio"] == case["peak_bytes"] / case["reference_bytes"]
