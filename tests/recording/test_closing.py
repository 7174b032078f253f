"""Closing a recorder: the file is complete, the recorder lets go of the SDK's stream, logging afterwards is refused."""

import gc
import weakref

import numpy as np
import pytest

from hybridtrack.recording import RerunRecorder
from hybridtrack.recording.inspection import RecordingFile


def test_a_closed_recorder_holds_no_stream_and_its_file_is_complete(tmp_path):
    path = tmp_path / "closed.rrd"
    with RerunRecorder(path, {"seed": 1}) as recorder:
        recorder.log_scalars("estimator/kf/nis", np.arange(5), np.arange(5.0), np.arange(5) * 0.1)
        recorder.log_path("world/estimate/kf", np.arange(5), np.c_[np.arange(5.0), np.zeros(5)], np.arange(5) * 0.1)
        stream = weakref.ref(recorder.stream)
    gc.collect()
    assert stream() is None  # the recorder, still referenced here, no longer keeps the stream (nor its threads' data)
    rec = RecordingFile(path)
    assert rec.step_range() == (0, 4)
    assert rec.unviewed_entities() == []
    recorder.close()  # idempotent


def test_logging_after_close_names_the_file(tmp_path):
    path = tmp_path / "late.rrd"
    with RerunRecorder(path) as recorder:
        recorder.log_scalars("estimator/kf/nis", np.arange(3), np.ones(3))
    with pytest.raises(ValueError, match=r"late\.rrd is closed.*expected every log_… call before it"):
        recorder.log_scalars("estimator/kf/nis", np.arange(3), np.ones(3))
    with pytest.raises(ValueError, match=r"late\.rrd is closed"):
        recorder.log_event(1, "too late")
    recorder.flush()  # a closed recorder's flush does nothing
