"""The tracks of ``hybridtrack track`` as GeoJSON (``hybridtrack track … --geojson`` writes ``OUT/tracks.geojson``).

:func:`tracks_geojson` turns a latitude/longitude file's results — the ``summary`` of
:func:`~hybridtrack.apps.tracking.track_file` and the ``lat_lon`` estimate of each object's ``OUT/<id>.npz`` — into
a FeatureCollection (RFC 7946: WGS-84, every position ``[longitude, latitude]`` in degrees, rounded to 10⁻⁷°,
about 1 cm) of LineStrings:

* per object, its estimated track over all its reports, properties ``{"id", "kind": "track", "mode": null,
  "start_utc", "end_utc"}``;
* per segment of that object (``summary.json``'s ``segments``, in order), the estimate from the segment's first
  report to its end, which is the next segment's first report (segments end where the next starts, so a segment
  of one report is the line from it to the next report), properties ``{"id", "kind": "segment", "mode",
  "start", "end", "start_utc", "end_utc"}`` (``start``, ``end`` in seconds as in the summary).

``start_utc`` and ``end_utc`` are null for files without UTC time stamps.  A LineString needs two positions: the
one segment that can have a single one — the last, when the mode changes at the last report — repeats it.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

#: the digits after the decimal point of a longitude or latitude (10⁻⁷° ≈ 1.1 cm)
DIGITS = 7


def tracks_geojson(summary: Mapping, outputs: str | os.PathLike) -> dict:
    """The FeatureCollection (module docstring) of ``summary`` (:func:`~hybridtrack.apps.tracking.track_file`'s,
    or ``summary.json`` read back) with the ``.npz`` files in the folder ``outputs`` (each object's ``output`` stem).

    Checked: ``summary`` has an ``"objects"`` list; each object's ``.npz`` exists and has ``lat_lon`` (K, 2), finite,
    of as many reports as its ``times`` (a FileNotFoundError / ValueError naming the file otherwise)."""
    objects = summary.get("objects") if isinstance(summary, Mapping) else None
    if not isinstance(objects, list):
        raise ValueError(f"summary: expected track_file's summary, a mapping with an 'objects' list, got {type(summary).__name__}")
    features = []
    for entry in objects:
        if not isinstance(entry, Mapping) or not isinstance(entry.get("output"), str):
            raise ValueError(f"summary: expected objects with an 'output' file stem (track_file's summary), got {entry!r:.80}")
        path = Path(outputs) / f"{entry['output']}.npz"
        if not path.is_file():
            raise FileNotFoundError(2, f"object {entry['id']!r}: no such output file", str(path))
        with np.load(path) as npz:
            if "lat_lon" not in npz:
                raise ValueError(f"{path}: no lat_lon (the estimate in degrees): not the output of a latitude/longitude file")
            times, lat_lon = np.asarray(npz["times"], dtype=float), np.asarray(npz["lat_lon"], dtype=float)
        if lat_lon.shape != (times.size, 2) or times.size < 2 or not np.isfinite(lat_lon).all():
            raise ValueError(
                f"{path}: lat_lon: expected finite (K, 2) degrees for its K = {times.size} ≥ 2 times, got shape {lat_lon.shape}"
            )
        positions = [[round(float(lon), DIGITS), round(float(lat), DIGITS)] for lat, lon in lat_lon]
        segments = entry["segments"]
        features.append(
            _line(
                positions,
                id=entry["id"],
                kind="track",
                mode=None,
                start_utc=segments[0].get("start_utc") if segments else None,
                end_utc=segments[-1].get("end_utc") if segments else None,
            )
        )
        for segment in segments:
            first, last = np.searchsorted(times, [segment["start"], segment["end"]])
            line = positions[first : last + 1]
            features.append(
                _line(
                    line if len(line) > 1 else line * 2,
                    id=entry["id"],
                    kind="segment",
                    mode=segment["mode"],
                    start=segment["start"],
                    end=segment["end"],
                    start_utc=segment.get("start_utc"),
                    end_utc=segment.get("end_utc"),
                )
            )
    return {"type": "FeatureCollection", "features": features}


def _line(positions: list, **properties) -> dict:
    return {"type": "Feature", "geometry": {"type": "LineString", "coordinates": positions}, "properties": properties}
