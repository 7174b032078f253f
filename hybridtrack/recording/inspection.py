"""Reading .rrd recordings back offline, without a viewer, as a stream (docs/recording.md, "Reading a file back").

:class:`RecordingFile` keeps only the summary (entity paths, step range, decision
events, last estimates, configuration); its accessors read the file again for one
entity and give numpy arrays sorted by step.  A file without rerun's end-of-stream
message and footer (a killed run) is *truncated*: every whole message before the
cut is read, and :attr:`RecordingFile.truncated` and :attr:`RecordingFile.problem` are set.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import tempfile
import warnings
import weakref
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

_MAGIC = b"RRF2"  # rerun's stream header: magic, version (4 bytes), options (4 bytes)
_STREAM_HEADER = 12
_MESSAGE_HEADER = struct.Struct("<QQ")  # message kind (0 = end of stream), payload length
_FOOTER_MAGIC = b"RRF2FOOT"  # in the stream footer that closes a complete file (followed by a 4-byte version)


def _entity(path: str) -> str:
    return path if path.startswith("/") else "/" + path


#: position and strip columns, 3-D (east, north, up) first
_POSITIONS = ("Points3D:positions", "Points2D:positions")
_STRIPS = ("LineStrips3D:strips", "LineStrips2D:strips")
#: the blueprint column of each field of a view in :meth:`RecordingFile.blueprint_views`
_VIEW_FIELDS = {"ViewBlueprint:class_identifier": "class", "ViewBlueprint:display_name": "name", "ViewBlueprint:space_origin": "origin"}


def _coordinates(points: np.ndarray, dims: int) -> np.ndarray:
    """Points (N, 2 or 3) as (N, dims): the first ``dims`` coordinates (z = 0 added to 2-D data)."""
    if dims not in (2, 3):
        raise ValueError(f"dims: expected 2 (east, north) or 3 (east, north, up), got {dims!r}")
    if points.size == 0:
        return np.zeros((0, dims))
    points = points.reshape(1, -1) if points.ndim == 1 else points
    if dims == 3 and points.shape[-1] == 2:
        return np.concatenate([points, np.zeros(points.shape[:-1] + (1,))], axis=-1)
    return points[..., :dims]


def _last_value(batch, column: str):
    """The last non-empty value of a blueprint column (a list), or None."""
    values = [v for v in batch.column(column).to_pylist() if v]
    return values[-1] if values else None


def view_selects(contents: list[str], origin: str, entity: str) -> bool:
    """Whether a view's entity-path filter selects ``entity`` (rerun's rules).

    Each rule is ``+ path`` or ``- path`` (``+`` if no sign), ``$origin`` replaced by
    the view's origin; ``path/**`` matches the path and everything below it, a path
    without it only itself.  The most specific matching rule decides (a longer path;
    on the same path an exact rule before a subtree rule, an exclusion before an
    inclusion); no matching rule: not selected.
    """
    entity = _entity(entity).rstrip("/") or "/"
    best = None
    for raw in contents:
        rule = raw.strip()
        include = not rule.startswith("-")
        rule = rule.lstrip("+-").strip().replace("$origin", origin.rstrip("/"))
        subtree = rule.endswith("/**")
        path = _entity(rule[:-3] if subtree else rule).rstrip("/") or "/"
        if subtree:
            matches = path == "/" or entity == path or entity.startswith(path + "/")
        else:
            matches = entity == path
        if matches:
            rank = (path.count("/") if path != "/" else 0, not subtree, not include)
            if best is None or rank > best[0]:
                best = (rank, include)
    return bool(best and best[1])


def scan_frames(path: Path) -> tuple[bool, int, str | None]:
    """Walk the message headers of an .rrd file without decoding payloads.

    Returns (complete, readable, problem): ``complete`` when the stream ends
    with the end-of-stream message and footer; ``readable`` the byte length of
    the whole messages at the start of the file; ``problem`` says where and why a
    file is not complete (None when it is).  A file that does not start with
    rerun's header is left to rerun to reject (returned as complete).
    """
    size = path.stat().st_size
    with path.open("rb") as f:
        header = f.read(_STREAM_HEADER)
        if len(header) < _STREAM_HEADER or header[:4] != _MAGIC:
            return True, size, None
        position = _STREAM_HEADER
        while True:
            if position == size:
                return False, position, f"no end-of-stream footer after byte {position} (the writer stopped before closing the file)"
            raw = f.read(_MESSAGE_HEADER.size)
            if len(raw) < _MESSAGE_HEADER.size:
                return False, position, f"cut inside a message header at byte {position} of {size}"
            kind, length = _MESSAGE_HEADER.unpack(raw)
            end = position + _MESSAGE_HEADER.size + length
            if end > size:
                return False, position, f"cut inside a message at byte {position} ({length} bytes announced, {size - position} present)"
            f.seek(end)
            if kind == 0:  # end of stream: what follows is the footer
                if _FOOTER_MAGIC in f.read()[-16:]:
                    return True, size, None
                return False, end, f"end-of-stream message at byte {position} without a complete footer"
            position = end


class RecordingFile:
    """The summary of one .rrd file, read as a stream; per-entity values on demand.

    Attributes: ``path``, ``application_id``, ``recording_id``, ``truncated``
    (the file lacks its end-of-stream footer, or a chunk failed to decode),
    ``problem`` (why, or None), ``readable_bytes`` (the length of the part read).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"{self.path}: no such recording")
        complete, readable, problem = scan_frames(self.path)
        self.truncated = not complete
        self.problem = problem
        self.readable_bytes = readable
        self._source = self.path
        if self.truncated and readable < self.path.stat().st_size:
            if readable <= _STREAM_HEADER:
                raise ValueError(f"{self.path}: not a readable rerun recording ({problem}; no whole message to read)")
            self._source = self._copy_prefix(readable)
        try:
            reader = self._reader()
            recordings = [entry for entry in reader.recordings() if entry.kind == "recording"]
        except Exception as error:  # noqa: BLE001 - rerun raises its own types for unreadable files
            raise ValueError(f"{self.path}: not a readable rerun recording ({error})") from None
        if not recordings:
            cut = f" before the cut ({problem})" if self.truncated else ""
            raise ValueError(f"{self.path}: holds no recording{cut}")
        self.application_id = recordings[0].application_id
        self.recording_id = recordings[0].recording_id
        self._scan(reader)

    def _copy_prefix(self, length: int) -> Path:
        """Copy the first ``length`` bytes (the whole messages) to a temporary file removed with this object."""
        folder = tempfile.mkdtemp(prefix="hybridtrack-inspect-")
        weakref.finalize(self, shutil.rmtree, folder, True)
        target = Path(shutil.copyfile(self.path, Path(folder) / self.path.name))
        os.truncate(target, length)
        return target

    def _reader(self):
        import rerun as rr

        with warnings.catch_warnings():
            if self.truncated:  # rerun warns that the footer is missing: reported by ``truncated`` instead
                warnings.filterwarnings("ignore", message=".*no footer.*")
            return rr.chunk.RrdReader(str(self._source))

    def _chunks(self, entity: str | None = None):
        """Record batches (entity path, batch) one chunk at a time; a decode error partway marks the file truncated."""
        stream = self._reader().stream()
        if entity is not None:
            stream = stream.filter(content=entity)
        try:
            for chunk in stream:
                yield chunk.entity_path, chunk.to_record_batch()
        except Exception as error:  # noqa: BLE001 - rerun raises its own types for corrupt chunks
            self.truncated = True
            self.problem = f"a chunk failed to decode ({error}); what came before it was read"

    def _scan(self, reader) -> None:
        """One pass over the chunks keeping only the summary."""
        import pyarrow as pa
        import pyarrow.compute as pc

        self._components: dict[str, set[str]] = {}
        low = high = None
        spans: dict[str, list[int]] = {}  # "time" / "utc" → [min, max] in integer nanoseconds
        events: list[tuple[int, str, str, int | None]] = []
        last: dict[str, tuple[int, list[float]]] = {}
        configuration = None
        for entity, batch in self._chunks():
            names = set(batch.schema.names) - {"rerun.controls.RowId"}
            self._components.setdefault(entity, set()).update(names)
            if entity == "/__properties/configuration" and "json" in names and _last_value(batch, "json"):
                configuration = _last_value(batch, "json")[0]
            if "step" not in names or batch.num_rows == 0:
                continue
            steps = batch.column("step")
            lo, hi = pc.min(steps).as_py(), pc.max(steps).as_py()
            if lo is not None:
                low = lo if low is None else min(low, lo)
                high = hi if high is None else max(high, hi)
            nanoseconds = {key: batch.column(key).cast(pa.int64()) for key in ("time", "utc") if key in names}
            for key, column in nanoseconds.items():
                lo_t, hi_t = pc.min(column).as_py(), pc.max(column).as_py()
                if lo_t is not None:
                    span = spans.setdefault(key, [lo_t, hi_t])
                    span[0], span[1] = min(span[0], lo_t), max(span[1], hi_t)
            if entity == "/events/decisions" and "TextLog:text" in names:
                levels = batch.column("TextLog:level").to_pylist() if "TextLog:level" in names else [None] * batch.num_rows
                at = nanoseconds["time"].to_pylist() if "time" in nanoseconds else [None] * batch.num_rows
                for s, level, text, t in zip(steps.to_pylist(), levels, batch.column("TextLog:text").to_pylist(), at):
                    if s is not None and text:
                        events.append((int(s), level[0] if level else "", text[0], t))
            column = next((c for c in _POSITIONS if c in names), None)
            if entity.startswith("/world/estimate/") and column is not None:
                step_values = steps.to_numpy(zero_copy_only=False)
                positions = batch.column(column)
                valid = [i for i in np.argsort(step_values, kind="stable")[::-1] if positions[int(i)].is_valid]
                if valid and (entity not in last or step_values[valid[0]] >= last[entity][0]):
                    value = positions[int(valid[0])].as_py()
                    if value:
                        last[entity] = (int(step_values[valid[0]]), [float(c) for c in value[0]])
        self._step_range = None if low is None else (int(low), int(high))
        self._spans = spans
        self._events = sorted(events, key=lambda e: e[0])
        self._last_positions = last
        self._configuration = json.loads(configuration) if configuration else {}

    @property
    def entity_paths(self) -> list[str]:
        """Every entity path with data, properties excluded."""
        return sorted(p for p in self._components if not p.startswith("/__properties"))

    @property
    def configuration(self) -> dict:
        """The run configuration stored by :class:`~hybridtrack.recording.RerunRecorder` ({} if none)."""
        return dict(self._configuration)

    def _table(self, entity: str, component: str) -> tuple[np.ndarray, list]:
        """Steps (sorted) and the values of one component of one entity, reading only that entity's chunks."""
        import pyarrow as pa

        entity = _entity(entity)
        if entity not in self._components:
            raise KeyError(f"{self.path}: no entity {entity!r}; entities: {', '.join(self.entity_paths)}")
        columns = self._components[entity]
        if component not in columns:
            raise KeyError(f"{self.path}: entity {entity!r} has no {component} column (has {sorted(columns)})")
        if "step" not in columns:
            raise KeyError(f"{self.path}: entity {entity!r} is not on the 'step' timeline")
        pairs: list[tuple[int, object]] = []
        for name, batch in self._chunks(entity):
            if name != entity or "step" not in batch.schema.names or component not in batch.schema.names:
                continue
            column = batch.column(component)
            if pa.types.is_temporal(column.type):  # time indexes and timestamps as integer nanoseconds
                column = column.cast(pa.int64())
            pairs += [(s, v) for s, v in zip(batch.column("step").to_pylist(), column.to_pylist()) if s is not None and v is not None]
        pairs.sort(key=lambda pair: pair[0])  # stable: the values of one step stay in the file's order
        return np.array([s for s, _ in pairs], dtype=np.int64), [v for _, v in pairs]

    def times(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        """The ``time`` timeline of an entity: steps (K,) and times in seconds (K,) (stored as whole nanoseconds)."""
        steps, nanoseconds = self._table(entity, "time")
        return steps, np.array(nanoseconds, dtype=np.int64) / 1e9

    def series(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        """A scalar series: steps (K,) and float64 values (K,) or (K, c) for c series under one entity."""
        steps, values = self._table(entity, "Scalars:scalars")
        array = np.array(values, dtype=np.float64)
        return steps, array[:, 0] if array.ndim == 2 and array.shape[1] == 1 else array

    def _first(self, entity: str, candidates: tuple[str, ...]) -> tuple[np.ndarray, list]:
        """:meth:`_table` of the first of ``candidates`` (3-D before 2-D) the entity has (the first one if none, for the error)."""
        columns = self._components.get(_entity(entity), set())
        return self._table(entity, next((c for c in candidates if c in columns), candidates[0]))

    def points(self, entity: str, dims: int = 2) -> tuple[np.ndarray, np.ndarray]:
        """One point per step: steps (K,), positions (K, dims) (stored as float32): dims = 2 east-north, 3 with up."""
        steps, values = self._first(entity, _POSITIONS)
        return steps, _coordinates(np.array([v[0] for v in values], dtype=np.float64), dims)

    def point_sets(self, entity: str, dims: int = 2) -> tuple[np.ndarray, list[np.ndarray]]:
        """Any number of points per step (e.g. clutter): steps (K,) and, per step, an (L, dims) array."""
        steps, values = self._first(entity, _POSITIONS)
        return steps, [_coordinates(np.array(list(v), dtype=np.float64), dims) for v in values]

    def strips(self, entity: str, dims: int = 2) -> tuple[np.ndarray, list[list[np.ndarray]]]:
        """Line strips per step (ellipses, bearing lines): steps and, per step, a list of (P, dims) arrays."""
        steps, values = self._first(entity, _STRIPS)
        return steps, [[_coordinates(np.array(strip, dtype=np.float64), dims) for strip in step] for step in values]

    def blueprint_views(self) -> list[dict]:
        """The views of the embedded blueprint — the one sent last (latest ``log_time``: the layout
        :class:`~hybridtrack.recording.RerunRecorder` makes active when it closes the file): ``name``,
        ``class`` (``3D``, ``TimeSeries``, ``TextLog``, …), ``origin`` and ``contents`` (entity-path filter rules)."""
        views: dict[str, dict] = {}
        for path, batch in self._blueprint_chunks():
            names = batch.schema.names
            if not path.startswith("/view/"):
                continue
            view = views.setdefault(path.split("/")[2], {"name": None, "class": None, "origin": "/", "contents": ["$origin/**"]})
            if path.endswith("/ViewContents") and "ViewContents:query" in names:
                view["contents"] = _last_value(batch, "ViewContents:query") or []
            for column, key in _VIEW_FIELDS.items():
                if column in names and _last_value(batch, column):
                    view[key] = _last_value(batch, column)[0]
        return [v for v in views.values() if v["class"] is not None]

    def _blueprint_chunks(self) -> list[tuple[str, object]]:
        """(entity path, record batch) of every chunk of the blueprint sent last (:meth:`blueprint_views`)."""
        import pyarrow as pa
        import pyarrow.compute as pc

        reader = self._reader()
        latest, chosen = None, []
        for store in reader.blueprints():
            chunks = [(chunk.entity_path, chunk.to_record_batch()) for chunk in reader.stream(store=store)]
            times = [pc.max(batch.column("log_time").cast(pa.int64())).as_py() for _, batch in chunks if "log_time" in batch.schema.names]
            sent = max((t for t in times if t is not None), default=-1)
            if latest is None or sent >= latest:
                latest, chosen = sent, chunks
        return chosen

    def blueprint_timeline(self) -> str | None:
        """The timeline the embedded blueprint opens the file on (its time panel's ``timeline``: ``utc`` for a
        recording of real time stamps), or None when it leaves the choice to the viewer."""
        chosen = None
        for path, batch in self._blueprint_chunks():
            if path == "/time_panel" and "TimePanelBlueprint:timeline" in batch.schema.names:
                chosen = (_last_value(batch, "TimePanelBlueprint:timeline") or [chosen])[0]
        return chosen

    def unviewed_entities(self) -> list[str]:
        """Entity paths with data that no view of the embedded blueprint shows: each needs a view whose
        contents select it (:func:`view_selects`) and whose class shows one of its archetypes
        (:data:`hybridtrack.recording.VIEW_CLASSES`)."""
        from hybridtrack.recording import VIEW_CLASSES

        views = self.blueprint_views()
        missing = []
        for entity in self.entity_paths:
            archetypes = {c.split(":")[0] for c in self._components[entity] if ":" in c}
            classes = {VIEW_CLASSES[a] for a in archetypes if a in VIEW_CLASSES}
            if not any((not classes or v["class"] in classes) and view_selects(v["contents"], v["origin"], entity) for v in views):
                missing.append(entity)
        return missing

    def events(self) -> list[tuple[int, str, str]]:
        """Text events on ``/events/decisions``: (step, level, text) sorted by step."""
        return [event[:3] for event in self._events]

    def time_range(self) -> tuple[float, float] | None:
        """The first and last time (s) on the ``time`` timeline (None if nothing is on it)."""
        span = self._spans.get("time")
        return None if span is None else (span[0] / 1e9, span[1] / 1e9)

    def utc_range(self) -> tuple[str, str] | None:
        """The first and last instant on the ``utc`` timeline as ISO 8601 UTC strings (None for a recording without
        real time stamps)."""
        span = self._spans.get("utc")
        return None if span is None else tuple(_iso(ns) for ns in span)

    def step_range(self) -> tuple[int, int] | None:
        """The smallest and largest step of any entity on the ``step`` timeline (None if there is none)."""
        return self._step_range

    def final_estimates(self) -> dict[str, dict]:
        """The last logged position of every ``/world/estimate/<filter>`` entity."""
        return {
            entity.removeprefix("/world/estimate/"): {"step": step, "position": position}
            for entity, (step, position) in sorted(self._last_positions.items())
        }

    def summary(self) -> dict:
        """Application and recording id, configuration, entity paths, step range, decisions, final estimates,
        and whether the file is truncated (``truncated``, ``problem``, ``readable_bytes``)."""
        step_range = self.step_range()
        return {
            "file": str(self.path),
            "application_id": self.application_id,
            "recording_id": self.recording_id,
            "configuration": self.configuration,
            "entity_paths": self.entity_paths,
            "step_range": list(step_range) if step_range else None,
            "time_range": list(self.time_range()) if self.time_range() else None,
            "utc_range": list(self.utc_range()) if self.utc_range() else None,
            "decisions": [{"step": s, "level": lv, "text": t, "time": None if ns is None else ns / 1e9} for s, lv, t, ns in self._events],
            "final_estimates": self.final_estimates(),
            "truncated": self.truncated,
            "problem": self.problem,
            "readable_bytes": self.readable_bytes,
        }


def _iso(nanoseconds: int) -> str:
    """ISO 8601 UTC of integer nanoseconds since the Unix epoch (to the nearest microsecond)."""
    instant = datetime(1970, 1, 1, tzinfo=UTC) + timedelta(microseconds=(nanoseconds + 500) // 1000)
    return instant.isoformat().replace("+00:00", "Z")


def format_summary(summary: dict) -> str:
    """The human-readable form of :meth:`RecordingFile.summary`."""
    lines = [
        f"file:           {summary['file']}",
        f"application id: {summary['application_id']}",
        f"recording id:   {summary['recording_id']}",
        f"configuration:  {json.dumps(summary['configuration'], sort_keys=True)}",
        f"steps:          {summary['step_range'][0]}..{summary['step_range'][1]}" if summary["step_range"] else "steps:          none",
        f"times:          {summary['time_range'][0]:g}..{summary['time_range'][1]:g} s"
        if summary.get("time_range")
        else "times:          none",
        *([f"utc:            {summary['utc_range'][0]} .. {summary['utc_range'][1]}"] if summary.get("utc_range") else []),
        f"entity paths ({len(summary['entity_paths'])}):",
        *[f"  {p}" for p in summary["entity_paths"]],
        f"decisions ({len(summary['decisions'])}):",
        *[
            f"  step {d['step']:>5}  {'' if d.get('time') is None else format(d['time'], '.6g') + ' s':>10}  {d['level']:<5} {d['text']}"
            for d in summary["decisions"]
        ],
        "final estimates:",
        *[
            f"  {name:<24} step {e['step']:>5}  x={e['position'][0]:.4g} y={e['position'][1]:.4g}"
            for name, e in summary["final_estimates"].items()
        ],
    ]
    if summary.get("truncated"):
        lines.append(
            f"WARNING: truncated recording: {summary['problem']}; the above is what the first {summary['readable_bytes']} bytes hold"
        )
    return "\n".join(lines)
