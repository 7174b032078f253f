"""What a closed RerunRecorder leaves behind: its rerun stream freed (threads), and the layouts a file carries."""

import os
import sys

import numpy as np
import pytest

from hybridtrack.recording import RerunRecorder
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack.recording.recorder import SWEEP_EVERY


def native_threads() -> int:
    return len(os.listdir("/proc/self/task"))


def record(path, **options):
    with RerunRecorder(path, {"file": path.name}, **options) as recorder:
        recorder.log_scalars("estimator/kf/nis", np.arange(5), np.linspace(0.0, 1.0, 5), np.arange(5) * 0.5)
        recorder.log_path("world/estimate/kf", np.arange(5), np.column_stack([np.arange(5.0), np.zeros(5)]), np.arange(5) * 0.5)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="counts the process's threads in /proc")
def test_closed_recorders_do_not_keep_their_streams_threads(tmp_path):
    """rerun keeps every stream (two threads each) until told to free the orphaned ones; closing frees them every
    SWEEP_EVERY closes.  What stays is rerun 0.41's own leak, the blueprint stream of each file's layout (two
    threads): without the sweep 2 N recorders would leave 4 threads each, with it at most 2 each and SWEEP_EVERY − 1
    closed streams waiting."""
    record(tmp_path / "warm.rrd", generic_layout=False)  # rerun's runtime threads start with the first stream
    before = native_threads()
    n = 2 * SWEEP_EVERY
    for i in range(n):
        record(tmp_path / f"{i}.rrd", generic_layout=False)
    grown = native_threads() - before
    assert grown <= 2 * n + 2 * (SWEEP_EVERY - 1) < 4 * n
    assert all(RecordingFile(tmp_path / f"{i}.rrd").series("/estimator/kf/nis")[0].size == 5 for i in (0, n - 1))


def test_generic_layout_false_leaves_only_the_layout_of_what_was_logged(tmp_path):
    import rerun as rr

    record(tmp_path / "generic.rrd")
    record(tmp_path / "content.rrd", generic_layout=False)
    stores = {name: list(rr.chunk.RrdReader(str(tmp_path / f"{name}.rrd")).blueprints()) for name in ("generic", "content")}
    assert len(stores["generic"]) == 2 and len(stores["content"]) == 1  # the generic layout at the start, then close()'s
    views = {name: sorted((v["class"], v["origin"]) for v in RecordingFile(tmp_path / f"{name}.rrd").blueprint_views()) for name in stores}
    assert views["content"] == views["generic"]  # the active layout is close()'s in both
    assert ("3D", "/world") in views["content"] and any(c == "TimeSeries" for c, _ in views["content"])
    assert RecordingFile(tmp_path / "content.rrd").unviewed_entities() == []
