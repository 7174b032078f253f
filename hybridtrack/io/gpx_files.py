"""Reading GPX 1.0 / 1.1 files (GPS logs) for :func:`~hybridtrack.io.track_files.read_tracks` (``format="gpx"``,
or a ``.gpx`` file name), through the optional package gpxpy (``pip install hybridtrack[gpx]``).

What is read: the points (``<trkpt>``) of every track (``<trk>``) and its segments (``<trkseg>``, joined in
file order) — one :class:`~hybridtrack.io.track_files.Track` per ``<trk>``, its id the track's ``<name>`` (a
name repeated by a later track gets `` #2``, `` #3``, … so that every ``<trk>`` stays its own track) or
``"track N"`` (N: the track's place in the file, from 1) without one.  Each point gives a row of time
(``<time>``, with its zone; none: UTC), latitude and longitude (degrees, WGS-84) and — when *every* point with
a time has an ``<ele>`` — the altitude (metres; positions are then east-north-up), then checked, sorted,
de-duplicated, speed-checked and projected by ``read_tracks`` like a CSV's rows (its module docstring).

What is not read: routes (``<rte>``) and waypoints (``<wpt>``) — planned, not travelled — and speed/course,
whether GPX 1.0's ``<speed>``/``<course>`` or extensions (the track has none: ``Track.speed``/``course`` are
None).

The ``line`` of a row and of its problems is the line of the ``<trkpt>`` start tag (found by a pass of the
standard-library expat parser, as gpxpy keeps no line numbers; should the two parsers disagree on the points,
the point's place in the file, from 1, stands in).  A point without a ``<time>``, or whose time gpxpy cannot
read, is a :class:`~hybridtrack.io.track_files.Problem` ``bad_time`` (dropped) naming the track and the
point.  Refused (a ValueError naming the file): bytes that are not well-formed XML, a root element other than
``<gpx>``, what gpxpy refuses (a point without a latitude, a non-numeric one), a file without track points.
"""

from __future__ import annotations

import xml.parsers.expat
from collections import Counter
from datetime import UTC

from hybridtrack.io.csv_text import checked_path
from hybridtrack.io.track_files import Problem, Rows, require

#: the column keywords of read_tracks a GPX file's rows fix (``alt`` dropped when a point has no elevation)
SETTINGS = {"time": "time", "lat": "lat", "lon": "lon", "alt": "alt", "id": "id"}
#: what the rows hold (for the error refusing column keywords)
COLUMNS = "a GPX file's rows are its track points: time, lat, lon, elevation (alt) and the track's name (id)"
_HINT = "expected a GPX 1.0 or 1.1 file of tracks (<gpx><trk><trkseg><trkpt lat=… lon=…><time>…"


def read_rows(path) -> Rows:
    """The :class:`~hybridtrack.io.track_files.Rows` of the GPX file ``path`` (module docstring): one row per
    track point with a time, a ``bad_time`` problem per point without one."""
    gpxpy = require("gpxpy", "gpx", f"reading GPX files ({path})")
    path = checked_path(path, "a GPX file")
    name = str(path)
    data = path.read_bytes()
    root, marks = _scan(data, name)
    if root != "gpx":
        raise ValueError(f"{name}: not a GPX file: the root element is <{root}>, expected <gpx>; {_HINT}")
    try:
        gpx = gpxpy.parse(data)
    except (gpxpy.gpx.GPXException, UnicodeDecodeError, ValueError) as error:
        raise ValueError(f"{name}: not a valid GPX file ({error}); {_HINT}") from None
    points = [(key, k, point) for key, track in _tracks(gpx.tracks) for k, point in enumerate(_points(track), 1)]
    if not points:
        raise ValueError(f"{name}: no track points (<trk><trkseg><trkpt>); routes (<rte>) and waypoints (<wpt>) are not read; {_HINT}")
    if len(marks) != len(points):  # the parsers disagree: the point's place in the file stands in for its line
        marks = [(i, None) for i in range(1, len(points) + 1)]
    rows, problems = [], []
    for (key, k, point), (line, raw_time) in zip(points, marks):
        if point.time is None:
            what = "has no <time>" if raw_time is None else f"has <time> {raw_time.strip()!r}, not an ISO-8601 time"
            message = f"{name}:{line}: track {key!r}, point {k} {what}; point dropped"
            problems.append(Problem(line, "time", "bad_time", "dropped", message, key))
            continue
        stamp = point.time if point.time.tzinfo is None else point.time.astimezone(UTC)
        rows.append((line, [stamp.isoformat(), key, repr(point.latitude), repr(point.longitude), point.elevation]))
    header = ["time", "id", "lat", "lon"]
    if rows and all(cells[4] is not None for _, cells in rows):
        header.append("alt")
        body = [(line, cells[:4] + [repr(float(cells[4]))]) for line, cells in rows]
    else:
        body = [(line, cells[:4]) for line, cells in rows]
    return Rows(name, 0, header, body, problems, records=len(points), unit="track points", hint=_HINT)


def _tracks(tracks):
    """(id, track) per ``<trk>``: its name, made unique with `` #2``, … (module docstring), or ``"track N"``."""
    seen = Counter()
    for n, track in enumerate(tracks, 1):
        key = (track.name or "").strip() or f"track {n}"
        seen[key] += 1
        yield (key if seen[key] == 1 else f"{key} #{seen[key]}"), track


def _points(track):
    return [point for segment in track.segments for point in segment.points]


def _scan(data: bytes, name: str) -> tuple[str, list[tuple[int, str | None]]]:
    """(the root element's local name, [(line of the ``<trkpt>`` start tag, the text of its ``<time>`` or None)
    per track point, in file order]) by expat; malformed XML is a ValueError naming the file and the line."""
    parser = xml.parsers.expat.ParserCreate()
    root: list[str] = []
    stack: list[str] = []
    marks: list[list] = []

    def start(tag, _attributes):
        local = tag.rpartition(":")[2]
        if not root:
            root.append(local)
        if local == "trkpt":
            marks.append([parser.CurrentLineNumber, None])
        elif local == "time" and stack and stack[-1] == "trkpt":
            marks[-1][1] = ""
        stack.append(local)

    def end(_tag):
        stack.pop()

    def text(chunk):
        if stack and stack[-1] == "time" and len(stack) > 1 and stack[-2] == "trkpt":
            marks[-1][1] += chunk

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as error:
        raise ValueError(
            f"{name}:{error.lineno}: not a GPX file: not well-formed XML ({xml.parsers.expat.ErrorString(error.code)}); {_HINT}"
        ) from None
    return (root[0] if root else ""), [(line, time) for line, time in marks]
