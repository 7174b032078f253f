"""The recorder seam: every run logs through a recorder object passed in.

Components never touch rerun's global stream.  :class:`RerunRecorder` owns one
``rerun.RecordingStream`` (application id ``hybridtrack``) with a file sink;
:class:`NullRecorder` records nothing (Monte Carlo).  Both are context managers;
leaving the context (normally or by an exception) flushes and closes the file so
it is always complete; :meth:`RerunRecorder.flush` pushes what was logged so far
to the file during a run (the pipeline streams its rows and flushes every few
seconds), so a killed process leaves a file — without its footer — holding
everything logged up to the last flush.

Series are logged as whole columns (``send_columns``) on the timelines ``step``
(sequence) and ``time`` (duration in seconds, when times are given).  Entity
paths used by the built-in components:

The full list of entity paths is in ``docs/recording.md``.  Every file
carries the default blueprint of :func:`default_blueprint` (trajectories,
likelihood ratios, signal functions, events) and the run's configuration as
the recording property ``configuration``.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

APPLICATION_ID = "hybridtrack"

#: the largest |t| in seconds the ``time`` timeline holds: rerun durations are int64 nanoseconds
MAX_RECORDABLE_SECONDS = (2**63 - 1) / 1e9


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
        """A 2-D trajectory: positions (K, 2), one point per step (``points``) and the whole path as a static line
        ``<entity>/path`` (``line``; a streamed run logs the points chunk by chunk and the line once at the end)."""

    def log_points(self, entity: str, steps: np.ndarray, points: np.ndarray, times: np.ndarray | None = None) -> None:
        """2-D points (K, 2) per step, or a variable number per step as (K, L, 2) NaN-padded (e.g. clutter);
        rows with NaN are skipped."""

    def log_scalars(
        self, entity: str, steps: np.ndarray, values: np.ndarray, times: np.ndarray | None = None, names: Sequence[str] | None = None
    ) -> None:
        """Scalar series: values (K,) or (K, c) (c named series under one entity)."""

    def log_event(self, step: int, text: str, time: float | None = None, level: str = "INFO") -> None:
        """A text event (decisions, warnings) at ``step``."""

    def log_ellipses(
        self, entity: str, steps: np.ndarray, centers: np.ndarray, covs: np.ndarray, times: np.ndarray | None = None, sigmas: float = 2.0
    ) -> None:
        """Covariance ellipses: centers (K, 2), 2×2 position covariances (K, 2, 2), drawn at ``sigmas``."""

    def log_lines(self, entity: str, steps: np.ndarray, starts: np.ndarray, ends: np.ndarray, times: np.ndarray | None = None) -> None:
        """One or more 2-D segments per step: starts, ends of shape (K, 2) or (K, L, 2) (e.g. bearing lines)."""

    def flush(self) -> None:
        """Write what was logged so far to the sink (blocks until it reached the file)."""

    def close(self) -> None:
        """Flush and close; idempotent."""


class NullRecorder:
    """Records nothing (recording turned off)."""

    def log_path(self, entity, steps, positions, times=None, *, points=True, line=True):
        pass

    def log_points(self, entity, steps, points, times=None):
        pass

    def log_scalars(self, entity, steps, values, times=None, names=None):
        pass

    def log_event(self, step, text, time=None, level="INFO"):
        pass

    def log_ellipses(self, entity, steps, centers, covs, times=None, sigmas=2.0):
        pass

    def log_lines(self, entity, steps, starts, ends, times=None):
        pass

    def flush(self):
        pass

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def recording_id(configuration: dict) -> str:
    """A stable recording id from a run's configuration (which includes its seed)."""
    text = json.dumps(configuration, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def default_blueprint():
    """The layout stored in every file: trajectories, likelihood ratios, signal functions, events."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin="/world", name="Trajectories"),
            rrb.Vertical(
                rrb.TimeSeriesView(
                    origin="/detector",
                    contents=["+ /detector/**", "- /detector/signal_function/**"],
                    name="Likelihood ratios and statistics",
                ),
                rrb.TimeSeriesView(
                    origin="/", contents=["+ /detector/signal_function/**", "+ /estimator/**"], name="Signal functions, NIS, bank size"
                ),
                rrb.TextLogView(origin="/events", name="Events"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


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


class RerunRecorder:
    """A file recording (.rrd) on its own ``rerun.RecordingStream``.

    ``configuration`` (a JSON-able dict, seed included) gives the recording id,
    so the same run twice gives the same id, and is stored as the recording
    property ``configuration``.  The default blueprint is embedded (``blueprint``: another layout, e.g.
    :func:`hybridtrack.tracking.track_blueprint`).
    """

    def __init__(self, path: str | Path, configuration: dict | None = None, *, recording_id_: str | None = None, blueprint=None):
        import rerun as rr

        self._rr = rr
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.configuration = dict(configuration or {})
        self.recording_id = recording_id_ or recording_id(self.configuration)
        self.stream = rr.RecordingStream(APPLICATION_ID, recording_id=self.recording_id)
        self.stream.save(str(self.path), default_blueprint=default_blueprint() if blueprint is None else blueprint)
        self.stream.send_property("configuration", rr.AnyValues(json=json.dumps(self.configuration, sort_keys=True, default=str)))
        self._closed = False

    # -- helpers
    def _indexes(self, steps, times):
        check_recordable_times(times)
        rr = self._rr
        steps = np.asarray(steps, dtype=np.int64)
        indexes = [rr.TimeColumn("step", sequence=steps)]
        if times is not None:
            indexes.append(rr.TimeColumn("time", duration=np.asarray(times, dtype=np.float64)))
        return indexes

    def _set_time(self, step, time):
        check_recordable_times(time, "time")
        self.stream.set_time("step", sequence=int(step))
        if time is not None:
            self.stream.set_time("time", duration=float(time))

    # -- Recorder
    def log_points(self, entity, steps, points, times=None):
        points = np.asarray(points, dtype=np.float64)
        keep = np.all(np.isfinite(points), axis=-1)  # (K,) or (K, L) for several points per step
        if not keep.any():
            return
        counts = keep.reshape(keep.shape[0], -1).sum(axis=1)
        present = counts > 0
        steps = np.asarray(steps)[present]
        times = None if times is None else np.asarray(times)[present]
        self.stream.send_columns(
            entity,
            indexes=self._indexes(steps, times),
            columns=self._rr.Points2D.columns(positions=points[keep]).partition(counts[present].astype(np.int64)),
        )

    def log_path(self, entity, steps, positions, times=None, *, points=True, line=True):
        positions = np.asarray(positions, dtype=np.float64)
        if points:
            self.log_points(entity, steps, positions, times)
        if line:
            finite = positions[np.all(np.isfinite(positions), axis=-1)]
            self.stream.log(f"{entity}/path", self._rr.LineStrips2D([finite]), static=True)

    def log_scalars(self, entity, steps, values, times=None, names=None):
        rr = self._rr
        values = np.asarray(values, dtype=np.float64)
        self.stream.send_columns(entity, indexes=self._indexes(steps, times), columns=rr.Scalars.columns(scalars=values))
        if names is not None:
            self.stream.log(entity, rr.SeriesLines(names=list(names)), static=True)

    def log_event(self, step, text, time=None, level="INFO"):
        self._set_time(step, time)
        self.stream.log("events/decisions", self._rr.TextLog(text, level=level))

    def _log_strips(self, entity, steps, strips, counts, times):
        """Line strips of P points each: ``strips`` (S, P, 2), ``counts`` (K,) strips per step (ΣK = S).

        The Arrow array is built directly (one buffer) instead of strip by strip: for a bank's
        ellipses that is the difference between a few ms and a few hundred.
        """
        import pyarrow as pa

        strip_type = self._rr.components.LineStrip2DBatch._ARROW_DATATYPE
        strips = np.ascontiguousarray(strips, dtype=np.float32)
        S, P = strips.shape[:2]
        points = pa.FixedSizeListArray.from_arrays(pa.array(strips.reshape(-1)), type=strip_type.value_type)
        array = pa.ListArray.from_arrays(pa.array(np.arange(S + 1, dtype=np.int32) * P), points, type=strip_type)
        self.stream.send_columns(
            entity,
            indexes=self._indexes(steps, times),
            columns=self._rr.LineStrips2D.columns(strips=array).partition(np.asarray(counts, dtype=np.int64)),
        )

    def log_ellipses(self, entity, steps, centers, covs, times=None, sigmas=2.0):
        centers, covs = np.asarray(centers, dtype=np.float64), np.asarray(covs, dtype=np.float64)
        keep = np.all(np.isfinite(centers), axis=-1) & np.all(np.isfinite(covs), axis=(-1, -2))
        if keep.any():
            outlines = ellipse_outlines(centers[keep], covs[keep], sigmas)
            times = None if times is None else np.asarray(times)[keep]
            self._log_strips(entity, np.asarray(steps)[keep], outlines, np.ones(len(outlines)), times)

    def log_lines(self, entity, steps, starts, ends, times=None):
        starts, ends = np.asarray(starts, dtype=np.float64), np.asarray(ends, dtype=np.float64)
        if starts.ndim == 2:
            starts, ends = starts[:, None], ends[:, None]
        segments = np.stack([starts, ends], axis=-2)  # (K, L, 2, 2)
        finite = np.all(np.isfinite(segments), axis=(-1, -2))  # (K, L)
        self._log_strips(entity, steps, segments[finite], finite.sum(axis=1), times)

    def flush(self):
        """Block until everything logged so far is written to the file (no footer yet: that comes with :meth:`close`)."""
        if not self._closed:
            self.stream.flush()

    def close(self):
        if not self._closed:
            self._closed = True
            self.stream.flush()
            self.stream.disconnect()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def log_measurements(recorder, sensors, measurements, steps, times=None) -> None:
    """Log each sensor's measurements: points when it measures (x, y), scalar series otherwise."""
    for sensor in sensors:
        z = measurements[sensor.name]
        entity = f"world/measurements/{sensor.name}"
        if sensor.components is not None and tuple(sensor.components) == ("x", "y"):
            recorder.log_points(entity, steps, z, times)
        else:
            recorder.log_scalars(entity, steps, z, times)


def log_estimate(recorder, name, steps, means, covs, position, times=None, *, line: bool = True) -> None:
    """An estimate's path under ``world/estimate/<name>`` and its 2σ position ellipses under ``…/ellipse``.

    ``means`` (K, n), ``covs`` (K, n, n); ``position`` the indices of x and y in the layout;
    ``line=False`` leaves out the static path line (a streamed chunk of a longer run).
    """
    index = np.ix_(position, position)
    recorder.log_path(f"world/estimate/{name}", steps, means[:, position], times, line=line)
    recorder.log_ellipses(f"world/estimate/{name}/ellipse", steps, means[:, position], covs[:, index[0], index[1]], times)


def open_recorder(path: str | Path | None, configuration: dict | None = None):
    """A :class:`RerunRecorder` writing ``path``, or a :class:`NullRecorder` when ``path`` is None."""
    return NullRecorder() if path is None else RerunRecorder(path, configuration)
