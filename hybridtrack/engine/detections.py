"""Unlabelled detections grouped into scans, and the true objects behind them (issue 23, item 1).

A sensor without identities (a radar, a camera, an AIS receiver read without its MMSI column) returns at scan k a
set Z_k = {z_{k,1}, …, z_{k,m_k}} of detections of unknown origin: some from the objects present (each detected
with probability P_D), the rest clutter (Bar-Shalom, Willett & Tian, *Tracking and Data Fusion*, YBS 2011, §2.2;
Blackman & Popoli, *Design and Analysis of Modern Tracking Systems*, Artech House 1999, §6.1).  :class:`Detections`
holds all scans as one flat table, sorted by scan: detection i has its own time stamp ``times[i]``, its scan
``scan[i]`` and its measured position ``z[i]``; scan k holds the rows ``bounds()[k]`` and has the time
``scan_times[k]`` (a tracker predicts its tracks to that time).  The simulator also knows each detection's
``origin`` (the object index, −1 for clutter) and the :class:`Truth`; a tracker never reads them.

Grouping flat detections into scans (:meth:`Detections.from_times`, :func:`group_scans`):

* by a scan column: the distinct labels in increasing order are scans 0 … K−1; a scan's time is the latest time
  stamp among its detections, and these must increase strictly with the label;
* by a time window w: with t₀ the earliest time stamp, detection i falls in window k = ⌊(t_i − t₀)/w⌋, the half-open
  [t₀ + k w, t₀ + (k+1) w) — except that the latest time stamp, when it lies exactly on a window's start, closes
  the window before it (the last bin is closed, as in :func:`numpy.histogram`); a window's scan time is its end
  t₀ + (k+1) w, the last one's capped at the latest time stamp; windows without detections are no scans.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from hybridtrack.core.validation import as_float_array

#: the names of the position components in a :class:`Truth` layout, in the order of :attr:`Truth.positions`
POSITION_NAMES = ("x", "y", "z")


def _immutable(value, kind: str) -> bool:
    """Whether ``value`` is a read-only array of ``kind`` (``"f"``: float64, ``"i"``: intp) owning its data: immutable
    (the pattern of :mod:`hybridtrack.core.validation`), so kept as it is instead of copied (simulated scenes of
    millions of detections hand theirs over this way)."""
    dtype = np.float64 if kind == "f" else np.intp
    return isinstance(value, np.ndarray) and value.dtype == dtype and value.base is None and not value.flags.writeable


def _floats(name: str, axes: int):
    """An attrs field holding a read-only float64 copy with ``axes`` axes, finite, named ``name`` in errors."""

    def convert(value):
        shape = (None,) * axes
        return as_float_array(value, name, shape, readonly=not _immutable(value, "f"))

    return attrs.field(converter=convert)


def index_array(value, name: str) -> np.ndarray:
    """``value`` as a read-only 1-D intp copy (an immutable intp array as it is): integers (or floats of integral value);
    a ValueError naming ``name``."""
    array = np.asarray(value)
    if array.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array of integers, got shape {array.shape}")
    if _immutable(value, "i"):
        return value
    if array.dtype.kind not in "iu":
        if array.size and array.dtype.kind != "f":
            raise ValueError(f"{name}: expected integers, got dtype {array.dtype}")
        bad = ~np.isfinite(array) | (array != np.round(array)) if array.size else np.zeros(0, dtype=bool)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{name}: expected integers, got {array[i].item()!r} at index {i}")
    out = np.array(array, dtype=np.intp, copy=True)
    out.setflags(write=False)
    return out


def _indices(name: str, optional: bool = False):
    def convert(value):
        return None if value is None and optional else index_array(value, name)

    return attrs.field(converter=convert, default=None) if optional else attrs.field(converter=convert)


def _layout(value) -> tuple[str, ...]:
    if isinstance(value, str) or not all(isinstance(name, str) for name in value):
        raise TypeError(f"layout: expected a sequence of component names (str), got {value!r}")
    layout = tuple(value)
    if len(set(layout)) != len(layout):
        raise ValueError(f"layout: component names must be distinct, got {layout}")
    if not {"x", "y"} <= set(layout):
        raise ValueError(f"layout: expected the position components 'x' and 'y' among the names, got {layout}")
    return layout


@attrs.frozen(eq=False)
class Truth:
    """The true objects, one row per object per scan (a flat table): ``times`` (P,) seconds (the scan times),
    ``ids`` (P,) the object index (≥ 0), ``states`` (P, n) in ``layout`` (component names, e.g.
    ``("x", "vx", "y", "vy")``, holding ``x`` and ``y``).  An object appears at most once per time."""

    times: np.ndarray = _floats("times", 1)
    ids: np.ndarray = _indices("ids")
    states: np.ndarray = _floats("states", 2)
    layout: tuple[str, ...] = attrs.field(converter=_layout)

    def __attrs_post_init__(self):
        p = self.times.shape[0]
        if self.ids.shape != (p,):
            raise ValueError(f"ids: expected shape ({p},) (one per row of times), got {self.ids.shape}")
        if self.states.shape != (p, len(self.layout)):
            raise ValueError(
                f"states: expected shape ({p}, {len(self.layout)}) (rows of times, components of layout), got {self.states.shape}"
            )
        if p and self.ids.min() < 0:
            i = int(np.argmin(self.ids))
            raise ValueError(f"ids: expected object indices ≥ 0, got {int(self.ids[i])} at row {i}")
        dt, di = np.diff(self.times), np.diff(self.ids)
        if np.any((dt < 0) | ((dt == 0) & (di < 0))):  # not yet by time, then by object: sort to find repeats
            order = np.lexsort((self.ids, self.times))
            dt, di = np.diff(self.times[order]), np.diff(self.ids[order])
        else:
            order = np.arange(p)
        same = (dt == 0) & (di == 0)
        if same.any():
            row = int(order[np.flatnonzero(same)[0]])
            raise ValueError(
                f"ids: object {int(self.ids[row])} appears twice at time {float(self.times[row])} (one row per object per time)"
            )

    @property
    def size(self) -> int:
        """P, the number of rows."""
        return self.times.shape[0]

    @property
    def objects(self) -> int:
        """The number of distinct objects."""
        return int(np.unique(self.ids).size)

    @property
    def positions(self) -> np.ndarray:
        """(P, 2) the x, y components of ``states`` — (P, 3) with z when the layout has one."""
        names = [name for name in POSITION_NAMES if name in self.layout]
        return self.states[:, [self.layout.index(name) for name in names]]

    def at(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """(ids, states) of the objects present at ``time`` (exactly equal times)."""
        rows = np.flatnonzero(self.times == time)
        return self.ids[rows], self.states[rows]


@attrs.define(frozen=True)
class ScanGrouping:
    """Flat detections grouped into scans (:func:`group_scans`): ``order`` (N,) the permutation that sorts the
    detections by scan (and by time within a scan, ties in input order), ``scan`` (N,) the scan of each sorted
    detection, ``scan_times`` (K,) the time of each scan."""

    order: np.ndarray
    scan: np.ndarray
    scan_times: np.ndarray


def _window_of(times: np.ndarray, start: float, window: float) -> np.ndarray:
    """k with start + k w ≤ t < start + (k+1) w, the boundaries computed as ``start + k * window`` (a time on a
    boundary is in the window it starts, whatever the rounding of (t − start)/w)."""
    k = np.floor((times - start) / window).astype(np.int64)
    k += times >= start + (k + 1) * window
    k -= times < start + k * window
    return k


def group_scans(times, *, scan_window: float | None = None, scan=None) -> ScanGrouping:
    """Group detections with time stamps ``times`` (N,) into scans: by the labels ``scan`` (N,) (any numbers; the
    distinct ones in increasing order are the scans) or into windows of ``scan_window`` seconds — exactly one of the
    two (the rules: module docstring).  The detections are sorted stably by time first."""
    times = as_float_array(times, "times", (None,))
    if times.size == 0:
        raise ValueError("times: no detections to group into scans")
    if (scan_window is None) == (scan is None):
        raise ValueError(
            f"scan and scan_window: give exactly one (a scan label per detection, or the window length in seconds), got "
            f"scan={'None' if scan is None else 'an array'}, scan_window={scan_window!r}"
        )
    by_time = np.argsort(times, kind="stable")
    if scan is not None:
        labels = as_float_array(scan, "scan", (times.size,))
        order = by_time[np.argsort(labels[by_time], kind="stable")]
        distinct, index = np.unique(labels[order], return_inverse=True)
        ends = np.full(distinct.size, -np.inf)
        np.maximum.at(ends, index, times[order])
        back = np.flatnonzero(np.diff(ends) <= 0)
        if back.size:
            k = int(back[0])
            raise ValueError(
                f"scan: scan {distinct[k + 1]:g} ends at time {ends[k + 1]:g}, not after scan {distinct[k]:g} (which ends at {ends[k]:g});"
                " scans in the order of their labels must end at increasing times"
            )
        return ScanGrouping(order, index.astype(np.intp), ends)
    if isinstance(scan_window, bool) or not isinstance(scan_window, (int, float, np.integer, np.floating)):
        raise TypeError(f"scan_window: expected a number of seconds, got {type(scan_window).__name__} ({scan_window!r})")
    if not (math.isfinite(scan_window) and scan_window > 0):
        raise ValueError(f"scan_window: expected a finite number of seconds > 0, got {scan_window!r}")
    window = float(scan_window)
    order = by_time
    ordered = times[order]
    start, latest = float(ordered[0]), float(ordered[-1])
    k = _window_of(ordered, start, window)
    if k[-1] > 0 and latest == start + k[-1] * window:  # the last bin is closed: the latest time ends the window before
        k[ordered == latest] -= 1
    distinct, index = np.unique(k, return_inverse=True)
    scan_times = np.minimum(start + (distinct + 1) * window, latest)
    return ScanGrouping(order, index.astype(np.intp), scan_times)


@attrs.frozen(eq=False)
class Detections:
    """Unlabelled detections grouped into scans (module docstring).

    ``scan_times`` (K,) seconds, strictly increasing: the time of each scan (for a time window: the window's end);
    ``scan`` (N,) non-decreasing, the scan of each detection (0 … K−1; a scan may hold none); ``times`` (N,) each
    detection's own time stamp (its scan's time for simulated scans), ``times[i] ≤ scan_times[scan[i]]``; ``z``
    (N, m) the measured positions (x, y) or (x, y, z); ``origin`` (N,) the true object of each detection, −1 for
    clutter (None: unknown; never read by a tracker); ``truth`` the true objects (:class:`Truth`) or None;
    ``velocity`` (N, 2) the velocity (east, north) in m/s each detection reports (an AIS report's course and speed
    over ground, a Doppler radar's), NaN where a detection reports none, or None for detections of position only.
    """

    scan_times: np.ndarray = _floats("scan_times", 1)
    scan: np.ndarray = _indices("scan")
    times: np.ndarray = _floats("times", 1)
    z: np.ndarray = _floats("z", 2)
    origin: np.ndarray | None = _indices("origin", optional=True)
    truth: Truth | None = attrs.field(default=None)
    velocity: np.ndarray | None = attrs.field(
        default=None,
        kw_only=True,
        converter=lambda v: None if v is None else as_float_array(v, "velocity", (None, 2), allow_nan=True, readonly=True),
    )

    def __attrs_post_init__(self):
        k, n = self.scan_times.shape[0], self.scan.shape[0]
        if self.velocity is not None and self.velocity.shape[0] != n:
            raise ValueError(f"velocity: expected shape ({n}, 2) (one per detection), got {self.velocity.shape}")
        back = np.flatnonzero(np.diff(self.scan_times) <= 0)
        if back.size:
            i = int(back[0])
            raise ValueError(
                f"scan_times: expected strictly increasing times, got {self.scan_times[i]:g} then {self.scan_times[i + 1]:g} at scans {i}, {i + 1}"
            )
        if self.times.shape != (n,):
            raise ValueError(f"times: expected shape ({n},) (one per detection of scan), got {self.times.shape}")
        if self.z.shape[0] != n or self.z.shape[1] < 1:
            raise ValueError(f"z: expected shape ({n}, m) (one position per detection of scan), got {self.z.shape}")
        if n:
            if self.scan.min() < 0 or self.scan.max() >= k:
                i = int(np.flatnonzero((self.scan < 0) | (self.scan >= k))[0])
                raise ValueError(f"scan: expected scan indices 0 … {k - 1} (K = {k} scan_times), got {int(self.scan[i])} at detection {i}")
            down = np.flatnonzero(np.diff(self.scan) < 0)
            if down.size:
                i = int(down[0])
                raise ValueError(f"scan: expected non-decreasing scan indices (detections sorted by scan), got {self.scan[i]} then {self.scan[i + 1]} at detection {i + 1}")  # fmt: skip
            late = np.flatnonzero(self.times > self.scan_times[self.scan])
            if late.size:
                i = int(late[0])
                raise ValueError(
                    f"times: detection {i} at time {self.times[i]:g} is later than the time {self.scan_times[self.scan[i]]:g} of its scan {int(self.scan[i])}"
                )
        if self.origin is not None:
            if self.origin.shape != (n,):
                raise ValueError(f"origin: expected shape ({n},) (one per detection), got {self.origin.shape}")
            if n and self.origin.min() < -1:
                i = int(np.argmin(self.origin))
                raise ValueError(f"origin: expected object indices ≥ 0 or −1 (clutter), got {int(self.origin[i])} at detection {i}")
        if self.truth is not None:
            if not isinstance(self.truth, Truth):
                raise TypeError(f"truth: expected a Truth or None, got {type(self.truth).__name__}")
            if self.origin is not None:
                unknown = (self.origin >= 0) & ~np.isin(self.origin, self.truth.ids)
                if unknown.any():
                    i = int(np.flatnonzero(unknown)[0])
                    raise ValueError(f"origin: detection {i} names object {int(self.origin[i])}, which is not in truth.ids")

    @classmethod
    def from_times(
        cls, times, z, *, scan_window: float | None = None, scan=None, origin=None, truth: Truth | None = None, velocity=None
    ) -> Detections:
        """Flat detections — time stamps ``times`` (N,), positions ``z`` (N, m), optional ``origin`` (N,) and
        ``velocity`` (N, 2) — grouped
        into scans by the labels ``scan`` (N,) or into windows of ``scan_window`` seconds, exactly one of the two
        (:func:`group_scans`; module docstring); the detections are sorted stably by time, then by scan."""
        times = as_float_array(times, "times", (None,))
        z = as_float_array(z, "z", (times.size, None))
        if origin is not None:
            origin = index_array(origin, "origin")
            if origin.shape != times.shape:
                raise ValueError(f"origin: expected shape {times.shape} (one per time), got {origin.shape}")
        if velocity is not None:
            velocity = as_float_array(velocity, "velocity", (times.size, 2), allow_nan=True)
        grouping = group_scans(times, scan_window=scan_window, scan=scan)
        order = grouping.order
        return cls(
            scan_times=grouping.scan_times,
            scan=grouping.scan,
            times=times[order],
            z=z[order],
            origin=None if origin is None else origin[order],
            truth=truth,
            velocity=None if velocity is None else velocity[order],
        )

    @property
    def scans(self) -> int:
        """K, the number of scans."""
        return self.scan_times.shape[0]

    @property
    def size(self) -> int:
        """N, the number of detections."""
        return self.scan.shape[0]

    @property
    def measurement_dim(self) -> int:
        """m, the components of a detection."""
        return self.z.shape[1]

    def counts(self) -> np.ndarray:
        """m_k, the number of detections of each scan (K,)."""
        return np.bincount(self.scan, minlength=self.scans)

    def bounds(self) -> list[slice]:
        """The rows of each scan: ``bounds()[k]`` is the slice of scan k's detections (found by binary search)."""
        edges = np.searchsorted(self.scan, np.arange(self.scans + 1)).tolist()
        return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]

    def at(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(times, z) of scan ``k``."""
        if not -self.scans <= k < self.scans:
            raise IndexError(f"k: scan {k} of {self.scans}")
        k = k % self.scans
        a, b = np.searchsorted(self.scan, [k, k + 1])
        return self.times[a:b], self.z[a:b]

    def head(self, scans: int) -> Detections:
        """The first ``scans`` scans (and the truth up to the last one's time): e.g. a comparison on part of a file."""
        if isinstance(scans, bool) or not isinstance(scans, (int, np.integer)) or scans < 0:
            raise ValueError(f"scans: expected a number of scans ≥ 0, got {scans!r}")
        scans = min(int(scans), self.scans)
        n = int(np.searchsorted(self.scan, scans))
        truth = self.truth
        if truth is not None and scans < self.scans:
            keep = truth.times <= self.scan_times[scans - 1] if scans else np.zeros(truth.size, dtype=bool)
            truth = Truth(truth.times[keep], truth.ids[keep], truth.states[keep], truth.layout)
        origin = None if self.origin is None else self.origin[:n]
        velocity = None if self.velocity is None else self.velocity[:n]
        return Detections(self.scan_times[:scans], self.scan[:n], self.times[:n], self.z[:n], origin, truth, velocity=velocity)
