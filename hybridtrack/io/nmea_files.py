"""Reading raw AIS NMEA 0183 logs for :func:`~hybridtrack.io.track_files.read_tracks` (``format="nmea"``, or a
``.nmea`` / ``.ais`` file name), through the optional package pyais (``pip install hybridtrack[ais]``).

One sentence a line: ``!AIVDM`` (received) or ``!AIVDO`` (own ship) sentences of any talker, messages of
several sentences assembled (pyais: :meth:`NMEAMessage.assemble_from_iterable`, fragments matched by sequence
id and channel, in order).  Position reports of class A (message types 1, 2, 3) and class B (18, 19) become
rows: id the MMSI, latitude/longitude, course over ground (degrees; 360 = not available → NaN) and speed over
ground (knots, stored in m/s; 102.3 = not available → NaN), then checked, sorted, de-duplicated (a report
heard by two receivers is a ``duplicate_time``), speed-checked and projected by ``read_tracks`` like a CSV's
rows (its module docstring; latitude 91 / longitude 181, "not available", are ``out_of_range``: dropped).
The heading and the report's own UTC second are not read.

Time of a message (the receiver's, that of its first sentence that has one):

* an NMEA 4.0 tag block before the sentence, its ``c:`` field — Unix seconds, or milliseconds when > 10¹¹:
  ``\\s:station1,c:1452603731*75\\!AIVDM,1,1,,A,13P;U:gP0sOs0bPM3@<6:P01P000,0*55``;
* else a time stamp leading the line, followed by a space or a comma (as AIS-catcher, rtl-ais or a shell's
  ``ts`` write them): ISO 8601 (``2016-01-12T13:02:11Z !AIVDM,…``, ``2016-01-12 13:02:11.218,!AIVDM,…``; no
  zone: UTC) or Unix seconds (``1452603731.218 !AIVDM,…``; milliseconds when > 10¹¹).

Every line not used is a :class:`~hybridtrack.io.track_files.Problem` (its ``line`` the file line; for a
message of several sentences the line of its first): ``bad_checksum`` (dropped) — the sentence's ``*hh`` or its
tag block's does not match, one per line; ``not_position`` (dropped) — other message types (5, static and
voyage data; 24, class B static data; …) and other NMEA sentences (``$GPRMC``, …), *one problem per type*
giving the count and the first line; ``bad_time`` (dropped) — a position report without a time, or with a
leading stamp or ``c:`` field that is not one; ``bad_row`` (dropped) — a line that is no NMEA sentence, a
sentence pyais cannot parse or decode, the fragments of a message whose other fragments are missing.
Refused (a ValueError naming the file): an empty file, a file without any NMEA sentence.  Blank lines are
skipped; bytes that are not UTF-8 are replaced (their lines then fail as sentences).
"""

from __future__ import annotations

import re
from datetime import UTC, datetime

from hybridtrack.io.csv_text import checked_path, finite_number
from hybridtrack.io.track_files import MILLISECONDS_LIKELY, Problem, Rows, require, timestamp

#: the column keywords of read_tracks an NMEA file's rows fix: the AIS fields and their "not available" codes
SETTINGS = {
    "time": "time",
    "id": "id",
    "lat": "lat",
    "lon": "lon",
    "course": "course",
    "speed": "speed",
    "speed_unit": "knots",
    "course_not_available": 360.0,
    "speed_not_available": 102.3,
}
#: what the rows hold (for the error refusing column keywords)
COLUMNS = "an NMEA file's rows are its AIS position reports: time, MMSI (id), lat, lon, course and speed (knots) over ground"
#: the AIS message types read: position reports of class A (1, 2, 3) and class B (18 standard, 19 extended)
POSITION_TYPES = (1, 2, 3, 18, 19)
#: the names of other message types often met, for the ``not_position`` problems
MESSAGE_NAMES = {
    4: "base station report",
    5: "static and voyage data",
    8: "binary broadcast",
    9: "SAR aircraft position report",
    21: "aid-to-navigation report",
    24: "class B static data",
    27: "long-range broadcast",
}
#: an NMEA 0183 sentence: ``!`` or ``$``, a talker id and a sentence type, then the fields
SENTENCE = re.compile(r"[!$][A-Z][A-Z0-9][A-Z]{3},")
_HINT = (
    "expected one NMEA 0183 AIS sentence a line (!AIVDM,1,1,,A,…,0*hh), with a tag block (\\c:UNIX SECONDS*hh\\) or a leading time stamp"
)


def read_rows(path) -> Rows:
    """The :class:`~hybridtrack.io.track_files.Rows` of the NMEA log ``path`` (module docstring): one row per
    position report, the other lines as problems."""
    require("pyais", "ais", f"reading AIS NMEA files ({path})")
    from pyais.exceptions import AISBaseException
    from pyais.messages import NMEAMessage, TagBlock

    path = checked_path(path, "an NMEA file of AIS sentences")
    name = str(path)
    lines = [(k, text.strip()) for k, text in enumerate(path.read_bytes().decode("utf-8", errors="replace").splitlines(), 1)]
    lines = [(k, text) for k, text in lines if text]
    if not lines:
        raise ValueError(f"{name}: empty file; {_HINT}")
    problems: list[Problem] = []
    ignored: dict[str, list[int]] = {}  # message type or sentence tag → [count, first line]
    pending: dict[tuple, list] = {}  # (sequence id, channel) → [(line, sentence, time)] of a message being assembled
    body = []
    sentences = 0

    def report(line, kind, message, key=None, column=None):
        problems.append(Problem(line, column, kind, "dropped", f"{name}:{line}: {message}", key))

    def ignore(what, line):
        ignored.setdefault(what, [0, line])[0] += 1

    def incomplete(parts):
        first = parts[0][1]
        shown = ", ".join(str(line) for line, _, _ in parts)
        message = (
            f"fragment(s) on line(s) {shown} of a {first.frag_cnt}-sentence AIS message (sequence id {first.seq_id},"
            f" channel {first.channel}) without the others; dropped"
        )
        report(parts[0][0], "bad_row", message)

    for line, text in lines:
        start = re.search(r"[\\!$]", text)
        if start is None:
            report(line, "bad_row", f"{text[:40]!r} is no NMEA sentence; line dropped")
            continue
        prefix, rest, stamp = text[: start.start()], text[start.start() :], None
        if prefix:
            if prefix[-1] not in " ,\t;":
                report(line, "bad_row", f"{prefix!r} before the sentence is not followed by a space or a comma; line dropped")
                continue
            stamp = _time_of(prefix.strip(" ,\t;"))
            if stamp is None:
                report(line, "bad_time", f"the leading {prefix.strip()!r} is neither an ISO-8601 time nor Unix seconds; line dropped")
                continue
        if rest.startswith("\\"):
            end = rest.find("\\", 1)
            if end < 0:
                report(line, "bad_row", "a tag block (\\…) without its closing backslash; line dropped")
                continue
            block, rest = rest[1:end], rest[end + 1 :]
            tag = TagBlock(block.encode("ascii", errors="replace"))
            try:
                tag.init()
            except (AISBaseException, ValueError, UnicodeDecodeError):
                report(line, "bad_row", f"tag block {block!r} is not NMEA 4.0 (fields*hh); line dropped")
                continue
            if not tag.is_valid:
                report(line, "bad_checksum", f"tag block {block!r}: no checksum or a wrong one; line dropped")
                continue
            if tag.receiver_timestamp is not None:
                stamp = _time_of(tag.receiver_timestamp)
                if stamp is None:
                    report(line, "bad_time", f"tag block c:{tag.receiver_timestamp!r} is not Unix seconds; line dropped")
                    continue
        if not SENTENCE.match(rest):
            report(line, "bad_row", f"{rest[:40]!r} is no NMEA sentence; line dropped")
            continue
        sentences += 1
        kind = rest.split(",", 1)[0]
        if kind[3:].upper() not in ("VDM", "VDO"):
            ignore(kind, line)
            continue
        try:
            sentence = NMEAMessage(rest.encode("ascii"))
        except (AISBaseException, ValueError, IndexError, UnicodeEncodeError) as error:
            report(line, "bad_row", f"not a valid AIS sentence ({error}); line dropped")
            continue
        if not sentence.is_valid:
            report(line, "bad_checksum", f"the checksum *{rest.rpartition('*')[2]} does not match the sentence; line dropped")
            continue
        if sentence.frag_cnt == 1:
            parts = [(line, sentence, stamp)]
        else:
            key = (sentence.seq_id, sentence.channel)
            if sentence.frag_num == 1:
                if key in pending:
                    incomplete(pending.pop(key))
                pending[key] = [(line, sentence, stamp)]
                continue
            parts = pending.get(key)
            if parts is None or parts[0][1].frag_cnt != sentence.frag_cnt or len(parts) + 1 != sentence.frag_num:
                incomplete([*pending.pop(key, []), (line, sentence, stamp)])
                continue
            parts.append((line, sentence, stamp))
            if len(parts) < sentence.frag_cnt:
                continue
            del pending[key]
        first = parts[0][0]
        message_type = parts[0][1].ais_id
        if message_type not in POSITION_TYPES:
            ignore(message_type, first)
            continue
        try:
            decoded = NMEAMessage.assemble_from_iterable([s for _, s, _ in parts]).decode()
        except (AISBaseException, ValueError, IndexError, KeyError) as error:
            report(first, "bad_row", f"AIS message type {message_type}: pyais cannot decode it ({error}); dropped")
            continue
        mmsi = str(getattr(decoded, "mmsi", "") or "")
        when = next((t for _, _, t in parts if t is not None), None)
        if when is None:
            message = f"AIS position report (type {message_type}) of MMSI {mmsi} without a time: no tag block c: field, no leading time stamp; dropped"
            report(first, "bad_time", message, mmsi or None, "time")
            continue
        cells = [getattr(decoded, field, None) for field in ("lat", "lon", "course", "speed")]
        body.append((first, [when.isoformat(), mmsi, *("" if v is None else repr(float(v)) for v in cells)]))
    for parts in pending.values():
        incomplete(parts)
    if sentences == 0:
        raise ValueError(f"{name}: no NMEA sentence in the file (its line {lines[0][0]}: {lines[0][1][:60]!r}); {_HINT}")
    for what, (count, line) in ignored.items():
        if isinstance(what, int):
            label = f" ({MESSAGE_NAMES[what]})" if what in MESSAGE_NAMES else ""
            message = f"{count} AIS message(s) of type {what}{label}, not a position report (types {', '.join(map(str, POSITION_TYPES))})"
        else:
            message = f"{count} {what} sentence(s), not AIS (!AIVDM/!AIVDO)"
        report(line, "not_position", f"{message}; ignored (the first on this line)")
    return Rows(name, 0, ["time", "id", "lat", "lon", "course", "speed"], body, problems, records=len(lines), unit="lines", hint=_HINT)


def _time_of(text: str) -> datetime | None:
    """Unix seconds (milliseconds when > 10¹¹) or an ISO-8601 time stamp as a UTC datetime; None for anything else."""
    value = finite_number(text)
    if value is None:
        return timestamp(text)
    try:
        return datetime.fromtimestamp(value / 1000.0 if value > MILLISECONDS_LIKELY else value, UTC)
    except (OverflowError, OSError, ValueError):
        return None
