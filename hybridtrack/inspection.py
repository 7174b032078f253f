"""Reading .rrd recordings back offline, without a viewer.

:class:`RecordingFile` gathers a file's chunks (``rerun.chunk.RrdReader``) per
entity path and gives them back as numpy arrays sorted by step:

    rec = RecordingFile("demo.rrd")
    steps, nis = rec.series("/estimator/nis")        # (K,), (K, c) float64
    steps, points = rec.points("/world/truth")       # (K,), (K, 2) float32 → float64
    rec.events()                                     # [(step, level, text), …]
    rec.summary()                                    # what ``hybridtrack inspect`` prints
"""

from __future__ import annotations

import json
from functools import cached_property
from pathlib import Path

import numpy as np


def _entity(path: str) -> str:
    return path if path.startswith("/") else "/" + path


class RecordingFile:
    """The data of one .rrd file, per entity path and column."""

    def __init__(self, path: str | Path):
        import pyarrow as pa
        import rerun as rr

        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"{self.path}: no such recording")
        try:
            self._reader = rr.chunk.RrdReader(str(self.path))
            recordings = [entry for entry in self._reader.recordings() if entry.kind == "recording"]
            chunks = list(self._reader.stream().to_chunks())
        except Exception as error:  # noqa: BLE001 - rerun raises its own types for unreadable files
            raise ValueError(f"{self.path}: not a readable rerun recording ({error})") from None
        if not recordings:
            raise ValueError(f"{self.path}: holds no recording")
        self.application_id = recordings[0].application_id
        self.recording_id = recordings[0].recording_id
        # entity → column → values, all columns of an entity kept row-aligned (None where a chunk lacks one)
        self._columns: dict[str, dict[str, list]] = {}
        rows_so_far: dict[str, int] = {}
        for chunk in chunks:
            batch = chunk.to_record_batch()
            entity = chunk.entity_path
            table = self._columns.setdefault(entity, {})
            before = rows_so_far.get(entity, 0)
            names = [n for n in batch.schema.names if n != "rerun.controls.RowId"]
            for name in names:
                column = batch.column(name)
                if pa.types.is_temporal(column.type):  # time indexes and timestamps as integer nanoseconds
                    column = column.cast(pa.int64())
                table.setdefault(name, [None] * before).extend(column.to_pylist())
            for name in set(table) - set(names):
                table[name].extend([None] * batch.num_rows)
            rows_so_far[entity] = before + batch.num_rows

    @cached_property
    def entity_paths(self) -> list[str]:
        """Every entity path with data, properties excluded."""
        return sorted(p for p in self._columns if not p.startswith("/__properties"))

    @cached_property
    def configuration(self) -> dict:
        """The run configuration stored by :class:`~hybridtrack.recording.RerunRecorder` ({} if none)."""
        values = self._columns.get("/__properties/configuration", {}).get("json")
        return json.loads(values[-1][0]) if values else {}

    def _table(self, entity: str, component: str) -> tuple[np.ndarray, list]:
        entity = _entity(entity)
        if entity not in self._columns:
            raise KeyError(f"{self.path}: no entity {entity!r}; entities: {', '.join(self.entity_paths)}")
        table = self._columns[entity]
        if component not in table:
            raise KeyError(f"{self.path}: entity {entity!r} has no {component} column (has {sorted(table)})")
        if "step" not in table:
            raise KeyError(f"{self.path}: entity {entity!r} is not on the 'step' timeline")
        pairs = [(s, v) for s, v in zip(table["step"], table[component]) if s is not None and v is not None]
        order = sorted(range(len(pairs)), key=lambda i: pairs[i][0])
        return np.array([pairs[i][0] for i in order], dtype=np.int64), [pairs[i][1] for i in order]

    def times(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        """The ``time`` timeline of an entity: steps (K,) and times in seconds (K,) (stored as whole nanoseconds)."""
        steps, nanoseconds = self._table(entity, "time")
        return steps, np.array(nanoseconds, dtype=np.int64) / 1e9

    def series(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        """A scalar series: steps (K,) and float64 values (K,) or (K, c) for c series under one entity."""
        steps, values = self._table(entity, "Scalars:scalars")
        array = np.array(values, dtype=np.float64)
        return steps, array[:, 0] if array.ndim == 2 and array.shape[1] == 1 else array

    def points(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        """One 2-D point per step: steps (K,), positions (K, 2) (stored as float32)."""
        steps, values = self._table(entity, "Points2D:positions")
        return steps, np.array([v[0] for v in values], dtype=np.float64).reshape(-1, 2)

    def point_sets(self, entity: str) -> tuple[np.ndarray, list[np.ndarray]]:
        """Any number of 2-D points per step (e.g. clutter): steps (K,) and, per step, an (L, 2) array."""
        steps, values = self._table(entity, "Points2D:positions")
        return steps, [np.array(list(v), dtype=np.float64).reshape(-1, 2) for v in values]

    def strips(self, entity: str) -> tuple[np.ndarray, list[list[np.ndarray]]]:
        """Line strips per step (ellipses, bearing lines): steps and, per step, a list of (P, 2) arrays."""
        steps, values = self._table(entity, "LineStrips2D:strips")
        return steps, [[np.array(strip, dtype=np.float64) for strip in step] for step in values]

    def events(self) -> list[tuple[int, str, str]]:
        """Text events on ``/events/decisions``: (step, level, text) sorted by step."""
        if "/events/decisions" not in self._columns:
            return []
        steps, texts = self._table("/events/decisions", "TextLog:text")
        _, levels = self._table("/events/decisions", "TextLog:level")
        return [(int(s), (lv[0] if lv else ""), t[0]) for s, lv, t in zip(steps, levels, texts)]

    def step_range(self) -> tuple[int, int] | None:
        steps = [s for table in self._columns.values() for s in table.get("step", []) if s is not None]
        return (int(min(steps)), int(max(steps))) if steps else None

    def final_estimates(self) -> dict[str, dict]:
        """The last logged position of every ``/world/estimate/<filter>`` entity."""
        out = {}
        for entity in self.entity_paths:
            if entity.startswith("/world/estimate/") and "Points2D:positions" in self._columns[entity]:
                steps, positions = self.points(entity)
                if len(steps):
                    out[entity.removeprefix("/world/estimate/")] = {"step": int(steps[-1]), "position": positions[-1].tolist()}
        return out

    def summary(self) -> dict:
        """Application and recording id, configuration, entity paths, step range, decisions, final estimates."""
        step_range = self.step_range()
        return {
            "file": str(self.path),
            "application_id": self.application_id,
            "recording_id": self.recording_id,
            "configuration": self.configuration,
            "entity_paths": self.entity_paths,
            "step_range": list(step_range) if step_range else None,
            "decisions": [{"step": s, "level": lv, "text": t} for s, lv, t in self.events()],
            "final_estimates": self.final_estimates(),
        }


def format_summary(summary: dict) -> str:
    """The human-readable form of :meth:`RecordingFile.summary`."""
    lines = [
        f"file:           {summary['file']}",
        f"application id: {summary['application_id']}",
        f"recording id:   {summary['recording_id']}",
        f"configuration:  {json.dumps(summary['configuration'], sort_keys=True)}",
        f"steps:          {summary['step_range'][0]}..{summary['step_range'][1]}" if summary["step_range"] else "steps:          none",
        f"entity paths ({len(summary['entity_paths'])}):",
        *[f"  {p}" for p in summary["entity_paths"]],
        f"decisions ({len(summary['decisions'])}):",
        *[f"  step {d['step']:>5}  {d['level']:<5} {d['text']}" for d in summary["decisions"]],
        "final estimates:",
        *[
            f"  {name:<24} step {e['step']:>5}  x={e['position'][0]:.4g} y={e['position'][1]:.4g}"
            for name, e in summary["final_estimates"].items()
        ],
    ]
    return "\n".join(lines)
