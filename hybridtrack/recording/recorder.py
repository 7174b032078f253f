"""The recorder seam: every run logs through a recorder object passed in (docs/recording.md, "The recorder").

:class:`RerunRecorder` owns one ``rerun.RecordingStream`` with a file sink, :class:`NullRecorder` records
nothing; leaving either context flushes and closes the file.  Series are logged as whole columns
(``send_columns``) on the timelines ``step`` and ``time`` (duration in seconds, when times are given) and, for a
recording of real time stamps (``epoch`` given), ``utc`` (the absolute time epoch + t), the timeline such a file
opens on.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
from collections.abc import Sequence
from contextlib import AbstractContextManager
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from hybridtrack.recording.layout import content_blueprint, default_blueprint, map_zoom
from hybridtrack.recording.results import log_result
from hybridtrack.recording.style import (
    LANE_WIDTH,
    finite_runs,
    is_hypothesis,
    is_mode_series,
    mode_lanes,
    palette,
    series_style,
    spatial_style,
)
from hybridtrack.sdk.distributions import chi2_quantile

APPLICATION_ID = "hybridtrack"

#: the largest |t| in seconds the ``time`` timeline holds: rerun durations are int64 nanoseconds
MAX_RECORDABLE_SECONDS = (2**63 - 1) / 1e9


def unix_nanoseconds(instant) -> int:
    """A timezone-aware datetime as whole nanoseconds since 1970-01-01T00:00:00Z (exact to its microsecond)."""
    return (instant - datetime(1970, 1, 1, tzinfo=UTC)) // timedelta(microseconds=1) * 1000


def check_recordable_times(times, name: str = "times") -> None:
    """A ValueError naming ``name`` unless every time is finite with |t| < 2⁶³ ns ≈ 9.22e9 s.

    Larger times would wrap or turn into nulls on the int64-nanosecond ``time``
    timeline, and rerun would silently drop the whole column.
    """
    if times is None:
        return
    t = np.atleast_1d(np.asarray(times, dtype=np.float64))
    bad = np.flatnonzero(~(np.abs(t) < MAX_RECORDABLE_SECONDS))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"{name}: time {float(t.flat[i])!r} s (index {i}) does not fit the recording's time axis"
            f" (int64 nanoseconds: expected finite |t| < {MAX_RECORDABLE_SECONDS:.4g} s)"
        )


@runtime_checkable
class Recorder(Protocol):
    """What components log through.  ``steps`` (K,) ints; ``times`` (K,) seconds or None."""

    def log_path(
        self,
        entity: str,
        steps: np.ndarray,
        positions: np.ndarray,
        times: np.ndarray | None = None,
        *,
        points: bool = True,
        line: bool = True,
    ) -> None:
        """A trajectory: positions (K, 2) east-north (z = 0) or (K, 3) with altitude, one point per step
        (``points``) and the whole path as a static line ``<entity>/path`` (``line``; a streamed run logs the
        points chunk by chunk and the line once at the end)."""

    def log_points(self, entity: str, steps: np.ndarray, points: np.ndarray, times: np.ndarray | None = None) -> None:
        """2-D points (K, 2) per step, or a variable number per step as (K, L, 2) NaN-padded (e.g. clutter);
        rows with NaN are skipped."""

    def log_scalars(
        self, entity: str, steps: np.ndarray, values: np.ndarray, times: np.ndarray | None = None, names: Sequence[str] | None = None
    ) -> None:
        """Scalar series: values (K,) or (K, c) (c named series under one entity)."""

    def log_event(self, step: int, text: str, time: float | None = None, level: str = "INFO") -> None:
        """A text event (decisions, warnings) at ``step``."""

    def log_modes(self, entity: str, steps: np.ndarray, modes: np.ndarray, names: Sequence[str], times: np.ndarray | None = None) -> None:
        """The mode of a trajectory per step: ``modes`` (K,) indices into ``names`` (−1: none yet).  Colours the
        entity's path in the space-time view by mode and marks the changes (truth: switches; estimate: identified)."""

    def log_ellipses(
        self, entity: str, steps: np.ndarray, centers: np.ndarray, covs: np.ndarray, times: np.ndarray | None = None, sigmas: float = 2.0
    ) -> None:
        """Covariance ellipses: centers (K, 2), 2×2 position covariances (K, 2, 2), drawn at ``sigmas``."""

    def log_lines(self, entity: str, steps: np.ndarray, starts: np.ndarray, ends: np.ndarray, times: np.ndarray | None = None) -> None:
        """One or more 2-D segments per step: starts, ends of shape (K, 2) or (K, L, 2) (e.g. bearing lines)."""

    def log_result(self, result, **context) -> None:
        """A finished run's result, handed over by the engine or an algorithm after the run, or the finished
        steps of a run still going (a pipeline hands them in chunks, ``start=…``)
        (:func:`hybridtrack.recording.results.log_result`, by the result's type)."""

    def flush(self) -> None:
        """Write what was logged so far to the sink (blocks until it reached the file)."""

    def close(self) -> None:
        """Flush and close; idempotent."""


class NullRecorder(AbstractContextManager):
    """Records nothing (recording turned off): every ``log_…`` method of :class:`Recorder` and of its optional
    extensions, ``flush`` and ``close`` accept their arguments and do nothing."""

    def __getattr__(self, name: str):
        if name.startswith("log_") or name in ("flush", "close"):
            return lambda *args, **kwargs: None
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __exit__(self, *exc):
        return False


def recording_id(configuration: dict) -> str:
    """A stable recording id from a run's configuration (which includes its seed)."""
    text = json.dumps(configuration, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def ellipse_outlines(centers: np.ndarray, covs: np.ndarray, sigmas: float = 2.0, points: int = 33) -> np.ndarray:
    """Outlines (K, points, 2) of {c + σ·√P u : |u| = 1}, for centers (K, 2) and covariances (K, 2, 2).

    √P is the symmetric square root of the 2×2 PSD matrix in closed form,
    √P = (P + √det P · I) / √(tr P + 2 √det P)  (Cayley–Hamilton), vectorized over K.
    """
    angles = np.linspace(0.0, 2 * np.pi, points)
    circle = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    P = (covs + np.swapaxes(covs, -1, -2)) / 2
    root_det = np.sqrt(np.clip(P[:, 0, 0] * P[:, 1, 1] - P[:, 0, 1] ** 2, 0.0, None))
    scale = np.sqrt(np.clip(P[:, 0, 0] + P[:, 1, 1] + 2 * root_det, 0.0, None))
    root = (P + root_det[:, None, None] * np.eye(2)) / np.where(scale > 0, scale, 1.0)[:, None, None]
    return centers[:, None, :] + sigmas * circle @ root  # √P is symmetric: u·√Pᵀ = u·√P


def _xyz(points: np.ndarray) -> np.ndarray:
    """East-north points (..., 2) with z = 0 appended; (..., 3) (altitude as z) unchanged."""
    points = np.asarray(points, dtype=np.float64)
    if points.shape[-1] == 3:
        return points
    if points.shape[-1] != 2:
        raise ValueError(f"positions: expected (..., 2) east-north or (..., 3) east-north-up coordinates, got shape {points.shape}")
    return np.concatenate([points, np.zeros(points.shape[:-1] + (1,))], axis=-1)


def _rows(times, rows):
    """``times[rows]`` as float64 seconds, or None."""
    return None if times is None else np.asarray(times, dtype=np.float64)[rows]


#: at most this many points per path in the space-time view (longer paths are thinned evenly)
SPACETIME_POINTS = 4000

#: the roles (``world/<role>``) of the paths every run on a recording shares: the truth and the observer.  The
#: simulator logs the truth and each pipeline or algorithm given it logs it again; :meth:`RerunRecorder.log_path`
#: sends only their points not yet logged (same step, time and position)
SHARED_ROLES = ("truth", "observer")


@functools.lru_cache(maxsize=512)
def _style(archetype: str, colour: tuple, size: float):
    """The static style of an entity: ``rerun.<archetype>.from_fields(colors=[colour], radii=[ui_points(size)])``
    (one radius for GeoPoints), built once per style (archetypes are immutable; a file logs each a few times and a
    run of many files the same few again)."""
    import rerun as rr

    radius = rr.Radius.ui_points(size)
    return getattr(rr, archetype).from_fields(colors=[colour], radii=radius if archetype == "GeoPoints" else [radius])


@functools.lru_cache(maxsize=512)
def _series_lines(names: tuple, colours: tuple, widths: tuple | None):
    """``rerun.SeriesLines(names, colors, widths)``, built once per style (as :func:`_style`)."""
    import rerun as rr

    return rr.SeriesLines(names=list(names), colors=list(colours), widths=None if widths is None else list(widths))


class _ClosedStream:
    """The stream of a closed :class:`RerunRecorder`: any use is a ValueError naming the file."""

    def __init__(self, path: Path):
        self.path = path

    def __getattr__(self, name: str):
        raise ValueError(f"recorder: {self.path} is closed (close() or the end of its with block); expected every log_… call before it")


#: closed recorders between two calls of :func:`free_closed_streams` (each flushes every stream rerun holds, ~5 ms
#: with a hundred): at most this many closed streams wait to be freed
SWEEP_EVERY = 16
_closed_since_sweep = 0


def free_closed_streams(rr) -> None:
    """Free the rerun streams no one holds any more (those of closed recorders), with their threads and buffers.

    rerun 0.41 lists every ``RecordingStream`` it creates; dropping the Python object only disconnects it and moves
    it to a list of orphans, which ``rerun.init`` (documented: it "flushes all existing recordings" and destructs the
    orphaned ones) or the end of the process empties — ``bindings.flush_and_cleanup_orphaned_recordings`` is what
    ``rerun.init`` calls for it.  Without this a run writing one file per object keeps two threads and ~0.6 MB per
    file (``hybridtrack track`` on the Solent file: 150 threads, 47 MB).  The streams of the blueprints
    (``send_blueprint``, ``save(default_blueprint=…)``) are not freed by it: rerun 0.41's memory sink and its stream
    hold each other (``MemorySinkStorage.rec``), so each stays until the process ends."""
    rr.bindings.flush_and_cleanup_orphaned_recordings()


class RerunRecorder(AbstractContextManager):
    """A file recording (.rrd) on its own ``rerun.RecordingStream``; ``configuration`` (a JSON-able dict, seed
    included) gives the recording id (the same run twice, the same id) and is stored as the property ``configuration``.

    Everything spatial is 3-D east-north-up (2-D positions get z = 0); each entity is styled once from its path
    (:func:`spatial_style`, :func:`series_style`).  :meth:`close` adds the space-time view and embeds the blueprint
    of what was logged (:func:`content_blueprint`) as the file's active and default layout.

    ``epoch`` (a timezone-aware UTC datetime, the instant of t = 0): every series and event is also put on the
    ``utc`` timeline at epoch + t, so that a recording of real reports shows their clock time; the embedded
    blueprint then opens the file on ``utc`` (``step`` stays one click away in the time panel).

    ``generic_layout`` (default True): the file starts with the generic layout (:func:`default_blueprint`), the one a
    file keeps when its run is killed before :meth:`close`; False for a file written in one go from a finished run
    (``hybridtrack track``'s, one per object), which then carries only the layout of :meth:`close`.  Every layout
    costs rerun 0.41 a blueprint stream that it never frees (about 0.6 MB and two threads; :meth:`close`).
    """

    def __init__(self, path: str | Path, configuration: dict | None = None, *, epoch=None, generic_layout: bool = True):
        import rerun as rr

        self._rr = rr
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.configuration = dict(configuration or {})
        self.recording_id = recording_id(self.configuration)
        self.stream = rr.RecordingStream(APPLICATION_ID, recording_id=self.recording_id)
        self.stream.save(
            str(self.path), default_blueprint=default_blueprint(timeline=None if epoch is None else "utc") if generic_layout else None
        )
        self.stream.send_property("configuration", rr.AnyValues(json=json.dumps(self.configuration, sort_keys=True, default=str)))
        self.content: dict[str, str] = {}  # entity path → view class (VIEW_CLASSES)
        self._tracks: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray | None]] = {}
        self._modes: dict[str, tuple[np.ndarray, np.ndarray, tuple[str, ...]]] = {}
        self._geo: list[np.ndarray] = []  # the corners of every geo path (for the map view's zoom)
        self._breaks: dict[str, np.ndarray] = {}  # a hypothesis's path: where its pieces in play start (rows of its track)
        self._events: list[tuple[int, str]] = []  # the decisions: (step, text)
        self._shared: dict[str, list[tuple]] = {}  # SHARED_ROLES path → blocks of logged points: steps (sorted), xyz, times
        self._time_step: float | None = None
        self._epoch = None if epoch is None else unix_nanoseconds(epoch)  # t = 0, in whole ns since the Unix epoch
        self._on_utc = False  # whether anything was put on the utc timeline
        self._index_columns: dict[tuple, list] = {}  # (steps, times) bytes → their index columns (:meth:`_indexes`)
        self._closed = False

    # -- helpers
    def _indexes(self, steps, times, rows=slice(None)):
        """The ``step`` (and ``time``) index columns of ``rows`` of a series, noting the time step τ; the columns of
        the steps and times logged before are the ones built then (the series of a run share them)."""
        steps, times = np.asarray(steps, dtype=np.int64)[rows], _rows(times, rows)
        key = (steps.tobytes(), None if times is None else times.tobytes())
        hit = self._index_columns.get(key)
        if hit is not None:
            return hit
        self._index_columns[key] = indexes = self._new_indexes(steps, times)
        return indexes

    def _new_indexes(self, steps: np.ndarray, times: np.ndarray | None) -> list:
        check_recordable_times(times)
        rr = self._rr
        indexes = [rr.TimeColumn("step", sequence=steps)]
        if times is not None:
            indexes.append(rr.TimeColumn("time", duration=times))
            if self._epoch is not None:
                indexes.append(rr.TimeColumn("utc", timestamp=self._utc(times)))
                self._on_utc = True
            if self._time_step is None and times.size > 1:
                gaps = np.diff(steps) > 0
                if gaps.any():
                    self._time_step = float(np.median(np.diff(times)[gaps] / np.diff(steps)[gaps]))
        return indexes

    def _utc(self, times):
        """epoch + t as numpy datetime64[ns] (exact integer nanoseconds: no float rounding of 10⁹ s clock times)."""
        return (self._epoch + np.round(np.asarray(times, dtype=np.float64) * 1e9).astype(np.int64)).astype("datetime64[ns]")

    def _note(self, entity: str, view_class: str) -> bool:
        """Note a logged entity (True the first time), declaring east-north-up on its spatial root."""
        entity = entity.strip("/")
        if entity in self.content:
            return False
        root = entity.split("/")[0]
        if view_class == "3D" and root not in self.content:
            self.stream.log(root, self._rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            self.content[root] = "3D"
        self.content[entity] = view_class
        return True

    def _send_points(self, entity, steps, points, times, keep, radii=None) -> bool:
        """Send the ``keep`` points ((K,) or (K, L) for several per step) of the steps that have one; False if none."""
        if not keep.any():
            return False
        counts = keep.reshape(keep.shape[0], -1).sum(axis=1)
        present = counts > 0
        columns = self._rr.Points3D.columns(positions=points[keep], radii=None if radii is None else radii[keep])
        self.stream.send_columns(entity, indexes=self._indexes(steps, times, present), columns=columns.partition(counts[present]))
        return True

    # -- Recorder
    def log_points(self, entity, steps, points, times=None):
        points = _xyz(points)
        if self._send_points(entity, steps, points, times, np.all(np.isfinite(points), axis=-1)) and self._note(entity, "3D"):
            colour, _ = spatial_style(entity)
            role = entity.strip("/").split("/")[1:2]
            size = 1.25 if is_hypothesis(entity) else {"measurements": 3.0, "clutter": 2.0, "truth": 2.5}.get(role[0] if role else "", 2.0)
            self.stream.log(entity, _style("Points3D", colour, size), static=True)

    def log_weighted_points(self, entity, steps, points, weights, times=None, max_radius=0.05):
        """Optional extension of the Recorder protocol: points (K, L, 2 or 3) with weights (K, L) ≥ 0 drawn as radii,
        r = max_radius · √(w / max_step w) (area ∝ weight; particle clouds, mixture components).  Rows with NaN skipped."""
        points, weights = _xyz(points), np.asarray(weights, dtype=np.float64)
        keep = np.all(np.isfinite(points), axis=-1) & np.isfinite(weights)
        top = np.max(np.where(keep, weights, 0.0), axis=-1, keepdims=True, initial=0.0)
        radii = max_radius * np.sqrt(np.clip(weights, 0.0, None) / np.where(top > 0, top, 1.0))
        if self._send_points(entity, steps, points, times, keep, radii):
            self._note(entity, "3D")

    def log_geo_path(self, entity, steps, lat_lon, times=None):
        """Optional extension of the Recorder protocol: WGS-84 positions (K, 2) (latitude°, longitude°) as
        ``GeoPoints`` per step and the whole path as a static ``GeoLineStrings`` ``<entity>/path``, shown by a map
        view (rerun's ``MapView``, the ``Map`` view class of :func:`content_blueprint`).  Rows with NaN skipped."""
        rr = self._rr
        lat_lon = np.asarray(lat_lon, dtype=np.float64)
        if lat_lon.ndim != 2 or lat_lon.shape[1] != 2:
            raise ValueError(f"lat_lon: expected (K, 2) latitude/longitude in degrees, got shape {lat_lon.shape}")
        keep = np.all(np.isfinite(lat_lon), axis=-1)
        if not keep.any():
            return
        self._geo.append(np.stack([lat_lon[keep].min(axis=0), lat_lon[keep].max(axis=0)]))
        colour, _ = spatial_style(entity)
        self.stream.send_columns(entity, indexes=self._indexes(steps, times, keep), columns=rr.GeoPoints.columns(positions=lat_lon[keep]))
        self.stream.log(entity, _style("GeoPoints", colour, 4.0), static=True)
        self.stream.log(
            f"{entity}/path", rr.GeoLineStrings(lat_lon=[lat_lon[keep]], colors=[colour], radii=rr.Radius.ui_points(1.5)), static=True
        )
        self._note(entity, "Map")
        self._note(f"{entity}/path", "Map")

    def _unlogged(self, entity: str, steps, positions: np.ndarray, times) -> np.ndarray:
        """The rows of a shared path's points (:data:`SHARED_ROLES`) not logged before at the same step and time with
        the same position (all rows for the other paths), noting them as logged (in blocks, one per call that logged
        some: a streamed run's chunks are appended, not merged)."""
        key = entity.strip("/")
        parts = key.split("/")
        if len(parts) < 2 or parts[1] not in SHARED_ROLES:
            return np.ones(len(positions), dtype=bool)
        steps = np.asarray(steps, dtype=np.int64)
        clock = np.full(steps.shape, np.nan) if times is None else np.asarray(times, dtype=np.float64)
        keep = np.ones(steps.shape, dtype=bool)
        blocks = self._shared.setdefault(key, [])
        if not steps.size:
            return keep
        low, high = steps.min(), steps.max()
        for old_steps, old_xyz, old_clock in blocks:
            if old_steps[0] > high or old_steps[-1] < low:
                continue
            at = np.clip(np.searchsorted(old_steps, steps), 0, old_steps.size - 1)
            same = (old_steps[at] == steps) & np.all((old_xyz[at] == positions) | (np.isnan(old_xyz[at]) & np.isnan(positions)), axis=-1)
            keep &= ~(same & ((old_clock[at] == clock) | (np.isnan(old_clock[at]) & np.isnan(clock))))
        if keep.any():
            order = np.argsort(steps[keep], kind="stable")
            blocks.append((steps[keep][order], positions[keep][order], clock[keep][order]))
        return keep

    def log_path(self, entity, steps, positions, times=None, *, points=True, line=True):
        positions = _xyz(positions)
        if points:
            keep = self._unlogged(entity, steps, positions, times)
            if keep.all():
                self.log_points(entity, steps, positions, times)
            elif keep.any():
                self.log_points(entity, np.asarray(steps)[keep], positions[keep], _rows(times, keep))
        if line:
            finite = np.all(np.isfinite(positions), axis=-1)
            pieces = finite_runs(finite)
            if not pieces:
                return
            colour, label = spatial_style(entity)
            rr = self._rr
            fan = is_hypothesis(entity)
            if fan:  # a bank's hypothesis: in play over separate periods, one strip each (no line joins the gaps)
                strips = [positions[a:b] for a, b in pieces]
                style = {"colors": [colour], "radii": [rr.Radius.ui_points(0.6)]}
            else:  # labelled (the label shows on hover; drawn only for the truth and the observer, which do not overlap)
                strips, style = [positions[finite]], {"colors": [colour], "radii": [rr.Radius.ui_points(1.0)], "labels": [label]}
                style["show_labels"] = entity.strip("/").split("/")[1:2] in (["truth"], ["observer"])
            self.stream.log(f"{entity}/path", rr.LineStrips3D(strips, **style), static=True)
            self._note(f"{entity}/path", "3D")
            stride = max(1, -(-int(finite.sum()) // SPACETIME_POINTS))
            if fan:  # each piece thinned on its own, its last point kept; the space-time view breaks the line between pieces
                kept = [np.unique(np.r_[np.arange(a, b, stride), b - 1]) for a, b in pieces]
                rows = np.concatenate(kept)
                self._breaks[entity.strip("/")] = np.cumsum([len(k) for k in kept])[:-1]
            else:
                rows = np.flatnonzero(finite)[::stride]
            self._tracks[entity.strip("/")] = (np.asarray(steps)[rows], positions[rows], _rows(times, rows))

    def log_scalars(self, entity, steps, values, times=None, names=None):
        rr = self._rr
        values = np.asarray(values, dtype=np.float64)
        self.stream.send_columns(entity, indexes=self._indexes(steps, times), columns=rr.Scalars.columns(scalars=values))
        first = self._note(entity, "TimeSeries")
        if first or names is not None:
            labels, colours = series_style(entity, 1 if values.ndim == 1 else values.shape[1], names)
            widths = [LANE_WIDTH] * len(labels) if is_mode_series(entity) else None
            self.stream.log(
                entity, _series_lines(tuple(labels), tuple(map(tuple, colours)), None if widths is None else tuple(widths)), static=True
            )

    def log_event(self, step, text, time=None, level="INFO"):
        check_recordable_times(time, "time")
        self.stream.set_time("step", sequence=int(step))
        if time is not None:
            self.stream.set_time("time", duration=float(time))
            if self._epoch is not None:
                self.stream.set_time("utc", timestamp=self._utc(time))
                self._on_utc = True
        self.stream.log("events/decisions", self._rr.TextLog(text, level=level))
        self._note("events/decisions", "TextLog")
        self._events.append((int(step), str(text)))

    def log_modes(self, entity, steps, modes, names, times=None):
        steps = np.asarray(steps, dtype=np.int64)
        modes = np.asarray(modes)
        if modes.shape != steps.shape:
            raise ValueError(f"modes: expected one mode index per step, shape {steps.shape}, got {modes.shape}")
        self._modes[entity.strip("/")] = (steps, modes.astype(np.int64), tuple(str(n) for n in names))

    def _log_strips(self, entity, steps, strips, counts, times, rows=slice(None)):
        """Line strips of P points each: ``strips`` (S, P, 2 or 3), ``counts`` strips per step of ``rows`` (Σ = S).

        The Arrow array is built directly (one buffer) instead of strip by strip: for a bank's
        ellipses that is the difference between a few ms and a few hundred.
        """
        import pyarrow as pa

        rr = self._rr
        strip_type = rr.components.LineStrip3DBatch(None).as_arrow_array().type  # the component's Arrow type
        strips = np.ascontiguousarray(_xyz(strips), dtype=np.float32)
        S, P = strips.shape[:2]
        points = pa.FixedSizeListArray.from_arrays(pa.array(strips.reshape(-1)), type=strip_type.value_type)
        array = pa.ListArray.from_arrays(pa.array(np.arange(S + 1, dtype=np.int32) * P), points, type=strip_type)
        self.stream.send_columns(
            entity,
            indexes=self._indexes(steps, times, rows),
            columns=rr.LineStrips3D.columns(strips=array).partition(np.asarray(counts, dtype=np.int64)),
        )
        if self._note(entity, "3D"):
            colour, _ = spatial_style(entity)
            self.stream.log(entity, _style("LineStrips3D", colour, 0.75), static=True)

    def log_ellipses(self, entity, steps, centers, covs, times=None, sigmas=2.0):
        centers, covs = np.asarray(centers, dtype=np.float64), np.asarray(covs, dtype=np.float64)
        keep = np.all(np.isfinite(centers), axis=-1) & np.all(np.isfinite(covs), axis=(-1, -2))
        if keep.any():
            outlines = ellipse_outlines(centers[keep], covs[keep], sigmas)
            self._log_strips(entity, steps, outlines, np.ones(len(outlines)), times, keep)

    def log_lines(self, entity, steps, starts, ends, times=None):
        starts, ends = np.asarray(starts, dtype=np.float64), np.asarray(ends, dtype=np.float64)
        if starts.ndim == 2:
            starts, ends = starts[:, None], ends[:, None]
        segments = np.stack([starts, ends], axis=-2)  # (K, L, 2, 2)
        finite = np.all(np.isfinite(segments), axis=(-1, -2))  # (K, L)
        self._log_strips(entity, steps, segments[finite], finite.sum(axis=1), times)

    # -- the space-time view and the blueprint, when the run ends
    def _log_spacetime(self) -> dict[str, tuple]:
        """The space-time view: each whole path as (x, y, s (t − t₀)), mode changes and decisions marked.

        Returns the camera placements of the two 3-D views (origin → (position, target)).
        """
        if not self._tracks:
            return {}
        rr = self._rr
        use_times = all(t is not None for _, _, t in self._tracks.values())
        clock = {e: (t if use_times else s.astype(np.float64)) for e, (s, _, t) in self._tracks.items()}
        t0 = min(float(c.min()) for c in clock.values())
        span = max(float(c.max()) for c in clock.values()) - t0
        own = [xyz[:, :2] for e, (_, xyz, _) in self._tracks.items() if not is_hypothesis(e)]  # the bank's fans aside
        plane = np.concatenate(own or [xyz[:, :2] for _, xyz, _ in self._tracks.values()])
        low, high = plane.min(axis=0), plane.max(axis=0)
        centre, extent = (low + high) / 2, float(max(np.max(high - low), 1.0))  # largest horizontal extent, ≥ 1 m
        scale = extent / span if span > 0 else 1.0
        lifted = {}
        for entity, (steps, xyz, _) in self._tracks.items():
            points = np.column_stack([xyz[:, 0], xyz[:, 1], (clock[entity] - t0) * scale])
            lifted[entity] = (steps, points)
            target = "spacetime/" + entity.split("/", 1)[-1]
            colour, label = spatial_style(entity)
            if entity in self._modes and points.shape[0] > 1:
                mode_steps, modes, names = self._modes[entity]
                at = modes[np.clip(np.searchsorted(mode_steps, steps, side="right") - 1, 0, len(modes) - 1)]
                cuts = np.flatnonzero(np.diff(at)) + 1
                bounds = np.concatenate([[0], cuts, [len(at)]])
                strips = [points[a : min(b + 1, len(points))] for a, b in zip(bounds[:-1], bounds[1:])]
                labels = [names[m] if 0 <= m < len(names) else "undecided" for m in at[bounds[:-1]]]
                colours = [palette(n) if n != "undecided" else colour for n in labels]
                style = {"colors": colours, "labels": labels, "radii": [rr.Radius.ui_points(2.0)], "show_labels": False}
                if cuts.size:
                    self.stream.log(
                        f"{target}/changes",
                        rr.Points3D(
                            points[cuts],
                            colors=[palette(n) for n in labels[1:]],
                            labels=[f"{label} → {n} (step {int(steps[c])})" for n, c in zip(labels[1:], cuts)],
                            radii=[rr.Radius.ui_points(4.0)],
                            show_labels=False,  # on hover: only the decisions are labelled in the view
                        ),
                        static=True,
                    )
                    self._note(f"{target}/changes", "3D")
            elif is_hypothesis(entity):  # pieces in play, unlabelled: the fan out of each switch
                strips = [piece for piece in np.split(points, self._breaks.get(entity, [])) if len(piece) > 1]
                style = {"colors": [colour], "radii": [rr.Radius.ui_points(0.75)]}
            else:
                strips, style = [points], {"colors": [colour], "labels": [label], "radii": [rr.Radius.ui_points(1.5)], "show_labels": False}
            if strips:
                self.stream.log(target, rr.LineStrips3D(strips, **style), static=True)
                self._note(target, "3D")
        if self._events:
            moded = [e for e in lifted if e in self._modes and not e.endswith("truth")]
            whole = [e for e in lifted if not is_hypothesis(e)] or list(lifted)
            reference = (moded or [e for e in whole if e.endswith("truth")] or whole)[0]
            steps, points = lifted[reference]
            marks: dict[int, list[str]] = {}  # the decisions of one step share one mark and one label
            for step, text in self._events:
                marks.setdefault(step, []).append(short_decision(text))
            at = np.clip(np.searchsorted(steps, list(marks)), 0, len(steps) - 1)
            self.stream.log(
                "spacetime/decisions",
                rr.Points3D(
                    points[at],
                    colors=[palette("decision")],
                    labels=[", ".join(texts) for texts in marks.values()],
                    radii=[rr.Radius.ui_points(5.0)],
                ),
                static=True,
            )
            self._note("spacetime/decisions", "3D")
        cx, cy = (float(c) for c in centre)
        return {
            "/world": ((cx, cy - 0.75 * extent, 1.05 * extent), (cx, cy, 0.0)),
            "/spacetime": ((cx + 1.05 * extent, cy - 1.05 * extent, 1.1 * extent), (cx, cy, 0.5 * extent)),
        }

    def log_result(self, result, **context):
        """Record a finished run's result (:func:`hybridtrack.recording.results.log_result`)."""
        log_result(result, self, **context)

    @property
    def timeline(self) -> str | None:
        """The timeline the embedded blueprint opens on: ``utc`` when something was logged on it, else None (the
        viewer's choice, ``step``)."""
        return "utc" if self._on_utc else None

    def blueprint(self):
        """The blueprint of what was logged so far (:func:`content_blueprint`)."""
        return content_blueprint(self.content, time_step=self._time_step, timeline=self.timeline)

    def flush(self):
        """Block until everything logged so far is written to the file (no footer yet: that comes with :meth:`close`)."""
        if not self._closed:
            self.stream.flush()

    def close(self):
        """Log the space-time view, embed the blueprint of what was logged, flush and close; idempotent.

        Every :data:`SWEEP_EVERY` closes the closed streams are freed (:func:`free_closed_streams`): rerun keeps every
        stream it made until the process ends (its threads, ~0.6 MB each) unless told to let go of the orphaned ones."""
        if not self._closed:
            self._closed = True
            eyes = None
            try:
                eyes = self._log_spacetime()
            finally:
                zoom = map_zoom(np.concatenate(self._geo)) if self._geo else None
                blueprint = content_blueprint(self.content, time_step=self._time_step, eyes=eyes, map_zoom=zoom, timeline=self.timeline)
                self.stream.send_blueprint(blueprint)
                self.stream.disconnect()  # flushes the batcher and the file, writes the footer, closes the file
                self._release()
                global _closed_since_sweep
                _closed_since_sweep += 1
                if _closed_since_sweep >= SWEEP_EVERY:
                    _closed_since_sweep = 0
                    free_closed_streams(self._rr)

    def _release(self) -> None:
        """Let go of the closed stream and of what was kept for :meth:`close` (the paths, modes, events, corners).

        A recorder kept after ``with`` (a test, a notebook) then no longer holds the SDK's stream nor the copies of
        its paths.  Logging after :meth:`close` is a ValueError naming the file.
        """
        self.stream = _ClosedStream(self.path)
        self._tracks, self._modes, self._shared, self._breaks, self._geo, self._events = {}, {}, {}, {}, [], []
        self._index_columns = {}

    def __exit__(self, *exc):
        self.close()
        return False


def component_names(sensor) -> list[str]:
    """The names of a sensor's measured components: its ``components`` (``("vx", "vy")``), else ``[0]``, ``[1]``, …
    (the sensor's own name alone for a one-component sensor without them, e.g. a bearing)."""
    m = int(sensor.measurement_dim)
    if sensor.components is not None and len(sensor.components) == m:
        return [str(c) for c in sensor.components]
    return [""] if m == 1 else [f"[{i}]" for i in range(m)]


def measured_components(sensors) -> list[str]:
    """``<sensor> <component>`` for every column of the network's stacked z (the innovations' legend names)."""
    return [f"{s.name} {c}".strip() for s in sensors for c in component_names(s)]


def log_measurements(recorder, sensors, measurements, steps, times=None) -> None:
    """Log each sensor's measurements: points when it measures (x, y), scalar series otherwise (one per component,
    named ``<sensor> <component>``)."""
    for sensor in sensors:
        z = measurements[sensor.name]
        entity = f"world/measurements/{sensor.name}"
        if sensor.components is not None and tuple(sensor.components) == ("x", "y"):
            recorder.log_points(entity, steps, z, times)
        else:
            names = component_names(sensor)
            recorder.log_scalars(entity, steps, z, times, names=names if np.ndim(z) == 2 and np.shape(z)[1] == len(names) > 1 else None)


def log_estimate(recorder, name, steps, means, covs, position, times=None, *, line: bool = True) -> None:
    """An estimate's path under ``world/estimate/<name>`` and its 2σ position ellipses under ``…/ellipse``.

    ``means`` (K, n), ``covs`` (K, n, n); ``position`` the indices of x and y in the layout;
    ``line=False`` leaves out the static path line (a streamed chunk of a longer run).
    """
    recorder.log_path(f"world/estimate/{name}", steps, means[:, position], times, line=line)
    recorder.log_ellipses(f"world/estimate/{name}/ellipse", steps, means[:, position], covs[:, position][:, :, position], times)


def log_run(recorder, run, name: str, *, sensors=(), measurements=None, truth=None) -> np.ndarray:
    """The truth ``world/truth`` (a trajectory, when given), each sensor's ``measurements`` (sensor name →
    (K+1, m)) and the estimate of a finished ``run`` (:func:`log_estimate`); returns its steps 0 … K."""
    steps, times = np.arange(run.steps), run.times
    if truth is not None:
        recorder.log_path("world/truth", steps, truth.positions[: steps.size], times)
    log_measurements(recorder, sensors, {key: value[: steps.size] for key, value in (measurements or {}).items()}, steps, times)
    log_estimate(recorder, name, steps, run.means, run.covs, [run.layout.index("x"), run.layout.index("y")], times)
    return steps


def log_mode(recorder, name: str, steps, run, series: str = "mode") -> None:
    """A run's mode per step (indices into ``run.modes``): ``estimator/<name>/<series>``, one series per mode the
    run was in, named after it, in its palette colour, on its own lane (:func:`~hybridtrack.recording.style.mode_lanes`),
    and the mode colouring of ``world/estimate/<name>`` (:meth:`Recorder.log_modes`)."""
    lanes, names = mode_lanes(run.mode, run.modes)
    if names:
        recorder.log_scalars(f"estimator/{name}/{series}", steps, lanes[:, 0] if len(names) == 1 else lanes, run.times, names=names)
    recorder.log_modes(f"world/estimate/{name}", steps, run.mode, run.modes, run.times)


def nis_bounds(dims: np.ndarray, probability: float = 0.95) -> np.ndarray:
    """The two-sided χ² interval of the NIS per step: (K, 2) = F⁻¹_{χ²(m_k)}((1 ∓ p)/2), NaN where m_k = 0.

    Under a consistent filter νᵀS⁻¹ν ~ χ²(m) with m the measured components (Bar-Shalom, Li and
    Kirubarajan 2001, §5.4.2): a fraction ``probability`` of the steps falls inside.
    """
    m = np.asarray(dims, dtype=np.float64)
    tails = np.array([(1 - probability) / 2, (1 + probability) / 2])
    with np.errstate(invalid="ignore"):
        return chi2_quantile(tails[None, :], np.where(m > 0, m, np.nan)[:, None])


def short_decision(text: str) -> str:
    """The label of a decision in the space-time view: the event without the detector and the statistics
    (``sprt_pairwise: left_turn_r3 accepted with margin 4.76 (A = 4.60)`` → ``left_turn_r3 accepted``), ≤ 40 characters."""
    head, _, body = text.partition(": ")
    body = head if not body or body.startswith("x0=") else re.split(r" with | \(|, |: ", body)[0]  # a TMA solution: its method
    return body if len(body) <= 40 else body[:39] + "…"


def decision_text(decision) -> str:
    """The event line of a decision: ``<detector>: <message>`` naming the accepted hypothesis
    (``<detector>: <mode> (<message>)`` when the message does not name it)."""
    if decision.message and decision.mode in decision.message:
        return f"{decision.detector}: {decision.message}"
    return f"{decision.detector}: {decision.mode}" + (f" ({decision.message})" if decision.message else "")


def open_recorder(path: str | Path | None, configuration: dict | None = None):
    """A :class:`RerunRecorder` writing ``path``, or a :class:`NullRecorder` when ``path`` is None."""
    return NullRecorder() if path is None else RerunRecorder(path, configuration)
