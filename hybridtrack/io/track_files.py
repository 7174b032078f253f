"""Reading real time-stamped position files (AIS, GPS logs): one :class:`Track` per object, in metres.

Sources (:func:`read_tracks`, ``format=`` or the file name's ending): CSV files (below), GPX 1.0/1.1 files
(:mod:`.gpx_files`, via gpxpy), raw AIS NMEA logs (:mod:`.nmea_files`, via pyais) and pandas DataFrames (the
columns of a CSV; a problem's ``line`` is the row's position + 2).  Each format's reader only produces the rows
(:class:`Rows`: text cells under a header, the line of each record, the records it could not use as
problems); checking them, grouping by id, sorting, duplicates, the speed check, the projection and the
problem reports below are the same code for every format.

CSV layout (comma separated — or ``;`` when the header has no comma — one header
row, any column order, extra columns ignored; ``.csv.gz`` is read through gzip)::

    Time,MMSI,Latitude_degrees,Longitude_degrees,COG_degrees,SOG_knots
    2016-01-12 13:02:11.218,235070762,50.7730133333333,-1.092935,157.8,5.9

Columns (names configurable, see :func:`read_tracks`):

* **time** — seconds (a decimal number; milliseconds with ``time_unit="ms"``), ISO-8601 timestamps
  (``2016-01-12 13:02:11.218``, ``2016-01-12T13:02:11Z``, ``…+01:00``) or any form a ``time_format``
  (strptime) reads (``12/01/2016 13:02:11``: ``"%d/%m/%Y %H:%M:%S"``); the first cell that is a number or a
  timestamp decides which, and every row must then use that form.
  Timestamps without a zone are read as UTC; the track times are seconds after
  :attr:`TrackFile.epoch`, the earliest valid timestamp of the file.  Numeric
  times are kept as they are (``epoch`` None); numbers ≥ 10¹¹ (epoch milliseconds
  read as seconds) are refused unless ``time_unit`` is given.
* **position** — either ``x, y`` in metres, or latitude/longitude in degrees
  (WGS-84) projected to a local east-north tangent plane at
  :attr:`TrackFile.origin` (see *Projection*).
* optional **altitude** (metres; height above the WGS-84 ellipsoid with
  latitude/longitude): positions are then (K, 3), east-north-up.
* optional **id** — one track per distinct id (in order of first appearance);
  without it the whole file is one track with id ``""``.
* optional **course** over ground (degrees, a compass bearing: clockwise from
  north) and **speed** over ground (``speed_unit``: ``"m/s"``, ``"knots"`` or
  ``"km/h"``; stored in m/s).

Projection (``projection=``):

* ``"enu"`` (default) — exact local east-north-up coordinates: geodetic →
  WGS-84 ECEF (:func:`geodetic_to_ecef`), then the rotation to the tangent
  plane at the origin (φ₀, λ₀):
  e = −sin λ₀ ΔX + cos λ₀ ΔY,
  n = −sin φ₀ cos λ₀ ΔX − sin φ₀ sin λ₀ ΔY + cos φ₀ ΔZ,
  u = cos φ₀ cos λ₀ ΔX + cos φ₀ sin λ₀ ΔY + sin φ₀ ΔZ
  (Hofmann-Wellenhof, Lichtenegger & Wasle, *GNSS*, Springer 2008, §10.2.2;
  constants a = 6 378 137 m, f = 1/298.257223563, NIMA TR8350.2).  Without an
  altitude column h = 0 and positions are (e, n); u is dropped, i.e. points are
  projected orthogonally onto the tangent plane.
* ``"equirectangular"`` — e = Δλ (N₀ + h₀) cos φ₀, n = Δφ M₀ with the prime-vertical
  and meridian radii N₀, M₀ = a (1 − e²) / (1 − e² sin² φ₀)^{3/2} at the origin
  (u = h − h₀): cheap, but its error grows with the distance from the origin.

Their error against the exact geodesic (Vincenty's inverse formula on the
WGS-84 ellipsoid, :func:`geodesic_inverse`) is measured by
:func:`projection_error` and tabulated in ``docs/real_data.md``: at 100 km from
an origin at 50.8° N, ``enu`` is within 4.12 m (the chord-versus-arc shrinkage
≈ d³/(6R²)), ``equirectangular`` off by up to 1.09 km.

What is refused and what is reported: the table of ``docs/real_data.md``.
Structural faults (an empty file, a header without data rows, a configured
column missing — the error lists the columns present — or named twice) are a
ValueError (or FileNotFoundError / IsADirectoryError / TypeError) naming the
file.  Faults of single rows are *reported, not used*: each becomes a
:class:`Problem` in the track's ``problems`` (and in :attr:`TrackFile.problems`,
with the rows that belong to no track), summarised by one warning
(``warn=False`` silences it).  Fix j is reachable from fix i when |p_j − p_i| ≤
``max_speed`` (t_j − t_i) + ``jump_tolerance`` (the tolerance absorbs AIS
receive-time jitter): bursts of at most :data:`MAX_OUTLIER_BURST` fixes not
reachable from the last good fix are dropped, a lasting jump is flagged and kept.
"""

from __future__ import annotations

import importlib
import inspect
import itertools
import math
import os
import reprlib
import sys
import warnings
from collections import Counter
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from types import SimpleNamespace

import attrs
import numpy as np

from hybridtrack.core.validation import check_positive
from hybridtrack.io.csv_text import checked_path, finite_number, read_csv

#: WGS-84 semi-major axis a (m) and flattening f (NIMA TR8350.2, 3rd ed., table 3.1)
WGS84_A = 6_378_137.0
WGS84_F = 1.0 / 298.257223563
WGS84_B = WGS84_A * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)

#: a jump is dropped as an outlier burst when one of the next this-many fixes is again reachable from the last good fix
MAX_OUTLIER_BURST = 3

PROJECTIONS = ("enu", "equirectangular")
SPEED_UNITS = {"m/s": 1.0, "knots": 1852.0 / 3600.0, "km/h": 1000.0 / 3600.0}
#: seconds per unit of a numeric time column (``time_unit``)
TIME_UNITS = {"s": 1.0, "ms": 1e-3}
#: the physical speed limit (m/s) of each object class (``object_class``): above any ship's (68 kn, fast craft
#: included), any road vehicle's (306 km/h) and any aircraft's ground speed below Mach 1.2 at altitude
SPEED_LIMITS = {"ship": 35.0, "ground": 85.0, "aircraft": 400.0}
#: numeric times from here on are no seconds of our era (the year 5138): epoch milliseconds, unless ``time_unit`` says
MILLISECONDS_LIKELY = 1e11
#: a coordinate (m) farther than this from the origin is not a position on or near the Earth (x/y files, altitude)
MAX_COORDINATE = 1e9

#: column names and codes of the Stone Soup Solent AIS CSV (``data/solent_ais/``): ``read_tracks(path, **SOLENT_AIS)``
SOLENT_AIS = {
    "time": "Time",
    "id": "MMSI",
    "lat": "Latitude_degrees",
    "lon": "Longitude_degrees",
    "course": "COG_degrees",
    "speed": "SOG_knots",
    "speed_unit": "knots",
    "course_not_available": 360.0,
    "speed_not_available": 102.3,
}

_HINT = "expected a UTF-8 CSV with a header row and one row per position report"


@attrs.frozen
class Problem:
    """One fault of the input: ``line`` of the file (the header is line 1; 0 for the whole track), the ``column``
    concerned (or None), ``kind`` (``bad_time``, ``not_a_number``, ``out_of_range``, ``bad_row``, ``missing_id``,
    ``duplicate_time``, ``conflicting_duplicate``, ``speed_jump``, ``not_available``, ``unsorted``; NMEA logs also
    ``bad_checksum`` and ``not_position``), what was done
    (``action``: ``dropped``, ``flagged``, ``set_nan``, ``sorted``) and a ``message`` naming the file and line."""

    line: int
    column: str | None
    kind: str
    action: str
    message: str
    id: str | None = None


def _column(axes, dtype=np.float64):
    return attrs.field(converter=lambda a: _readonly(a, axes, dtype), eq=attrs.cmp_using(eq=_equal_nan), hash=False)


def _readonly(value, axes, dtype):
    if value is None:
        return None
    array = np.array(value, dtype=dtype, copy=True)
    if array.ndim != axes:
        raise ValueError(f"expected {axes} axes, got shape {array.shape}")
    array.setflags(write=False)
    return array


def _equal_nan(a, b):
    if a is None or b is None:
        return a is b
    return np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


@attrs.frozen
class Track:
    """The reports of one object, sorted by time: ``times`` (K,) seconds, ``positions`` (K, 2) east/x, north/y in
    metres — or (K, 3) with up/z — ``course`` (K,) over ground in degrees clockwise from north and ``speed`` (K,)
    over ground in m/s (None when the file has no such column; NaN where not available), ``lines`` (K,) the file line
    of each report, and the ``problems`` found in this object's rows (what was dropped, flagged or set to NaN)."""

    id: str
    times: np.ndarray = _column(1)
    positions: np.ndarray = _column(2)
    lines: np.ndarray = _column(1, np.int64)
    course: np.ndarray | None = _column(1)
    speed: np.ndarray | None = _column(1)
    problems: tuple[Problem, ...] = attrs.field(default=(), converter=tuple)

    def __attrs_post_init__(self):
        k = self.times.shape[0]
        if self.positions.shape[0] != k or self.positions.shape[1] not in (2, 3):
            raise ValueError(f"positions: expected shape ({k}, 2) or ({k}, 3), got {self.positions.shape}")
        for name in ("lines", "course", "speed"):
            value = getattr(self, name)
            if value is not None and value.shape != (k,):
                raise ValueError(f"{name}: expected shape ({k},), got {value.shape}")

    def __len__(self) -> int:
        return self.times.shape[0]


@attrs.frozen
class TrackFile:
    """What :func:`read_tracks` returns: ``tracks`` id → :class:`Track` (in order of first appearance), the
    ``origin`` (lat°, lon°, h m) of the tangent plane (None for x/y files), the ``projection``, the ``epoch`` (UTC
    datetime of time 0 for ISO timestamps, None for numeric seconds) and every :class:`Problem` of the file, by
    line (those of the tracks and those of rows that belong to no track)."""

    path: str
    tracks: dict[str, Track]
    origin: tuple[float, float, float] | None
    projection: str | None
    epoch: datetime | None
    problems: tuple[Problem, ...]

    @property
    def reports(self) -> int:
        """The number of reports kept, over all tracks."""
        return sum(len(t) for t in self.tracks.values())


# --- geodesy -------------------------------------------------------------------------------------------------


def ground_velocity(course, speed) -> np.ndarray:
    """(N, 2) the velocity (east, north) of a reported course over ground χ (N,) in degrees clockwise from north and
    speed s (N,): s (sin χ, cos χ); NaN where either is NaN."""
    chi = np.radians(np.asarray(course, dtype=float))
    return np.asarray(speed, dtype=float)[:, None] * np.column_stack([np.sin(chi), np.cos(chi)])


def geodetic_to_ecef(lat, lon, h=0.0) -> np.ndarray:
    """WGS-84 geodetic (degrees, degrees, metres) → ECEF (…, 3) in metres: X = (N + h) cos φ cos λ,
    Y = (N + h) cos φ sin λ, Z = (N (1 − e²) + h) sin φ, N = a / √(1 − e² sin² φ) (NIMA TR8350.2, eq. 4-14)."""
    phi, lam = np.radians(lat), np.radians(lon)
    h = np.asarray(h, dtype=np.float64)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(phi) ** 2)
    return np.stack(
        [(n + h) * np.cos(phi) * np.cos(lam), (n + h) * np.cos(phi) * np.sin(lam), (n * (1.0 - WGS84_E2) + h) * np.sin(phi)], axis=-1
    )


def project(lat, lon, h=None, *, origin: Sequence[float], projection: str = "enu") -> np.ndarray:
    """Project WGS-84 latitude/longitude (degrees) and optional height (m) to the local tangent plane at
    ``origin`` = (lat₀, lon₀[, h₀]): (K, 2) east/north, or (K, 3) east/north/up when ``h`` is given.

    ``"enu"`` (the ECEF difference rotated to east-north-up) and ``"equirectangular"``: the formulas of the module
    docstring (Hofmann-Wellenhof et al. 2008, §10.2.2)."""
    check_projection(projection)
    lat0, lon0, h0 = _origin(origin)
    lat = np.asarray(lat, dtype=np.float64)
    lon = np.asarray(lon, dtype=np.float64)
    hh = np.zeros_like(lat) if h is None else np.asarray(h, dtype=np.float64)
    phi0, lam0 = math.radians(lat0), math.radians(lon0)
    if projection == "enu":
        d = geodetic_to_ecef(lat, lon, hh) - geodetic_to_ecef(lat0, lon0, h0)
        sp, cp, sl, cl = math.sin(phi0), math.cos(phi0), math.sin(lam0), math.cos(lam0)
        e = -sl * d[..., 0] + cl * d[..., 1]
        n = -sp * cl * d[..., 0] - sp * sl * d[..., 1] + cp * d[..., 2]
        u = cp * cl * d[..., 0] + cp * sl * d[..., 1] + sp * d[..., 2]
    else:
        prime, meridian = _radii(phi0)
        dlon = (lon - lon0 + 180.0) % 360.0 - 180.0
        e = np.radians(dlon) * (prime + h0) * math.cos(phi0)
        n = np.radians(lat - lat0) * (meridian + h0)
        u = hh - h0
    return np.stack([e, n] if h is None else [e, n, u], axis=-1)


def ecef_to_geodetic(xyz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF (…, 3) in metres → WGS-84 (lat°, lon°, h m), the inverse of :func:`geodetic_to_ecef`.

    λ = atan2(Y, X); with p = √(X² + Y²), φ from the fixed-point iteration
    φ ← atan2(Z, p (1 − e² N/(N + h))), h = p/cos φ − N, N = a/√(1 − e² sin² φ),
    started at φ = atan2(Z, p (1 − e²)) (Hofmann-Wellenhof, Lichtenegger & Wasle, *GNSS*, 2008, §10.2.1).
    Six iterations reach 10⁻¹¹ rad for heights below 100 km (checked against pymap3d).
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.shape[-1:] != (3,):
        raise ValueError(f"xyz: expected ECEF coordinates of shape (..., 3), got {xyz.shape}")
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    lam = np.arctan2(y, x)
    p = np.hypot(x, y)
    phi = np.arctan2(z, p * (1.0 - WGS84_E2))
    for _ in range(6):
        n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(phi) ** 2)
        h = p / np.cos(phi) - n
        phi = np.arctan2(z, p * (1.0 - WGS84_E2 * n / (n + h)))
    return np.degrees(phi), np.degrees(lam), h


def unproject(positions, *, origin: Sequence[float], projection: str = "enu") -> np.ndarray:
    """Tangent-plane positions back to WGS-84: (K, 2) east/north → (K, 2) (lat°, lon°), or (K, 3)
    east/north/up → (K, 3) (lat°, lon°, h m); the inverse of :func:`project`.

    ``"enu"`` with up given: ECEF = ECEF(origin) + Rᵀ (e, n, u) (R the rotation of :func:`project`), then
    :func:`ecef_to_geodetic`.  Without up (:func:`project` dropped it), the point is taken on the height of the
    origin: u is found by the Newton step u ← u − (h(e, n, u) − h₀), h changing at the rate ≈ 1 per metre of u,
    repeated three times (|h − h₀| < 1 µm within 100 km), so ``unproject(project(lat, lon))`` returns lat, lon
    for points at the origin's height.  ``"equirectangular"``: φ = φ₀ + n/M₀, λ = λ₀ + e/((N₀ + h₀) cos φ₀),
    h = h₀ + u (exact inverse of its forward formula).
    """
    check_projection(projection)
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] not in (2, 3):
        raise ValueError(f"positions: expected (K, 2) east/north or (K, 3) east/north/up metres, got shape {positions.shape}")
    lat0, lon0, h0 = _origin(origin)
    e, n = positions[:, 0], positions[:, 1]
    phi0, lam0 = math.radians(lat0), math.radians(lon0)
    if projection == "equirectangular":
        prime, meridian = _radii(phi0)
        lat = lat0 + np.degrees(n / (meridian + h0))
        lon = (lon0 + np.degrees(e / ((prime + h0) * math.cos(phi0))) + 180.0) % 360.0 - 180.0
        return np.stack([lat, lon, h0 + positions[:, 2]] if positions.shape[1] == 3 else [lat, lon], axis=-1)
    sp, cp, sl, cl = math.sin(phi0), math.cos(phi0), math.sin(lam0), math.cos(lam0)
    rotation = np.array([[-sl, cl, 0.0], [-sp * cl, -sp * sl, cp], [cp * cl, cp * sl, sp]])  # ECEF → ENU
    base = geodetic_to_ecef(lat0, lon0, h0)

    def geodetic(up):
        return ecef_to_geodetic(base + np.stack([e, n, up], axis=-1) @ rotation)

    if positions.shape[1] == 3:
        return np.stack(geodetic(positions[:, 2]), axis=-1)
    up = np.zeros_like(e)
    for _ in range(3):
        up = up - (geodetic(up)[2] - h0)
    return np.stack(geodetic(up)[:2], axis=-1)


def check_projection(projection) -> None:
    if projection not in PROJECTIONS:
        raise ValueError(f"projection: {projection!r}; expected one of {PROJECTIONS}")


def _radii(phi0: float) -> tuple[float, float]:
    """The prime-vertical and meridian radii of curvature at latitude φ₀ (rad): N₀ = a / √w, M₀ = a (1 − e²) / w^{3/2},
    w = 1 − e² sin² φ₀ (the ``equirectangular`` projection of the module docstring)."""
    w = 1.0 - WGS84_E2 * math.sin(phi0) ** 2
    return WGS84_A / math.sqrt(w), WGS84_A * (1.0 - WGS84_E2) / w**1.5


def _origin(origin) -> tuple[float, float, float]:
    try:
        values = [float(v) for v in origin]
    except (TypeError, ValueError):
        raise ValueError(f"origin: expected (lat°, lon°) or (lat°, lon°, h m), got {origin!r}") from None
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise ValueError(f"origin: expected 2 or 3 finite numbers (lat°, lon°[, h m]), got {origin!r}")
    if not (-90.0 <= values[0] <= 90.0 and -180.0 <= values[1] <= 180.0):
        raise ValueError(f"origin: latitude {values[0]} / longitude {values[1]} outside [−90, 90] / [−180, 180]")
    return values[0], values[1], values[2] if len(values) == 3 else 0.0


def geodesic_inverse(lat1, lon1, lat2, lon2, *, tol: float = 1e-12, max_iter: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """(distance m, initial azimuth ° clockwise from north) of the WGS-84 geodesic between two points (degrees).

    Vincenty's inverse formula (T. Vincenty, "Direct and inverse solutions of geodesics on the ellipsoid with
    application of nested equations", Survey Review 23(176):88–93, 1975), iterated on λ to ``tol`` rad —
    accurate to a fraction of a millimetre.  Vectorized; nearly antipodal points (where the iteration does not
    converge) raise a ValueError.
    """
    a, b, f = WGS84_A, WGS84_B, WGS84_F
    lat1, lon1, lat2, lon2 = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (lat1, lon1, lat2, lon2)))
    big_l = np.radians(lon2 - lon1)
    u1 = np.arctan((1.0 - f) * np.tan(np.radians(lat1)))
    u2 = np.arctan((1.0 - f) * np.tan(np.radians(lat2)))
    su1, cu1, su2, cu2 = np.sin(u1), np.cos(u1), np.sin(u2), np.cos(u2)
    lam = big_l.copy()
    for _ in range(max_iter):
        sl, cl = np.sin(lam), np.cos(lam)
        sin_s = np.hypot(cu2 * sl, cu1 * su2 - su1 * cu2 * cl)
        cos_s = su1 * su2 + cu1 * cu2 * cl
        sigma = np.arctan2(sin_s, cos_s)
        with np.errstate(invalid="ignore", divide="ignore"):
            sin_a = np.where(sin_s > 0, cu1 * cu2 * sl / sin_s, 0.0)
            cos2a = 1.0 - sin_a**2
            cos2sm = np.where(cos2a > 0, cos_s - 2.0 * su1 * su2 / cos2a, 0.0)
        c = f / 16.0 * cos2a * (4.0 + f * (4.0 - 3.0 * cos2a))
        new = big_l + (1.0 - c) * f * sin_a * (sigma + c * sin_s * (cos2sm + c * cos_s * (-1.0 + 2.0 * cos2sm**2)))
        done = np.abs(new - lam) <= tol
        lam = new
        if done.all():
            break
    else:
        raise ValueError("geodesic_inverse: Vincenty's iteration did not converge (nearly antipodal points)")
    sl, cl = np.sin(lam), np.cos(lam)
    u_sq = cos2a * (a * a - b * b) / (b * b)
    big_a = 1.0 + u_sq / 16384.0 * (4096.0 + u_sq * (-768.0 + u_sq * (320.0 - 175.0 * u_sq)))
    big_b = u_sq / 1024.0 * (256.0 + u_sq * (-128.0 + u_sq * (74.0 - 47.0 * u_sq)))
    bracket = cos_s * (-1.0 + 2.0 * cos2sm**2) - big_b / 6.0 * cos2sm * (-3.0 + 4.0 * sin_s**2) * (-3.0 + 4.0 * cos2sm**2)
    d_sigma = big_b * sin_s * (cos2sm + big_b / 4.0 * bracket)
    distance = b * big_a * (sigma - d_sigma)
    azimuth = np.degrees(np.arctan2(cu2 * sl, cu1 * su2 - su1 * cu2 * cl)) % 360.0
    return distance, azimuth


def projection_error(origin: Sequence[float], distance: float = 100e3, *, projection: str = "enu", directions: int = 16) -> dict:
    """Measure a projection against the WGS-84 geodesic at ``distance`` metres from ``origin`` in ``directions``
    compass directions.

    Points are placed roughly (spherical formulas) at that range; for each, the reference position is the
    azimuthal-equidistant one, s (sin α, cos α) with s, α from :func:`geodesic_inverse` (exact distance and bearing
    from the origin).  Local scale: a second point 100 m further east and one 100 m further north (approximately)
    are projected and their planar distance compared with the geodesic one.  Returns the maxima over directions:
    ``position`` (m, |projected − reference|), ``distance`` (m, planar range − geodesic range, the signed value of
    largest magnitude), ``bearing`` (degrees), ``scale`` (relative, |planar/geodesic − 1| for 100 m steps) and the
    ``range`` actually tested (m).
    """
    lat0, lon0, _ = _origin(origin)
    bearings = np.radians(np.arange(directions) * 360.0 / directions)
    delta = check_positive(distance, "distance") / 6_371_000.0
    phi0, lam0 = math.radians(lat0), math.radians(lon0)
    phi = np.arcsin(math.sin(phi0) * np.cos(delta) + math.cos(phi0) * np.sin(delta) * np.cos(bearings))
    lam = lam0 + np.arctan2(np.sin(bearings) * np.sin(delta) * math.cos(phi0), np.cos(delta) - math.sin(phi0) * np.sin(phi))
    lat, lon = np.degrees(phi), np.degrees(lam)
    s, alpha = geodesic_inverse(lat0, lon0, lat, lon)
    reference = np.stack([s * np.sin(np.radians(alpha)), s * np.cos(np.radians(alpha))], axis=-1)
    p = project(lat, lon, origin=(lat0, lon0), projection=projection)
    planar_range = np.hypot(p[:, 0], p[:, 1])
    bearing = np.degrees(np.arctan2(p[:, 0], p[:, 1])) % 360.0
    scale = []
    for dlat, dlon in ((0.0, 100.0 / (111_320.0 * np.cos(phi))), (100.0 / 111_000.0, 0.0)):
        lat2, lon2 = lat + dlat, lon + dlon
        q = project(lat2, lon2, origin=(lat0, lon0), projection=projection)
        geodesic, _ = geodesic_inverse(lat, lon, lat2, lon2)
        scale.append(np.abs(np.hypot(*(q - p).T) / geodesic - 1.0))
    range_error = planar_range - s
    worst = int(np.argmax(np.abs(range_error)))
    return {
        "projection": projection,
        "range": float(np.mean(s)),
        "position": float(np.max(np.hypot(*(p - reference).T))),
        "distance": float(range_error[worst]),
        "bearing": float(np.max(np.abs((bearing - alpha + 180.0) % 360.0 - 180.0))),
        "scale": float(np.max(scale)),
    }


# --- reading ---------------------------------------------------------------------------------------------------

#: the formats :func:`read_tracks` reads (``format=``)
FORMATS = ("csv", "gpx", "nmea")
#: file name endings (lower case) → format, when ``format`` is not given
EXTENSIONS = {".csv": "csv", ".csv.gz": "csv", ".gpx": "gpx", ".nmea": "nmea", ".ais": "nmea"}
#: the module reading each format that is not CSV (its ``read_rows(path)`` → :class:`Rows`, ``SETTINGS`` the
#: column keywords it fixes, ``COLUMNS`` what its rows hold)
FILE_READERS = {"gpx": "hybridtrack.io.gpx_files", "nmea": "hybridtrack.io.nmea_files"}
#: the keywords of :func:`read_tracks` that name or read columns: for CSV files and DataFrames only
COLUMN_KEYWORDS = (
    "time",
    "x",
    "y",
    "lat",
    "lon",
    "alt",
    "id",
    "course",
    "speed",
    "speed_unit",
    "course_not_available",
    "speed_not_available",
    "time_unit",
    "time_format",
)
#: the name of a DataFrame source in messages and :attr:`TrackFile.path`
DATA_FRAME = "<DataFrame>"


class MissingExtraError(ImportError, ValueError):
    """An optional package a reader needs is not installed; the message names it and the ``pip install
    hybridtrack[extra]`` that brings it (a ValueError too, so that the CLI reports it as a user error)."""


def require(module: str, extra: str, what: str):
    """The module ``module``, imported on first use; without it a :class:`MissingExtraError` saying that ``what``
    needs it and ``pip install hybridtrack[extra]``."""
    try:
        return importlib.import_module(module)
    except ImportError as error:
        message = f"{what} needs the {module} package, which is not installed: pip install hybridtrack[{extra}] ({error})"
        raise MissingExtraError(message, name=module) from None


@attrs.frozen
class Rows:
    """The position reports of one source as :func:`read_tracks` checks them, whatever the format: text cells
    under a ``header`` (the CSV's own; for GPX and NMEA the columns their reader produces), ``body`` (line,
    cells) with the ``line`` of the source each record starts on, the ``problems`` the format's reader found
    itself (records it could not turn into a row: ``bad_time``, ``bad_checksum``, ``not_position``, …), ``name``
    (the file, or ``"<DataFrame>"``, as messages show it), ``records`` (how many records the source held, in
    ``unit``: the count of the no-report-left error) and ``hint`` (what a valid source looks like)."""

    name: str
    header_line: int
    header: list[str]
    body: list[tuple[int, list[str]]]
    problems: tuple[Problem, ...] = attrs.field(default=(), converter=tuple)
    records: int | None = None
    unit: str = "data rows"
    hint: str = _HINT


def timestamp(cell: str) -> datetime | None:
    """An ISO-8601 time stamp (``2016-01-12 13:02:11.218``, ``…T13:02:11Z``, ``…+01:00``) as a UTC datetime (naive
    ones read as UTC), None when ``cell`` is not one."""
    try:
        stamp = datetime.fromisoformat(cell)
    except ValueError:
        return None
    return stamp.replace(tzinfo=UTC) if stamp.tzinfo is None else stamp.astimezone(UTC)


def is_data_frame(source) -> bool:
    """Whether ``source`` is a pandas DataFrame (without importing pandas: a DataFrame exists only once it is)."""
    pandas = sys.modules.get("pandas")
    return pandas is not None and isinstance(source, pandas.DataFrame)


def source_format(source, format: str | None = None) -> str:
    """The format :func:`read_tracks` reads ``source`` (a path or a DataFrame) in: ``format`` when given (one of
    :data:`FORMATS`; a DataFrame only as ``"csv"``, its columns), else from the file name's ending
    (:data:`EXTENSIONS`); a ValueError naming the ending and the formats for any other."""
    if format is not None and format not in FORMATS:
        raise ValueError(f"format: {format!r}; expected one of {FORMATS} (or none: from the file name's extension)")
    if is_data_frame(source):
        if format not in (None, "csv"):
            raise ValueError(f"format: {format!r} is a file format; a DataFrame is read by its columns, as a CSV (give no format)")
        return "csv"
    if format is not None:
        return format
    name = Path(source).name.lower()
    ending = next((end for end in sorted(EXTENSIONS, key=len, reverse=True) if name.endswith(end)), None)
    if ending is None:
        suffix = "".join(Path(name).suffixes[-2:]) or "(none)"
        endings = ", ".join(EXTENSIONS)
        raise ValueError(
            f"{source}: unknown extension {suffix!r}; expected one of {endings} — or give format, one of {FORMATS} ([reader] format = 'csv')"
        )
    return EXTENSIONS[ending]


def read_tracks(
    source,
    *,
    format: str | None = None,
    time: str = "time",
    x: str = "x",
    y: str = "y",
    lat: str | None = None,
    lon: str | None = None,
    alt: str | None = None,
    id: str | None = None,
    course: str | None = None,
    speed: str | None = None,
    speed_unit: str = "m/s",
    course_not_available: float | None = None,
    speed_not_available: float | None = None,
    origin: str | Sequence[float] = "first",
    projection: str = "enu",
    max_speed: float | None = None,
    object_class: str | None = None,
    jump_tolerance: float = 0.0,
    time_unit: str | None = None,
    time_format: str | None = None,
    warn: bool = True,
) -> TrackFile:
    """Read time-stamped positions — a CSV (or ``.csv.gz``), GPX or raw AIS NMEA file, or a pandas DataFrame —
    into one :class:`Track` per object.

    ``source``: a file name (str or os.PathLike) or a :class:`pandas.DataFrame` (its columns read as a CSV's:
    below).  ``format``: ``"csv"``, ``"gpx"`` (:mod:`.gpx_files`) or ``"nmea"`` (:mod:`.nmea_files`); by default
    from the file name: ``.csv``, ``.csv.gz`` → csv, ``.gpx`` → gpx, ``.nmea``, ``.ais`` → nmea (any other
    ending without ``format`` is a ValueError).  Whatever the format, the records become rows checked, grouped,
    sorted, de-duplicated, speed-checked and projected the same way, with the same :class:`Problem` reports
    (module docstring), and ISO times become seconds after the UTC :attr:`TrackFile.epoch`.

    ``time``, ``x``, ``y`` / ``lat``, ``lon``, ``alt``, ``id``, ``course``, ``speed`` name the columns of a CSV or a
    DataFrame (GPX and NMEA files have none of their own: any of these keywords — or ``speed_unit``, the
    ``*_not_available`` codes, ``time_unit``, ``time_format`` — other than its default is a ValueError; those
    readers set them); giving ``lat`` and ``lon`` selects geographic positions, projected with ``projection`` to
    the tangent plane at ``origin``: ``"first"`` — the first valid fix of the file, ``"mean"`` — the mean
    latitude/longitude/height of the fixes kept after the speed check, or an explicit (lat°, lon°[, h m]).
    ``max_speed`` (m/s, None = no check) and ``jump_tolerance`` (m, the allowance for position noise and
    time-stamp jitter) define which fix is reachable (module docstring, which also says what is refused, dropped,
    flagged or set to NaN); ``object_class`` (``"ship"``, ``"ground"``, ``"aircraft"``) sets ``max_speed`` to that
    class's physical limit (:data:`SPEED_LIMITS`) when ``max_speed`` is not given.  Numeric times are in
    ``time_unit`` (``"s"`` or ``"ms"``; by default seconds, and numbers ≥ 10¹¹ — epoch milliseconds, read as
    seconds after the year 5000 — are refused until ``time_unit`` says which); ``time_format`` (a
    :func:`datetime.strptime` format such as ``"%d/%m/%Y %H:%M:%S"``, UTC unless it holds a zone) reads time stamps
    of any other form.  A file of which no report is left (every row dropped) is a ValueError naming the column,
    what it holds and what is expected (with a hint when every latitude is out of range but the longitudes would
    fit: swapped columns).  ``course_not_available``/``speed_not_available`` are the codes meaning "no value"
    (``speed_not_available`` in ``speed_unit``).  The speed check of geographic files runs in the plane of the
    file's first valid fix (or of the explicit origin) before a ``"mean"`` origin is computed; ``"mean"`` is the
    arithmetic mean of the degrees, so it is wrong for tracks that cross the ±180° meridian (give the origin there).

    A DataFrame's cells may be strings (read as a CSV's), numbers, or pandas Timestamps / ``datetime64`` values
    (times: naive ones are UTC, like ISO strings without a zone); NaN, None and NaT are empty cells.  A
    :class:`Problem`'s ``line`` there is the row's position + 2, the line it would have in a CSV written with a
    header (``frame.to_csv(index=False)``), and messages name the source ``<DataFrame>``.  A format whose package is
    missing (gpxpy, pyais) is a :class:`MissingExtraError` naming the ``pip install hybridtrack[…]`` extra.
    """
    frame = is_data_frame(source)
    if not frame and not isinstance(source, (str, os.PathLike)):
        raise TypeError(
            f"source: expected a file path (str or os.PathLike) or a pandas DataFrame, got {type(source).__name__} ({reprlib.repr(source)})"
        )
    if not frame:
        checked_path(source, "a position file (" + ", ".join(EXTENSIONS) + ")")
    kind = source_format(source, format)
    columns = dict(time=time, x=x, y=y, lat=lat, lon=lon, alt=alt, id=id, course=course, speed=speed, speed_unit=speed_unit)
    columns.update(course_not_available=course_not_available, speed_not_available=speed_not_available)
    columns.update(time_unit=time_unit, time_format=time_format)
    if kind in FILE_READERS:
        module = importlib.import_module(FILE_READERS[kind])
        defaults = inspect.signature(read_tracks).parameters
        for key in COLUMN_KEYWORDS:
            if columns[key] != defaults[key].default and columns[key] != module.SETTINGS.get(key):
                raise ValueError(
                    f"{key}={columns[key]!r}: format {kind!r} has no columns ({key} applies to CSV files and DataFrames);"
                    f" leave it out: {module.COLUMNS}"
                )
        columns.update(module.SETTINGS)
    if (columns["lat"] is None) != (columns["lon"] is None):
        raise ValueError(f"lat/lon: give both latitude and longitude column names, got lat={lat!r}, lon={lon!r}")
    if speed_unit not in SPEED_UNITS:
        raise ValueError(f"speed_unit: {speed_unit!r}; expected one of {sorted(SPEED_UNITS)}")
    check_projection(projection)
    if object_class is not None and object_class not in SPEED_LIMITS:
        raise ValueError(f"object_class: {object_class!r}; expected one of {sorted(SPEED_LIMITS)}")
    check_time_options(time_unit, time_format)
    if max_speed is None and object_class is not None:
        max_speed = SPEED_LIMITS[object_class]
    if max_speed is not None:
        max_speed = check_positive(max_speed, "max_speed (m/s)")
    if not (isinstance(jump_tolerance, (int, float)) and math.isfinite(jump_tolerance) and jump_tolerance >= 0):
        raise ValueError(f"jump_tolerance: expected a finite number of metres ≥ 0, got {jump_tolerance!r}")
    origin = check_origin_option(origin)

    if frame:
        wanted = [columns[key] for key in ("time", "x", "y", "lat", "lon", "alt", "id", "course", "speed")]
        rows = frame_rows(source, wanted)
    elif kind == "csv":
        rows = Rows(str(source), *read_csv(source, "a CSV file of position reports", _HINT))
    else:
        rows = module.read_rows(source)
        if columns["alt"] is not None and columns["alt"] not in rows.header:
            columns["alt"] = None  # a GPX file's elevation only when every point has one
    data = _read_rows(rows, **columns, origin=origin, projection=projection, max_speed=max_speed, jump_tolerance=jump_tolerance)
    if warn and data.problems:
        counts = Counter(f"{p.kind} ({p.action})" for p in data.problems)
        summary = ", ".join(f"{n} {kind}" for kind, n in counts.most_common())
        warnings.warn(f"{data.path}: {len(data.problems)} problems: {summary}; see TrackFile.problems", stacklevel=2)
    return data


def check_time_options(time_unit, time_format) -> None:
    """A ValueError unless ``time_unit`` is None or one of :data:`TIME_UNITS` and ``time_format`` None or a strptime
    format, and not both are given (:func:`read_tracks`)."""
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise ValueError(f"time_unit: {time_unit!r}; expected one of {sorted(TIME_UNITS)} (seconds, milliseconds)")
    if time_format is not None and (not isinstance(time_format, str) or "%" not in time_format):
        raise ValueError(f"time_format: expected a strptime format such as '%d/%m/%Y %H:%M:%S', got {time_format!r}")
    if time_format is not None and time_unit is not None:
        raise ValueError(f"time_format {time_format!r} and time_unit {time_unit!r}: give one (time_unit is for numeric times)")


def check_origin_option(origin):
    """The ``origin`` keyword of :func:`read_tracks`: ``"first"``, ``"mean"`` or an explicit (lat°, lon°, h m) (checked)."""
    if isinstance(origin, str) and origin not in ("first", "mean"):
        raise ValueError(f"origin: {origin!r}; expected 'first', 'mean' or (lat°, lon°[, h m])")
    return origin if isinstance(origin, str) else _origin(origin)


def frame_rows(frame, names: Sequence[str | None]) -> Rows:
    """The :class:`Rows` of a pandas DataFrame: every column in the header (its name as a str), the cells of the
    columns ``names`` (None entries skipped) as text — strings stripped, integers and floats as Python writes them,
    Timestamps / ``datetime``/``datetime64`` in ISO 8601, NaN/None/NaT/NA empty — and the others empty; row i is
    "line" i + 2 (as in a CSV written with its header)."""
    header = [str(c) for c in frame.columns]
    used = {i for i, c in enumerate(header) if c in set(n for n in names if n is not None)}
    cells = [[_text(v) for v in frame.iloc[:, i].to_numpy(dtype=object)] if i in used else None for i in range(len(header))]
    blank = [""] * len(frame)
    filled = [blank if column is None else column for column in cells]
    body = [(k + 2, [column[k] for column in filled]) for k in range(len(frame))]
    return Rows(DATA_FRAME, 1, header, body, hint="expected a DataFrame with one row per position report")


def _text(value) -> str:
    """One DataFrame cell as a CSV's text (:func:`frame_rows`)."""
    if value is None or type(value).__name__ in ("NaTType", "NAType"):
        return ""
    if isinstance(value, str):
        return value.strip()
    if isinstance(value, datetime):  # pandas Timestamps too
        return value.isoformat()
    if isinstance(value, np.datetime64):
        return "" if np.isnat(value) else str(np.datetime_as_string(value))
    if isinstance(value, (bool, np.bool_)):
        return str(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return "" if math.isnan(value) else repr(float(value))
    return str(value).strip()


@attrs.define
class ParsedRows:
    """The rows of a :class:`Rows` table that passed the row checks of :func:`parse_rows`, before any grouping:
    ``rows`` in file order, each a namespace with ``line``, ``id`` (the id cell, ``""`` without an id column),
    ``time`` (seconds: after ``epoch`` for time stamps), ``values`` (the position cells as numbers, in
    ``position_columns`` order), ``course``, ``speed`` (None without the column, ``"n/a"`` for the file's
    not-available code, NaN for a bad cell) and ``cells`` (the row's text cells); ``problems`` the faults found so
    far (a list: later stages add theirs); ``columns`` each configured column's index in ``header``."""

    table: Rows
    columns: dict[str, int]
    position_columns: list[str]
    geographic: bool
    altitude: bool
    rows: list[SimpleNamespace]
    problems: list[Problem]
    epoch: datetime | None
    lat: str | None = None
    lon: str | None = None

    def report(self, line, column, kind, action, message, track=None) -> None:
        """Add a :class:`Problem` at ``line`` of the file (the message prefixed with ``file:line:``)."""
        self.problems.append(Problem(line, column, kind, action, f"{self.table.name}:{line}: {message}", track))

    def fix(self, r) -> tuple[float, float, float]:
        """(lat°, lon°, h m) of a row of a geographic file."""
        return r.values[0], r.values[1], r.values[2] if self.altitude else 0.0

    def positions(self, rows, origin, projection: str) -> np.ndarray:
        """The positions (len(rows), 2 or 3) of ``rows`` in metres: the cells of an x/y file, or the latitude/longitude
        projected with ``projection`` to the tangent plane at ``origin`` (:func:`project`)."""
        values = np.array([r.values for r in rows], dtype=np.float64).reshape(len(rows), len(self.position_columns))
        if not self.geographic:
            return values
        return project(values[:, 0], values[:, 1], values[:, 2] if self.altitude else None, origin=origin, projection=projection)

    def origin_of(self, kept, origin):
        """The tangent-plane origin of a geographic file from the rows ``kept``: an explicit (lat°, lon°, h m) as it is;
        ``"first"`` the fix of the earliest line kept, ``"mean"`` the mean latitude/longitude/height of the fixes kept
        (None when none is kept)."""
        if not isinstance(origin, str):
            return origin
        if not kept:
            return None
        if origin == "first":
            return self.fix(min(kept, key=lambda r: r.line))
        v = np.array([r.values for r in kept])
        return float(v[:, 0].mean()), float(v[:, 1].mean()), float(v[:, 2].mean()) if self.altitude else 0.0

    def by_place(self, problem) -> tuple[int, int]:
        """The sort key of a problem in file order: line, then column."""
        header = self.table.header
        return problem.line, header.index(problem.column) if problem.column in header else -1

    def nothing_left(self) -> str:
        """The message of a source of which every row was dropped (:func:`read_tracks`)."""
        table = self.table
        records = len(table.body) if table.records is None else table.records
        problems = sorted(self.problems, key=self.by_place)
        return _nothing_left(table.name, f"{records} {table.unit}", problems, table.header, self.columns, table.body, self.lat, self.lon)


def parse_rows(
    table: Rows,
    *,
    time,
    x,
    y,
    lat,
    lon,
    alt,
    id,
    course,
    speed,
    speed_unit,
    course_not_available,
    speed_not_available,
    time_unit,
    time_format,
    extra: Sequence[str] = (),
) -> ParsedRows:
    """The row checks of :func:`read_tracks` without grouping by object, de-duplicating, the speed check or the
    projection: each row of ``table`` whose cell count, id, time and position are valid (the module docstring's
    rules; course and speed cells that are not are set to NaN), with the problems of the others, the times in
    seconds (after the earliest valid time stamp, :attr:`ParsedRows.epoch`, for time stamps).  ``extra``: more
    columns that must be in the header (their cells are in each row's ``cells``).  The keywords are those of
    :func:`read_tracks`, checked."""
    path, header_line, header, body = table.name, table.header_line, table.header, table.body
    geographic = lat is not None
    position_columns = [lat, lon] if geographic else [x, y]
    if alt is not None:
        position_columns.append(alt)
    columns = {}
    for name in [name for name in (time, *position_columns, id, course, speed, *extra) if name is not None]:
        if name not in header:
            raise ValueError(f"{path}:{header_line}: no column {name!r} in the header; the columns are {header}")
        if header.count(name) > 1:
            raise ValueError(f"{path}:{header_line}: column {name!r} appears {header.count(name)} times in the header")
        columns[name] = header.index(name)
    if not body and not table.problems:
        raise ValueError(f"{path}: header only, no data rows; {table.hint}")

    parsed = ParsedRows(table, columns, position_columns, geographic, alt is not None, [], list(table.problems), None, lat, lon)
    report = parsed.report

    # time stamps (ISO 8601 or time_format) or numbers: decided by the first time cell that is either
    cells = (row[columns[time]] for _, row in body if len(row) > columns[time])
    first_time = next((c for c in cells if finite_number(c) is not None or timestamp(c) is not None), "")
    numeric = time_format is None and finite_number(first_time) is not None
    stamped = time_format is not None or (not numeric and timestamp(first_time) is not None)
    if time_format is not None:
        form = f"a time of time_format {time_format!r}"
    elif stamped:
        form = "an ISO-8601 timestamp (as the first time of the file)"
    elif numeric:
        form = f"a finite number of {'milliseconds' if time_unit == 'ms' else 'seconds'}"
    else:
        form = (
            "a number of seconds or an ISO-8601 timestamp (2016-01-12 13:02:11); for another form give [reader] time_format,"
            " a strptime format such as '%d/%m/%Y %H:%M:%S'"
        )

    def parse_time(cell):
        if time_format is not None:
            try:
                stamp = datetime.strptime(cell, time_format)
            except ValueError:
                return None
            return stamp.replace(tzinfo=UTC) if stamp.tzinfo is None else stamp.astimezone(UTC)
        if stamped:
            return timestamp(cell)
        value = finite_number(cell) if numeric else None
        return None if value is None else value * TIME_UNITS[time_unit or "s"]

    rows = parsed.rows  # the rows used, in file order: line, id, time, values (the position cells), course, speed, cells
    for line, row in body:
        if len(row) != len(header):
            report(line, None, "bad_row", "dropped", f"{len(row)} cells, the header has {len(header)}; row dropped")
            continue
        key = row[columns[id]] if id is not None else ""
        if id is not None and not key:
            report(line, id, "missing_id", "dropped", f"column {id!r} is empty; row dropped")
            continue
        cell = row[columns[time]]
        stamp = parse_time(cell)
        if stamp is None:
            report(line, time, "bad_time", "dropped", f"column {time!r} holds {cell!r}, not {form}; row dropped", key)
            continue
        if numeric and time_unit is None and abs(stamp) >= MILLISECONDS_LIKELY:
            raise ValueError(
                f"{path}:{line}: column {time!r} holds {cell}: as seconds, later than the year 5000 — epoch milliseconds?"
                " set [reader] time_unit = 'ms' (or 's' if these are seconds)"
            )
        values = [finite_number(row[columns[name]]) for name in position_columns]
        if None in values:
            name = position_columns[values.index(None)]
            cell = row[columns[name]]
            report(line, name, "not_a_number", "dropped", f"column {name!r} holds {cell!r}, not a finite number; row dropped", key)
            continue
        metres = list(zip(position_columns, values))[2 if geographic else 0 :]
        far = next(((name, value) for name, value in metres if abs(value) > MAX_COORDINATE), None)
        if far is not None:
            message = (
                f"column {far[0]!r} holds {far[1]:g}, farther than {MAX_COORDINATE:g} m: not a position on or near the Earth; row dropped"
            )
            report(line, far[0], "out_of_range", "dropped", message, key)
            continue
        if geographic and not (-90.0 <= values[0] <= 90.0 and -180.0 <= values[1] <= 180.0):
            bad, value, limits = (lat, values[0], "[-90, 90]") if not -90.0 <= values[0] <= 90.0 else (lon, values[1], "[-180, 180]")
            report(line, bad, "out_of_range", "dropped", f"column {bad!r} holds {value}, outside {limits} degrees; row dropped", key)
            continue
        extra_values = []
        for name, low, high, code, factor in (
            (course, 0.0, 360.0, course_not_available, 1.0),
            (speed, 0.0, math.inf, speed_not_available, SPEED_UNITS[speed_unit]),
        ):
            if name is None:
                extra_values.append(None)
                continue
            cell = row[columns[name]]
            value = finite_number(cell)
            if value is not None and code is not None and value == code:
                extra_values.append("n/a")
            elif value is None or not low <= value <= high:
                kind, why = ("not_a_number", "not a finite number") if value is None else ("out_of_range", f"outside [{low}, {high}]")
                report(line, name, kind, "set_nan", f"column {name!r} holds {cell!r}, {why}; set to NaN", key)
                extra_values.append(math.nan)
            else:
                extra_values.append(value * factor)
        rows.append(SimpleNamespace(line=line, id=key, time=stamp, values=values, course=extra_values[0], speed=extra_values[1], cells=row))

    parsed.epoch = min((r.time for r in rows), default=None) if stamped else None
    for r in rows if stamped else ():
        r.time = (r.time - parsed.epoch).total_seconds()
    return parsed


def _read_rows(
    table: Rows,
    *,
    time,
    x,
    y,
    lat,
    lon,
    alt,
    id,
    course,
    speed,
    speed_unit,
    course_not_available,
    speed_not_available,
    origin,
    projection,
    max_speed,
    jump_tolerance,
    time_unit,
    time_format,
) -> TrackFile:
    """The tracks of ``table`` (any format's rows), with the checked keywords of :func:`read_tracks`."""
    columns = dict(time=time, x=x, y=y, lat=lat, lon=lon, alt=alt, id=id, course=course, speed=speed, speed_unit=speed_unit)
    columns.update(course_not_available=course_not_available, speed_not_available=speed_not_available)
    parsed = parse_rows(table, **columns, time_unit=time_unit, time_format=time_format)
    path, geographic, problems, report = table.name, parsed.geographic, parsed.problems, parsed.report
    groups: dict[str, list[SimpleNamespace]] = {}  # id → the rows used
    for r in parsed.rows:
        groups.setdefault(r.id, []).append(r)
    rows = parsed.rows  # rows[0]: the first row used of the file
    epoch = parsed.epoch

    check_origin = origin if not isinstance(origin, str) else (parsed.fix(rows[0]) if rows else None)
    for key, group in groups.items():  # each group becomes the rows kept
        ordered = sorted(group, key=lambda r: r.time)
        late = next((r for r, s in zip(ordered, group) if r is not s), None)
        if late is not None:
            report(late.line, time, "unsorted", "sorted", f"id {key!r}: rows out of time order (the first misplaced one here); sorted", key)
        unique = []
        for _, same_time in itertools.groupby(ordered, key=lambda r: r.time):
            unique.extend(_distinct_times(list(same_time), key, report, time))
        if max_speed is not None and len(unique) > 1:
            unique = _speed_check(unique, parsed.positions(unique, check_origin, projection), max_speed, jump_tolerance, key, report, time)
        groups[key] = unique

    kept = [r for g in groups.values() for r in g]
    if geographic:
        origin = parsed.origin_of(kept, origin)

    tracks = {}
    for key, group in groups.items():
        for name, attr, code in ((course, "course", course_not_available), (speed, "speed", speed_not_available)):
            lines = [r.line for r in group if getattr(r, attr) == "n/a"]  # none without the column (all None)
            if lines:
                shown = ", ".join(map(str, lines[:5])) + (", …" if len(lines) > 5 else "")
                message = f"id {key!r}: column {name!r} holds {code} (not available) in {len(lines)} rows (lines {shown}); set to NaN"
                report(lines[0], name, "not_available", "set_nan", message, key)
        tracks[key] = Track(
            id=key,
            times=np.array([r.time for r in group], dtype=np.float64),
            positions=parsed.positions(group, origin, projection),
            lines=[r.line for r in group],
            course=None if course is None else [math.nan if r.course == "n/a" else r.course for r in group],
            speed=None if speed is None else [math.nan if r.speed == "n/a" else r.speed for r in group],
            problems=sorted((p for p in problems if p.id == key), key=parsed.by_place),
        )
    problems.sort(key=parsed.by_place)
    if not any(tracks.values()):
        raise ValueError(parsed.nothing_left())
    return TrackFile(str(path), tracks, origin if geographic else None, projection if geographic else None, epoch, tuple(problems))


def _distinct_times(rows, key, report, column) -> list:
    """The rows of one object at one time stamp (file order) → the row kept: the first when every row has its
    position (a repeat: ``duplicate_time``, the others dropped), none when the positions differ (conflicting reports,
    ``conflicting_duplicate``: each row dropped, not one chosen by its order in the file)."""
    first = rows[0]
    if len(rows) == 1:
        return rows
    if all(r.values == first.values for r in rows):
        for r in rows[1:]:
            same = r.course == first.course and r.speed == first.speed
            what = "identical to it" if same else "same position, other course or speed"
            report(
                r.line,
                column,
                "duplicate_time",
                "dropped",
                f"id {key!r}: time {r.time!r} repeats line {first.line} ({what}); row dropped",
                key,
            )
        return [first]
    lines = ", ".join(str(r.line) for r in rows)
    for r in rows:
        message = f"id {key!r}: time {r.time!r} has reports of different positions on lines {lines}; conflicting reports, row dropped"
        report(r.line, column, "conflicting_duplicate", "dropped", message, key)
    return []


def problem_kinds(problems) -> list[tuple[str, int, Problem]]:
    """(kind, count, the first problem of that kind) per kind of ``problems`` (a sequence), the most common first."""
    first: dict[str, Problem] = {}
    for problem in problems:
        first.setdefault(problem.kind, problem)
    return [(kind, n, first[kind]) for kind, n in Counter(p.kind for p in problems).most_common()]


def _nothing_left(path, rows, problems, header, columns, body, lat, lon) -> str:
    """The message of a file of which every row was dropped: the counts by kind, the first problem of the most
    common kind and, when every latitude is out of range but the longitudes would fit as latitudes, the hint."""
    kinds = problem_kinds(problems)
    summary = ", ".join(f"{n} {kind}" for kind, n, _ in kinds)
    first = kinds[0][2].message if kinds else ""
    hint = ""
    if lat is not None and any(kind == "out_of_range" for kind, _, _ in kinds):
        pairs = [(finite_number(row[columns[lat]]), finite_number(row[columns[lon]])) for _, row in body if len(row) == len(header)]
        pairs = [(a, b) for a, b in pairs if a is not None and b is not None]
        if pairs and all(abs(a) > 90.0 and abs(b) <= 90.0 for a, b in pairs):
            hint = f"; every {lat!r} is outside [-90, 90] but every {lon!r} inside: latitude and longitude swapped? (swap lat and lon in [reader])"
    return f"{path}: no report left of {rows} ({summary}); the first: {first}{hint}"


def _speed_check(group, positions, max_speed, tolerance, key, report, column):
    """Drop outlier bursts and first-fix outliers faster than ``max_speed`` (reachable: module docstring); flag (and keep) lasting jumps."""
    times = np.array([r.time for r in group])

    def gap(i, j):
        return float(np.linalg.norm(positions[j] - positions[i]))

    def ok(i, j):
        return gap(i, j) <= max_speed * (times[j] - times[i]) + tolerance

    kept = [0]
    i = 1
    while i < len(group):
        k = kept[-1]
        if not ok(k, i):
            v = gap(k, i) / (times[i] - times[k])
            allowance = f" (+ {tolerance:g} m)" if tolerance else ""
            back = next((m for m in range(i + 1, min(i + 1 + MAX_OUTLIER_BURST, len(group))) if ok(k, m)), None)
            where = f"id {key!r}: reaching this fix from line {group[k].line} ({gap(k, i):.1f} m in {times[i] - times[k]:.3g} s) takes {v:.1f} m/s > max_speed {max_speed:g} m/s{allowance}"
            if back is not None:
                burst = f"id {key!r}: part of the same burst"
                for m in range(i, back):
                    report(group[m].line, column, "speed_jump", "dropped", f"{where if m == i else burst}; row dropped", key)
                i = back
                continue
            if len(kept) == 1 and i + 1 < len(group) and ok(i, i + 1):
                report(group[k].line, column, "speed_jump", "dropped",
                       f"id {key!r}: the next fixes (lines {group[i].line}, {group[i + 1].line}) agree with each other but leaving this first fix takes {v:.1f} m/s > max_speed {max_speed:g} m/s{allowance}; row dropped", key)  # fmt: skip
                kept = []  # the first fix dropped: the track starts here
            else:
                report(group[i].line, column, "speed_jump", "flagged", f"{where}, and the track continues from here; kept", key)
        kept.append(i)
        i += 1
    return [group[i] for i in kept]
