"""Recording of a multi-target run (:class:`~hybridtrack.algorithms.multitarget.tracker.MultiTargetResult`).

Entity paths (docs/recording.md): ``world/detections`` every scan's detections (points per scan step),
``world/tracks/<id>`` each confirmed track's estimate per scan and its path (the colour of its id), with
``map/tracks/<id>`` on the map view for latitude/longitude files, and ``events/decisions`` a text event at each
track's confirmation ("track 7 confirmed") and deletion ("track 7 deleted").  The timeline ``step`` counts scans.
"""

from __future__ import annotations

import numpy as np


def record_multitarget(recorder, result, detections, lat_lon=None) -> None:
    """Log ``result`` and its input ``detections`` (a :class:`~hybridtrack.engine.detections.Detections`) to
    ``recorder``; ``lat_lon`` (Q, 2): the degrees of every row of ``result`` (None for x/y files)."""
    counts = detections.counts()
    K, widest = counts.size, int(counts.max(initial=0))
    if widest:
        points = np.full((K, widest, 2), np.nan)
        slot = np.arange(detections.scan.size) - np.searchsorted(detections.scan, detections.scan)
        points[detections.scan, slot] = detections.z
        recorder.log_points("world/detections", np.arange(K, dtype=np.int64), points, detections.scan_times)
    positions = result.positions()
    for track in result.tracks:
        rows = np.flatnonzero(result.track_id == track.id)
        steps = result.scan[rows].astype(np.int64)
        recorder.log_path(f"world/tracks/{track.id}", steps, positions[rows], result.time[rows])
        if lat_lon is not None:
            recorder.log_geo_path(f"map/tracks/{track.id}", steps, lat_lon[rows], result.time[rows])
    scan_of = {float(t): k for k, t in enumerate(result.scan_times.tolist())}
    for track in result.tracks:
        for what, time in (("confirmed", track.confirmed), ("deleted", track.deleted)):
            if time is not None:
                recorder.log_event(scan_of.get(float(time), 0), f"track {track.id} {what}", float(time))
