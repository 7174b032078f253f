"""A recorded run killed with SIGKILL leaves a file `hybridtrack inspect` reads and reports as truncated.

The pipeline streams its rows to the recording every ``record_every`` steps (or
every ``record_seconds``) and flushes the file, so the kill loses at most the
steps since the last flush.  The child prints each thousandth step *after*
processing it; once it has passed step 25,000 the flushes at 10,000 and 20,000
have completed (a flush blocks until the data is in the file), so steps
0 … 19,999 must be readable — without any timing assumption.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from hybridtrack.cli import main
from hybridtrack.recording import RerunRecorder
from hybridtrack.recording.inspection import RecordingFile, scan_frames

CHILD = textwrap.dedent(
    """
    import sys
    import numpy as np
    from hybridtrack import Gaussian, Schedule
    from hybridtrack.engine.pipeline import Pipeline
    from hybridtrack.recording import RerunRecorder
    from hybridtrack.engine.simulate import simulate
    from hybridtrack_plugins.sensors.position import PositionSensor

    X0 = np.array([0.0, 0.0, 0.0, 2.0])
    sensors = [PositionSensor(name="a")]
    truth, z = simulate(Schedule.from_rows([("straight", 60_000)]), X0, 0.1, sensors, seed=7)
    recorder = RerunRecorder(sys.argv[1], {"kill": True})
    pipeline = Pipeline(models=["straight"], estimator="kalman", sensors=sensors, measurements=z,
                        prior=Gaussian(X0, np.eye(4)), tau=0.1, recorder=recorder, truth=truth, record_seconds=None)
    while not pipeline.done:
        result = pipeline.step()
        if result.step % 1000 == 0:
            print(result.step, flush=True)
    pipeline.record()
    recorder.close()
    print("finished", flush=True)
    """
)
SAFE = 19_999  # steps 0..SAFE were flushed before the child printed step ≥ 25,000


def reference_nis(steps: int) -> np.ndarray:
    """The NIS of the same run, in process, without recording."""
    from hybridtrack import Gaussian, Schedule
    from hybridtrack.engine.pipeline import Pipeline
    from hybridtrack.engine.simulate import simulate
    from hybridtrack_plugins.sensors.position import PositionSensor

    X0 = np.array([0.0, 0.0, 0.0, 2.0])
    sensors = [PositionSensor(name="a")]
    _, z = simulate(Schedule.from_rows([("straight", 60_000)]), X0, 0.1, sensors, seed=7)
    z = {name: value[:steps] for name, value in z.items()}
    return (
        Pipeline(models=["straight"], estimator="kalman", sensors=sensors, measurements=z, prior=Gaussian(X0, np.eye(4)), tau=0.1)
        .run()
        .nis[:, 0]
    )


@pytest.fixture(scope="module")
def killed(tmp_path_factory):
    """Run the child, SIGKILL it after step 25,000, return the file it left."""
    path = tmp_path_factory.mktemp("kill") / "killed.rrd"
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        for line in child.stdout:
            if line.strip() == "finished":
                pytest.fail("the child finished before it could be killed")
            if int(line) >= 25_000:
                os.kill(child.pid, signal.SIGKILL)
                break
    finally:
        child.kill()
        child.wait(timeout=60)
    assert child.returncode == -signal.SIGKILL
    return path


@pytest.mark.slow
def test_a_killed_recording_keeps_the_flushed_steps_exactly(killed):
    rec = RecordingFile(killed)
    assert rec.truncated and "footer" in rec.problem
    low, high = rec.step_range()
    assert low == 0 and SAFE <= high < 60_000
    steps, nis = rec.series("estimator/straight/nis")
    assert steps[-1] >= SAFE and np.array_equal(steps, np.arange(len(steps)))  # no gap, no duplicate
    np.testing.assert_array_equal(nis[: SAFE + 1], reference_nis(SAFE + 1))  # float64, exactly the run's values
    for entity in ("world/truth", "world/measurements/a", "world/estimate/straight"):
        steps, _ = rec.points(entity)
        assert steps[-1] >= SAFE and np.array_equal(steps, np.arange(len(steps))), entity
    assert rec.configuration == {"kill": True}


@pytest.mark.slow
def test_inspect_reports_the_killed_file_as_truncated(killed, capsys):
    assert main(["inspect", str(killed), "--json"]) == 3
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary["truncated"] is True and summary["step_range"][1] >= SAFE
    assert summary["final_estimates"]["straight"]["step"] >= SAFE
    assert captured.err.count("\n") == 1 and "truncated recording" in captured.err and "Traceback" not in captured.err
    assert main(["inspect", str(killed)]) == 3
    assert "WARNING: truncated recording" in capsys.readouterr().out


def complete_file(path):
    with RerunRecorder(path, {"cut": True}) as recorder:
        for start in range(0, 4000, 200):
            recorder.log_scalars("detector/x", np.arange(start, start + 200), np.arange(start, start + 200.0))
            recorder.flush()
    return path


@pytest.mark.parametrize("fraction", [0.999, 0.9, 0.6, 0.3])
def test_a_file_cut_anywhere_reads_its_whole_messages(tmp_path, fraction, capsys):
    """Cut inside the footer, inside a message or a header: the whole messages before the cut are read."""
    data = complete_file(tmp_path / "full.rrd").read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: int(len(data) * fraction)])
    complete, readable, problem = scan_frames(cut)
    assert not complete and 0 < readable <= cut.stat().st_size and problem
    rec = RecordingFile(cut)
    assert rec.truncated
    if fraction > 0.5:
        steps, values = rec.series("detector/x")
        assert np.array_equal(values, steps.astype(float)) and np.array_equal(steps, np.arange(len(steps)))
    assert main(["inspect", str(cut)]) == 3
    assert "truncated" in capsys.readouterr().err
    assert cut.read_bytes() == data[: int(len(data) * fraction)]  # the user's file is left as it was


def test_a_complete_file_is_not_truncated(tmp_path, capsys):
    rec = RecordingFile(complete_file(tmp_path / "full.rrd"))
    assert not rec.truncated and rec.problem is None and rec.step_range() == (0, 3999)
    assert main(["inspect", str(tmp_path / "full.rrd"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["truncated"] is False


def test_a_file_cut_before_its_recording_is_a_clear_error(tmp_path, capsys):
    data = complete_file(tmp_path / "full.rrd").read_bytes()
    cut = tmp_path / "early.rrd"
    cut.write_bytes(data[:200])
    with pytest.raises(ValueError, match="early.rrd.*(not a readable rerun recording|holds no recording before the cut)"):
        RecordingFile(cut)
    assert main(["inspect", str(cut)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "early.rrd" in err and "Traceback" not in err


@pytest.mark.parametrize("content", [b"RRF2", b"RRF2\x00\x29\x00\x00\x01\x02\x00\x00\x02\x00"])
def test_a_file_with_no_whole_message_is_a_clear_error(tmp_path, content, capsys):
    bad = tmp_path / "stub.rrd"
    bad.write_bytes(content)
    with pytest.raises(ValueError, match="stub.rrd.*not a readable rerun recording"):
        RecordingFile(bad)
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "stub.rrd" in err and "Traceback" not in err
