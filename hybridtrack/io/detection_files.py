"""Reading files of unlabelled detections (a radar's plots, AIS reports read without their id): scans of detections (issue 23, item 1).

A CSV (or ``.csv.gz``) or a pandas DataFrame with one row per detection — a time and a position (``time,x,y`` in
metres, or latitude/longitude in degrees), no identity — becomes a
:class:`~hybridtrack.engine.detections.Detections`: the detections grouped into scans by the file's scan column
(``scan``) or into time windows of ``scan_window`` seconds (the rules of
:func:`~hybridtrack.engine.detections.group_scans`: a window's scan time is its end, the last one capped at the
latest time stamp; windows without detections are no scans).

The rows are read and checked exactly as :func:`~hybridtrack.io.track_files.read_tracks` reads them (the same CSV
reader, time stamps, projection to the tangent plane at ``origin``, :class:`~hybridtrack.io.track_files.Problem`
reports; :func:`~hybridtrack.io.track_files.parse_rows`), without what makes sense only for the reports of one
object: no grouping by id, no de-duplication of equal times (two objects may be detected at one time, even at
one place), no speed check.  A row with a bad time or position is reported and dropped; a bad ``scan`` cell
(not a finite number) too.  ``truth_id`` names a column kept as each detection's true object, for scoring only
(the MMSI of an AIS file): its distinct values, in order of first appearance, are the objects 0 … n−1
(:attr:`DetectionFile.truth_names` holds the original text); an empty cell is a detection of no known object
(origin −1, reported as ``missing_id``, ``flagged``).  A tracker never reads it.
"""

from __future__ import annotations

import os
import reprlib
import warnings
from collections import Counter
from collections.abc import Sequence
from datetime import datetime, timedelta

import attrs
import numpy as np

from hybridtrack.engine.detections import Detections, group_scans
from hybridtrack.io.csv_text import checked_path, finite_number, read_csv
from hybridtrack.io.track_files import (
    SPEED_UNITS,
    Problem,
    Rows,
    check_origin_option,
    check_projection,
    check_time_options,
    frame_rows,
    ground_velocity,
    is_data_frame,
    parse_rows,
    source_format,
)

_HINT = "expected a UTF-8 CSV with a header row and one row per detection (time, x, y or latitude, longitude)"


def _lines(value) -> np.ndarray:
    array = np.array(value, dtype=np.int64, copy=True)
    if array.ndim != 1:
        raise ValueError(f"lines: expected shape (N,), got {array.shape}")
    array.setflags(write=False)
    return array


@attrs.frozen(eq=False)
class DetectionFile:
    """What :func:`read_detections` returns: ``path`` (the file, or ``"<DataFrame>"``), the ``detections``, the
    ``origin`` (lat°, lon°, h m) of the tangent plane (None for x/y files), the ``projection`` (None for x/y files),
    the ``epoch`` (UTC datetime of time 0 for time stamps, None for numeric seconds), every
    :class:`~hybridtrack.io.track_files.Problem` of the file by line, ``truth_names`` (the ``truth_id`` cell of each
    object index of ``detections.origin``, None without a truth column) and ``lines`` (N,) the file line of each
    detection, in the order of ``detections``."""

    path: str
    detections: Detections
    origin: tuple[float, float, float] | None
    projection: str | None
    epoch: datetime | None
    problems: tuple[Problem, ...] = attrs.field(converter=tuple)
    truth_names: tuple[str, ...] | None
    lines: np.ndarray = attrs.field(converter=_lines)

    def __attrs_post_init__(self):
        if self.lines.shape != (self.detections.size,):
            raise ValueError(f"lines: expected shape ({self.detections.size},) (one per detection), got {self.lines.shape}")


def read_detections(
    source,
    *,
    format: str | None = None,
    time: str = "time",
    x: str = "x",
    y: str = "y",
    lat: str | None = None,
    lon: str | None = None,
    alt: str | None = None,
    scan: str | None = None,
    scan_window: float | None = None,
    truth_id: str | None = None,
    course: str | None = None,
    speed: str | None = None,
    speed_unit: str = "m/s",
    course_not_available: float | None = None,
    speed_not_available: float | None = None,
    origin: str | Sequence[float] = "first",
    projection: str = "enu",
    time_unit: str | None = None,
    time_format: str | None = None,
    warn: bool = True,
) -> DetectionFile:
    """Read the unlabelled detections of a CSV file (``.csv``, ``.csv.gz``; ``format="csv"`` for another name) or a
    pandas DataFrame, grouped into scans (module docstring).

    ``time``, ``x``, ``y`` / ``lat``, ``lon``, ``alt``, ``origin``, ``projection``, ``time_unit``, ``time_format``:
    the columns and their reading, as in :func:`~hybridtrack.io.track_files.read_tracks` (geographic positions
    projected to the tangent plane at ``origin``: ``"first"`` the first valid fix, ``"mean"`` the mean of all, or an
    explicit (lat°, lon°[, h m])).  Scans: ``scan`` names a column of scan labels (numbers; the distinct values in
    increasing order are the scans) or ``scan_window`` gives windows of that many seconds — exactly one of the two.
    ``truth_id``: a column kept as each detection's true object (module docstring).  ``course``, ``speed`` (both or
    neither; ``speed_unit``, ``course_not_available``, ``speed_not_available`` as for
    :func:`~hybridtrack.io.track_files.read_tracks`): the course over ground (degrees clockwise from north) and
    speed each detection reports (an AIS report's), kept as :attr:`Detections.velocity` = s (sin χ, cos χ) (east,
    north, m/s), NaN where either cell is a "not available" code or not a valid number.  ``warn``: one warning
    summarising the problems found (they are in :attr:`DetectionFile.problems` either way).
    """
    frame = is_data_frame(source)
    if not frame and not isinstance(source, (str, os.PathLike)):
        raise TypeError(
            f"source: expected a file path (str or os.PathLike) or a pandas DataFrame, got {type(source).__name__} ({reprlib.repr(source)})"
        )
    if not frame:
        checked_path(source, "a CSV file of detections (.csv, .csv.gz)")
    kind = source_format(source, format)
    if kind != "csv":
        raise ValueError(
            f"{source}: format {kind!r}; read_detections reads CSV files and DataFrames (give format='csv' for a CSV of another name)"
        )
    if (scan is None) == (scan_window is None):
        given = f"scan={scan!r}, scan_window={scan_window!r}"
        raise ValueError(
            f"scan and scan_window: give exactly one — scan, the column of scan numbers, or scan_window, the length of a scan in"
            f" seconds (e.g. scan_window = 10.0) — got {given}"
        )
    if scan_window is not None:
        group_scans([0.0], scan_window=scan_window)  # its checks of scan_window, before the file is read
    if (lat is None) != (lon is None):
        raise ValueError(f"lat/lon: give both latitude and longitude column names, got lat={lat!r}, lon={lon!r}")
    if (course is None) != (speed is None):
        raise ValueError(
            f"course/speed: give both the course and the speed column names (or neither), got course={course!r}, speed={speed!r}"
        )
    if speed_unit not in SPEED_UNITS:
        raise ValueError(f"speed_unit: {speed_unit!r}; expected one of {sorted(SPEED_UNITS)}")
    for name, value in (("scan", scan), ("truth_id", truth_id)):
        if value is not None and not isinstance(value, str):
            raise TypeError(f"{name}: expected a column name (str), got {type(value).__name__} ({value!r})")
    check_projection(projection)
    check_time_options(time_unit, time_format)
    origin = check_origin_option(origin)

    if frame:
        rows = frame_rows(source, [time, x, y, lat, lon, alt, scan, truth_id, course, speed])
        rows = attrs.evolve(rows, hint="expected a DataFrame with one row per detection")
    else:
        rows = Rows(str(source), *read_csv(source, "a CSV file of detections", _HINT), hint=_HINT)
    extra = [name for name in (scan, truth_id) if name is not None]
    parsed = parse_rows(
        rows,
        time=time,
        x=x,
        y=y,
        lat=lat,
        lon=lon,
        alt=alt,
        id=None,
        course=course,
        speed=speed,
        speed_unit=speed_unit,
        course_not_available=course_not_available,
        speed_not_available=speed_not_available,
        time_unit=time_unit,
        time_format=time_format,
        extra=extra,
    )
    kept = parsed.rows
    if scan is not None:
        labels, good = [], []
        for r in kept:
            cell = r.cells[parsed.columns[scan]]
            value = finite_number(cell)
            if value is None:
                parsed.report(
                    r.line, scan, "not_a_number", "dropped", f"column {scan!r} holds {cell!r}, not a finite scan number; row dropped"
                )
            else:
                labels.append(value)
                good.append(r)
        kept = good
    if not kept:
        raise ValueError(parsed.nothing_left())

    names = None
    truth = None
    if truth_id is not None:
        index: dict[str, int] = {}
        truth = np.empty(len(kept), dtype=np.intp)
        for i, r in enumerate(kept):
            cell = r.cells[parsed.columns[truth_id]]
            if not cell:
                message = f"column {truth_id!r} is empty; kept as a detection of no known object (origin -1)"
                parsed.report(r.line, truth_id, "missing_id", "flagged", message)
                truth[i] = -1
            else:
                truth[i] = index.setdefault(cell, len(index))
        names = tuple(index)

    if parsed.geographic:
        origin = parsed.origin_of(kept, origin)
    positions = parsed.positions(kept, origin, projection)
    times = np.array([r.time for r in kept], dtype=np.float64)
    epoch = parsed.epoch
    if epoch is not None and times.min() != 0.0:  # the earliest time stamp was on a row dropped for its scan cell
        epoch, times = epoch + timedelta(seconds=float(times.min())), times - times.min()
    grouping = group_scans(times, scan_window=scan_window, scan=None if scan is None else np.array(labels))
    order = grouping.order
    velocity = None
    if course is not None:
        values = np.array([[np.nan if v == "n/a" else v for v in (r.course, r.speed)] for r in kept], dtype=np.float64)
        velocity = ground_velocity(values[:, 0], values[:, 1])[order]
    detections = Detections(
        scan_times=grouping.scan_times,
        scan=grouping.scan,
        times=times[order],
        z=positions[order],
        origin=None if truth is None else truth[order],
        velocity=velocity,
    )
    lines = np.array([r.line for r in kept], dtype=np.int64)[order]
    problems = tuple(sorted(parsed.problems, key=parsed.by_place))
    data = DetectionFile(
        path=str(rows.name),
        detections=detections,
        origin=origin if parsed.geographic else None,
        projection=projection if parsed.geographic else None,
        epoch=epoch,
        problems=problems,
        truth_names=names,
        lines=lines,
    )
    if warn and problems:
        counts = Counter(f"{p.kind} ({p.action})" for p in problems)
        summary = ", ".join(f"{n} {kind}" for kind, n in counts.most_common())
        warnings.warn(f"{data.path}: {len(problems)} problems: {summary}; see DetectionFile.problems", stacklevel=2)
    return data
