"""Mode labels for real tracks: straight / left turn / right turn / stop segments from course and speed over ground.

The labels are a reference for maneuver detectors run on real data (AIS, GPS),
where no simulated truth exists.  From the reported course over ground c_k
(degrees, a compass bearing: clockwise from north) and speed over ground v_k
(m/s) at times t_k:

1. **Turn rate.**  The course is unwrapped, u_k = c_0 + Σ_{i≤k} wrap(c_i − c_{i−1})
   with wrap(·) ∈ [−180°, 180°), and the smoothed turn rate at t_k is minus the
   least-squares slope of u over the reports with |t_i − t_k| ≤ W/2 (the window
   ``window`` W in seconds; irregular sampling is handled by the regression):
   ω_k = −(π/180) Σ (t_i − t̄)(u_i − ū) / Σ (t_i − t̄)².  The minus sign turns
   the clockwise compass course into the counter-clockwise angle of the
   east-north frame, so **ω > 0 is a left (counter-clockwise) turn seen from
   above** and a decreasing course is a left turn.  Reports whose course is
   NaN (not available) are left out; ω_k is NaN with fewer than two reports in
   the window.
2. **Speed**, smoothed the same way (the mean over the window).
3. **States with hysteresis** (one pass in time): a moving report enters
   ``stop`` when v̄_k < v_stop and leaves it only when v̄_k ≥ v_go (v_go ≥ v_stop);
   a moving report enters ``left_turn`` when ω_k > ω_on (``right_turn`` when
   ω_k < −ω_on) and stays in the turn until |ω_k| < ω_off (ω_off ≤ ω_on), or
   until ω_k crosses −ω_on (+ω_on), which switches to the opposite turn.  A NaN
   ω or speed keeps the previous state.
4. **Minimum length.**  A segment spans [t of its first report, t of the next
   segment's first report] (the last one ends at the last report).  While a
   segment is shorter than ``min_duration`` seconds, the shortest is merged
   into its longer neighbour and equal neighbours are joined.

Each segment records its ``speed`` (the median reported speed, m/s), its
``turn_rate`` (rad/s, counter-clockwise positive: minus the least-squares slope
of the unwrapped course over the segment's *interior*, the reports more than
W/2 from both ends — smoothing over W blurs a turn's edges by up to W/2 and a
turn not much longer than W never reaches its full smoothed rate, so neither
the smoothed ω nor the whole segment's slope is used; a segment shorter than
W + 2 reports uses the median of its unsmoothed step rates
−wrap(c_k − c_{k−1})/Δt_k instead) and for turns the ``radius`` v / |ω| in
metres (None for straight and stop segments) — a coordinated-turn
radius, r = v/ω (Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to
Tracking and Navigation*, Wiley 2001, §11.7).  Thresholds in the spirit of
change-point labelling of AIS tracks by rate of turn (the seeds' maneuver
models: a turn is a constant-rate segment).
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from hybridtrack.apps.minimum_duration import joined_runs, merged_runs
from hybridtrack.core.validation import check_positive

#: default parameters (SI units; the turn rates are 0.5°/s and 0.25°/s)
DEFAULTS = {
    "window": 30.0,
    "omega_on": math.radians(0.5),
    "omega_off": math.radians(0.25),
    "v_stop": 0.5,
    "v_go": 1.0,
    "min_duration": 20.0,
}


@attrs.frozen
class ModeLabels:
    """The labelling of one track: ``segments`` (dicts ``start``, ``end`` (s), ``mode``, ``radius`` (m or None),
    ``turn_rate`` (rad/s, counter-clockwise positive), ``speed`` (median, m/s), ``first``/``last`` report indices), the
    ``parameters`` used, and per report the smoothed ``turn_rate`` and ``speed`` and the final ``modes``."""

    segments: tuple[dict, ...]
    parameters: dict
    turn_rate: np.ndarray = attrs.field(eq=attrs.cmp_using(eq=lambda a, b: np.array_equal(a, b, equal_nan=True)))
    speed: np.ndarray = attrs.field(eq=attrs.cmp_using(eq=lambda a, b: np.array_equal(a, b, equal_nan=True)))
    modes: tuple[str, ...]

    def to_dict(self) -> dict:
        """``{"parameters": …, "segments": […]}`` — plain JSON-ready values."""
        return {"parameters": dict(self.parameters), "segments": [dict(s) for s in self.segments]}


def _unwrapped(c: np.ndarray) -> np.ndarray:
    """Σ_{i≤k} wrap(c_i − c_{i−1}) (0 at k = 0), wrap(·) ∈ [−180°, 180°): the course change, unwrapped."""
    return np.concatenate([[0.0], np.cumsum((np.diff(c) + 180.0) % 360.0 - 180.0)])


def _window_sums(times: np.ndarray, valid: np.ndarray, window: float):
    """(t − t₀, window_sum, n): ``window_sum(a)`` sums a over the valid reports within ±window/2 of each report
    (prefix sums, so the cost is O(K) for any window), n counts them; ``window`` (s) is checked here."""
    window = check_positive(window, "window (s)")
    t = times - times[0]
    lo = np.searchsorted(t, t - window / 2.0, side="left")
    hi = np.searchsorted(t, t + window / 2.0, side="right")

    def window_sum(a):
        c = np.concatenate([[0.0], np.cumsum(np.where(valid, a, 0.0))])
        return c[hi] - c[lo]

    return t, window_sum, window_sum(np.ones_like(t))


def _checked(times, **columns) -> list[np.ndarray]:
    """[times, *columns] as float arrays: times finite and strictly increasing, each column one value per time."""
    t = np.asarray(times, dtype=np.float64)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"times: expected shape (K,) with K ≥ 1, got {t.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("times: expected finite, strictly increasing seconds")
    arrays = [t]
    for name, a in columns.items():
        a = np.asarray(a, dtype=np.float64)
        if a.shape != t.shape:
            raise ValueError(f"{name}: expected shape {t.shape} (one per time), got {a.shape}")
        if np.any(np.isinf(a)):
            raise ValueError(f"{name}: contains inf (NaN marks a missing value)")
        arrays.append(a)
    return arrays


def turn_rate(times, course, window: float = DEFAULTS["window"]) -> np.ndarray:
    """Smoothed turn rate ω (K,) in rad/s, counter-clockwise (left) positive, from the compass course (degrees).

    ω_k = −(π/180) × least-squares slope of the unwrapped course over the reports within ±window/2 of t_k
    (module docstring, step 1); NaN where fewer than two valid reports fall in the window.
    """
    t, c = _checked(times, course=course)
    valid = np.isfinite(c)
    u0 = np.zeros_like(c)  # the unwrapped course u minus its first value, 0 where the course is missing
    if valid.any():
        cv = c[valid]
        u0[valid] = (cv[0] + _unwrapped(cv)) - cv[0]
    t0, window_sum, n = _window_sums(t, valid, window)
    st, su = window_sum(t0), window_sum(u0)
    stt, stu = window_sum(t0 * t0), window_sum(t0 * u0)
    with np.errstate(invalid="ignore", divide="ignore"):
        sxx = stt - st * st / n
        sxy = stu - st * su / n
        slope = np.where((n >= 2) & (sxx > 1e-12 * np.maximum(stt, 1.0)), sxy / sxx, np.nan)
    return -np.radians(slope)


def smoothed_speed(times, speed, window: float = DEFAULTS["window"]) -> np.ndarray:
    """Mean speed (K,) over the valid reports within ±window/2 of each report; NaN where there is none."""
    t, v = _checked(times, speed=speed)
    valid = np.isfinite(v)
    _, window_sum, n = _window_sums(t, valid, window)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, window_sum(np.where(valid, v, 0.0)) / n, np.nan)


def _step_rates(t: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Unsmoothed turn rate of each step (K,), rad/s counter-clockwise: −wrap(c_k − c_j)/(t_k − t_j) from the
    previous report j with a course; NaN at the first report and where c_k is NaN."""
    rates = np.full_like(c, np.nan)
    index = np.flatnonzero(np.isfinite(c))
    if index.size > 1:
        dc = (np.diff(c[index]) + 180.0) % 360.0 - 180.0
        rates[index[1:]] = -np.radians(dc / np.diff(t[index]))
    return rates


def _segment_rate(t, c, raw, first, last, window) -> float:
    """A segment's turn rate (rad/s, counter-clockwise): minus the least-squares slope of the unwrapped course over its
    interior, the reports more than window/2 from both ends (where the smoothing may have moved the boundary); with
    fewer than 3 interior reports with a course, the median of the step rates of the whole segment."""
    index = np.arange(first, last + 1)
    index = index[np.isfinite(c[index])]
    inner = index[(t[index] >= t[first] + window / 2) & (t[index] <= t[last] - window / 2)]
    if inner.size >= 3:
        u = _unwrapped(c[inner])
        tt = t[inner] - t[inner].mean()
        return float(-np.radians(np.dot(tt, u - u.mean()) / np.dot(tt, tt)))
    w = raw[first + 1 : last + 1]  # the steps ending inside the segment
    return float(np.median(w[np.isfinite(w)])) if np.isfinite(w).any() else math.nan


def motion_states(omega, v, p) -> list[str]:
    """The mode of each report from its turn rate ω (rad/s, counter-clockwise positive) and speed v (m/s) by the
    hysteresis of step 3 of the module docstring, thresholds ``p["omega_on"]``, ``p["omega_off"]``,
    ``p["v_stop"]``, ``p["v_go"]`` (what :func:`label_modes` does with the smoothed course and speed, and what
    ``hybridtrack track`` does with the estimated ω̂ and |v̂| under ``[segments] by = "motion"``)."""
    state = "straight"
    stopped = False
    out = []
    for w, s in zip(omega, v):
        stopped = not s >= p["v_go"] if stopped else s < p["v_stop"]  # a NaN speed keeps the state
        if not stopped and not np.isnan(w):  # a turn is entered above omega_on and left below omega_off
            left = p["omega_off"] if state == "left_turn" else p["omega_on"]
            right = p["omega_off"] if state == "right_turn" else p["omega_on"]
            state = "left_turn" if w > left else ("right_turn" if w < -right else "straight")
        out.append("stop" if stopped else state)
    return out


def label_modes(times, course, speed, **parameters) -> ModeLabels:
    """Label the reports (times (K,) s, compass course (K,) degrees, speed over ground (K,) m/s; NaN = missing) with
    straight / left_turn / right_turn / stop segments (module docstring).

    ``parameters`` override :data:`DEFAULTS`: ``window`` (s), ``omega_on`` ≥ ``omega_off`` (rad/s), ``v_stop`` ≤
    ``v_go`` (m/s), ``min_duration`` (s, 0 keeps every segment).
    """
    unknown = sorted(set(parameters) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"label_modes: unknown parameters {unknown}; expected some of {sorted(DEFAULTS)}")
    p = {**DEFAULTS, **parameters}
    for name in ("window", "omega_on", "omega_off", "v_stop", "v_go"):
        p[name] = check_positive(p[name], name)
    p["min_duration"] = float(p["min_duration"])
    if not (math.isfinite(p["min_duration"]) and p["min_duration"] >= 0):
        raise ValueError(f"min_duration: expected a finite number of seconds ≥ 0, got {parameters.get('min_duration')!r}")
    if p["omega_off"] > p["omega_on"]:
        raise ValueError(f"omega_off ({p['omega_off']}) must not exceed omega_on ({p['omega_on']}) (hysteresis: leave below, enter above)")
    if p["v_go"] < p["v_stop"]:
        raise ValueError(f"v_go ({p['v_go']}) must not be below v_stop ({p['v_stop']})")
    t, c, v = _checked(times, course=course, speed=speed)
    omega = turn_rate(t, c, p["window"])
    vbar = smoothed_speed(t, v, p["window"])
    runs = joined_runs([[m, k, k] for k, m in enumerate(motion_states(omega, vbar, p))])
    runs = merged_runs(runs, t, dict.fromkeys({run[0] for run in runs}, p["min_duration"]))
    raw = _step_rates(t, c)
    segments = []
    for i, (mode, first, last) in enumerate(runs):
        end = t[runs[i + 1][1]] if i + 1 < len(runs) else t[last]
        s = v[first : last + 1]
        w_med = _segment_rate(t, c, raw, first, last, p["window"]) + 0.0  # + 0.0: no -0.0 in the output
        s_med = float(np.median(s[np.isfinite(s)])) if np.isfinite(s).any() else math.nan
        turn = mode in ("left_turn", "right_turn") and math.isfinite(w_med) and w_med != 0 and math.isfinite(s_med)
        segments.append(
            {
                "start": float(t[first]),
                "end": float(end),
                "mode": mode,
                "radius": s_med / abs(w_med) if turn else None,
                "turn_rate": None if math.isnan(w_med) else w_med,
                "speed": None if math.isnan(s_med) else s_med,
                "first": int(first),
                "last": int(last),
            }
        )
    for a in (omega, vbar):
        a.setflags(write=False)
    modes = tuple(mode for mode, first, last in runs for _ in range(first, last + 1))  # the mode of each report
    return ModeLabels(tuple(segments), p, omega, vbar, modes)


def label_track(track, **parameters) -> ModeLabels:
    """:func:`label_modes` on a :class:`hybridtrack.io.track_files.Track` (its times, course and speed columns)."""
    if track.course is None or track.speed is None:
        raise ValueError(f"track {track.id!r}: needs course and speed over ground columns (read_tracks course=…, speed=…)")
    return label_modes(track.times, track.course, track.speed, **parameters)
