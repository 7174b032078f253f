"""Simulated multi-target scenes: crossing, manoeuvring targets seen in clutter as scans of unlabelled detections (issue 23, item 1).

Scene model of :func:`simulate_scene` (scan k at time t_k = k T, T = ``interval``, k = 0 … K−1):

* **Targets** i = 0 … N_T−1 move in the plane with state (x, vx, y, vy) at a constant speed s_i ~ U(``speed``) and
  an initial heading uniform in [0, 2π).  Their motion is piecewise: straight segments and coordinated turns
  alternate, each lasting a duration drawn from ``straight`` or ``turn`` (seconds, uniform, rounded to whole
  scans, at least one; the first segment, straight or turn with probability ½, starts at a random point of its
  duration).  A turn's peak rate ω̂ has |ω̂| ~ U(``turn_rate``) (°/s) and a random sign (positive: left,
  counter-clockwise); with ``ramp`` > 0 s the rate within a turn of D scans rises and falls linearly,
  ω_q = ω̂ min(1, (q + 1) T/ramp, (D − q) T/ramp) over its steps q = 0 … D−1 (a trapezoid), else ω_q = ω̂.
  Between scans the rate is constant and the step is the exact coordinated turn (Bar-Shalom, Li & Kirubarajan,
  *Estimation with Applications to Tracking and Navigation*, Wiley 2001, §11.7.1), with a = ω T:

      x⁺ = x + T (vx s₁(a) − vy c₁(a))     vx⁺ = vx cos a − vy sin a
      y⁺ = y + T (vx c₁(a) + vy s₁(a))     vy⁺ = vx sin a + vy cos a

  s₁(a) = sin a / a = sinc(a/π), c₁(a) = (1 − cos a)/a = sin(a/2) sinc(a/2π): exact at a = 0 (straight motion),
  no branch.  There is no process noise: the manoeuvres are the targets' only departure from straight lines.
* **Lives**: without ``births`` every target is present at every scan.  With ``births``, target i lives
  L_i ~ U(``lifetime``) seconds (rounded to scans, 1 … K) from a scan b_i uniform in 0 … K − L_i, so that it is
  born and dies within the scene.
* **Placement**: each path is simulated from the origin, then shifted so that it is halfway through its life at a
  point uniform over the middle half of ``region`` (the middle 50 % of each axis), moved the least needed to keep
  its bounding box inside the region: every target starts inside, moves across the region and the paths cross
  (in :func:`crossing_scene`, 30–70 of the 190 pairs of paths cross, by seed).  A path too large for the region along an
  axis starts at a uniform point inside it instead; where it then leaves the region the target is out of the
  sensor's coverage: neither detected nor part of the truth.
* **Detections**: at each scan every target present is detected with probability P_D
  (``detection_probability``), z = (x, y) + w, w ~ N(0, σ² I₂) (σ = ``sigma``); the clutter is Poisson with mean
  λ = ``clutter_per_scan`` detections per scan, uniform over the region (the model of
  :class:`~hybridtrack.engine.clutter.ClutterModel`, density λ/V, which draws them; Bar-Shalom & Fortmann 1988,
  §6.4).  Within a scan the detections are in random order.

The result is a :class:`~hybridtrack.engine.detections.Detections` with every detection's ``origin`` (target index,
−1 for clutter) and the :class:`~hybridtrack.engine.detections.Truth`: every target's state at each scan where it
is present and inside the region, layout (x, vx, y, vy).  Randomness comes from one ``numpy.random.Generator`` per
part (motion, placement, detection, noise, clutter, order), spawned from ``seed``: the same seed gives the same scene.

Why not :func:`hybridtrack.engine.simulate.simulate_trajectories`: it runs one schedule of registered motion models
at a time, with process noise, through the models' transition matrices; a scene of 10,000 targets × hundreds of
scans needs all targets advanced at once, and the piecewise coordinated turn with a rate that changes per scan is
the one motion needed — written here once, vectorized over the targets, as the same equations as the
``coordinated_turn`` motion model.
"""

from __future__ import annotations

import math

import numpy as np

from hybridtrack.engine.clutter import ClutterModel
from hybridtrack.engine.detections import Detections, Truth

#: the layout of :attr:`Truth.states` of a simulated scene
SCENE_LAYOUT = ("x", "vx", "y", "vy")
#: the region of :func:`simulate_scene` when none is given: ((x0, x1), (y0, y1)) metres
DEFAULT_REGION = ((0.0, 5000.0), (0.0, 5000.0))


def _count(value, name: str, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name}: expected an integer ≥ {low}, got {value!r}")
    return int(value)


def _number(value, name: str, *, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not math.isfinite(value):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    if value < 0 or (positive and value == 0):
        raise ValueError(f"{name}: expected a number {'> 0' if positive else '≥ 0'}, got {value!r}")
    return float(value)


def _range(value, name: str, *, positive: bool = False) -> tuple[float, float]:
    """(low, high) with 0 ≤ low ≤ high (0 < low with ``positive``)."""
    try:
        low, high = value
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a range (low, high), got {value!r}") from None
    low, high = _number(low, f"{name}[0]", positive=positive), _number(high, f"{name}[1]", positive=positive)
    if high < low:
        raise ValueError(f"{name}: expected low ≤ high, got {value!r}")
    return low, high


def _region(value) -> np.ndarray:
    """((x0, x1), (y0, y1)) as a (2, 2) array with x1 > x0, y1 > y0."""
    try:
        region = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        region = None
    if region is None or region.shape != (2, 2) or not np.all(np.isfinite(region)):
        raise ValueError(f"region: expected ((x0, x1), (y0, y1)) in metres, got {value!r}")
    if not np.all(region[:, 1] > region[:, 0]):
        raise ValueError(f"region: expected x1 > x0 and y1 > y0, got {value!r}")
    return region


def _streams(seed, count: int) -> list[np.random.Generator]:
    if isinstance(seed, np.random.Generator):
        return seed.spawn(count)
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(count)]


def _frozen(array: np.ndarray) -> np.ndarray:
    """``array`` (a new array owning its data, referenced nowhere else) made read-only, for a value type to keep."""
    if array.base is not None:
        array = array.copy()
    array.setflags(write=False)
    return array


def _steps(seconds: np.ndarray, interval: float) -> np.ndarray:
    """Durations in seconds → whole scans, at least one."""
    return np.maximum(1, np.rint(seconds / interval)).astype(np.int64)


def coordinated_turn_step(x, vx, y, vy, omega, interval: float):
    """One exact coordinated-turn step of length T = ``interval`` at the rate ``omega`` (rad/s), elementwise over
    arrays (module docstring; Bar-Shalom, Li & Kirubarajan 2001, §11.7.1): returns (x⁺, vx⁺, y⁺, vy⁺)."""
    a = omega * interval
    s1 = np.sinc(a / np.pi)  # sin a / a
    c1 = np.sin(a / 2.0) * np.sinc(a / (2.0 * np.pi))  # (1 − cos a) / a
    cos, sin = np.cos(a), np.sin(a)
    return (x + interval * (vx * s1 - vy * c1), vx * cos - vy * sin, y + interval * (vx * c1 + vy * s1), vx * sin + vy * cos)


def simulate_scene(
    *,
    targets: int,
    scans: int,
    interval: float = 1.0,
    region=DEFAULT_REGION,
    detection_probability: float = 0.9,
    clutter_per_scan: float = 10.0,
    sigma: float = 10.0,
    speed=(5.0, 15.0),
    turn_rate=(0.5, 4.0),
    straight=(10.0, 40.0),
    turn=(5.0, 30.0),
    ramp: float = 0.0,
    births: bool = False,
    lifetime=None,
    seed=None,
) -> Detections:
    """A simulated scene of ``targets`` crossing, manoeuvring targets over ``scans`` scans ``interval`` seconds apart,
    detected with probability ``detection_probability`` with noise σ = ``sigma`` m, in Poisson clutter of
    ``clutter_per_scan`` detections per scan over ``region`` = ((x0, x1), (y0, y1)) metres (the model: module
    docstring).  ``speed`` (m/s), ``turn_rate`` (°/s), ``straight`` and ``turn`` (durations, s) and ``lifetime``
    (s; default from a quarter of the scene to all of it, used with ``births``) are (low, high) ranges drawn
    uniformly; ``ramp`` (s) the time a turn takes to reach its peak rate (0: at once).  The same ``seed`` gives the
    same scene."""
    targets = _count(targets, "targets", 0)
    scans = _count(scans, "scans", 1)
    interval = _number(interval, "interval", positive=True)
    region = _region(region)
    low, high = region[:, 0], region[:, 1]
    clutter = ClutterModel(
        density=_number(clutter_per_scan, "clutter_per_scan") / float(np.prod(high - low)),
        detection_probability=detection_probability,
        region=np.stack([low, high]),
    )
    sigma = _number(sigma, "sigma")
    speed = _range(speed, "speed")
    turn_rate = _range(turn_rate, "turn_rate")
    straight = _range(straight, "straight", positive=True)
    turn = _range(turn, "turn", positive=True)
    ramp = _number(ramp, "ramp")
    if not isinstance(births, (bool, np.bool_)):
        raise TypeError(f"births: expected True or False, got {births!r}")
    duration = scans * interval
    lifetime = (0.25 * duration, duration) if lifetime is None else _range(lifetime, "lifetime", positive=True)
    motion, placement, detection, noise, false, shuffle = _streams(seed, 6)

    # lives: the first scan b_i and the number of scans L_i of each target
    if births:
        lives = np.minimum(_steps(motion.uniform(*lifetime, targets), interval), scans)
        first = (motion.random(targets) * (scans - lives + 1)).astype(np.int64)
    else:
        lives = np.full(targets, scans, dtype=np.int64)
        first = np.zeros(targets, dtype=np.int64)

    # motion, all targets at once from scan 0 (a target's path is its part from its birth to its death):
    # straight segments and turns alternate
    heading = motion.uniform(0.0, 2.0 * np.pi, targets)
    s = motion.uniform(*speed, targets)
    x, y = np.zeros(targets), np.zeros(targets)
    vx, vy = s * np.cos(heading), s * np.sin(heading)
    rates = np.radians(turn_rate)

    def draw(turns):  # new segments (turn where ``turns``): their lengths (scans) and peak rates (rad/s, 0 when straight)
        n = turns.size
        length = np.where(turns, _steps(motion.uniform(*turn, n), interval), _steps(motion.uniform(*straight, n), interval))
        peak = motion.uniform(*rates, n) * np.where(motion.random(n) < 0.5, -1.0, 1.0)
        return length, np.where(turns, peak, 0.0)

    turning = motion.random(targets) < 0.5
    length, peak = draw(turning)
    position = (motion.random(targets) * length).astype(np.int64)  # the first segment starts part-way through
    last = first + lives  # a target is present at scans first ≤ k < last
    lowest, highest = np.full((2, targets), np.inf), np.full((2, targets), -np.inf)
    born, middle = np.zeros((2, targets)), np.zeros((2, targets))
    halfway = first + lives // 2
    present_count = np.cumsum(np.bincount(first, minlength=scans + 1) - np.bincount(last, minlength=scans + 1))[:scans]
    rows = np.concatenate([[0], np.cumsum(present_count)])  # the truth rows of scan k: rows[k] … rows[k + 1]
    ids, states = np.empty(rows[-1], dtype=np.intp), np.empty((rows[-1], 4))  # by scan, then by target
    for k in range(scans):
        if k:
            shape = np.minimum(1.0, np.minimum(position + 1, length - position) * (interval / ramp)) if ramp > 0 else 1.0
            x, vx, y, vy = coordinated_turn_step(x, vx, y, vy, peak * shape, interval)
            position += 1
            switch = np.flatnonzero(position >= length)
            if switch.size:
                turning[switch] = ~turning[switch]
                length[switch], peak[switch] = draw(turning[switch])
                position[switch] = 0
        present = (first <= k) & (k < last)
        alive = np.flatnonzero(present)
        here = slice(rows[k], rows[k + 1])
        ids[here] = alive
        for c, values in enumerate((x, vx, y, vy)):
            states[here, c] = values[alive]
        starting = alive[first[alive] == k]
        born[0, starting], born[1, starting] = x[starting], y[starting]
        midway = alive[halfway[alive] == k]
        middle[0, midway], middle[1, midway] = x[midway], y[midway]
        for axis, values in ((0, x), (1, y)):
            np.minimum(lowest[axis], values, out=lowest[axis], where=present)
            np.maximum(highest[axis], values, out=highest[axis], where=present)

    # placement: halfway through its life in the region's middle half, the bounding box inside (or the start inside)
    extent = highest - lowest
    size = (high - low)[:, None]
    u = placement.random((2, targets))
    centre = low[:, None] + (0.25 + 0.5 * u) * size  # where each path is halfway through its life: the region's middle half
    inner = np.clip(centre - middle, low[:, None] - lowest, high[:, None] - highest)  # moved the least to fit inside
    offset = np.where(extent <= size, inner, low[:, None] + u * size - born)

    scan = np.repeat(np.arange(scans), present_count)
    states[:, 0] += offset[0, ids]
    states[:, 2] += offset[1, ids]
    inside = (states[:, 0] >= low[0]) & (states[:, 0] <= high[0]) & (states[:, 2] >= low[1]) & (states[:, 2] <= high[1])
    if not inside.all():
        ids, scan, states = ids[inside], scan[inside], states[inside]
    scan_times = interval * np.arange(scans)
    truth = Truth(_frozen(scan_times[scan]), _frozen(ids), _frozen(states), SCENE_LAYOUT)  # handed over, not copied

    # detections: each target present detected with P_D, plus Poisson clutter; random order within each scan
    seen = np.flatnonzero(detection.random(ids.size) < clutter.detection_probability)
    z_true = np.column_stack([states[seen, 0], states[seen, 2]]) + sigma * noise.standard_normal((seen.size, 2))
    false_points = [clutter.draw_false(false) for _ in range(scans)]
    false_scan = np.repeat(np.arange(scans), [p.shape[0] for p in false_points])
    all_scan = np.concatenate([scan[seen], false_scan])
    all_z = np.concatenate([z_true, *false_points])
    all_origin = np.concatenate([ids[seen], np.full(false_scan.size, -1)])
    order = np.argsort(all_scan + shuffle.random(all_scan.size))  # by scan; within one, a random order
    del z_true, false_points, seen
    scan = all_scan[order]
    del all_scan
    z = all_z[order]
    del all_z
    return Detections(
        scan_times=scan_times,
        scan=_frozen(scan),
        times=_frozen(scan_times[scan]),
        z=_frozen(z),
        origin=_frozen(all_origin[order]),
        truth=truth,
    )


def crossing_scene(seed=None, **changes) -> Detections:
    """The simulated scene of issue 23: 20 targets crossing and turning at 0.5–4 °/s, P_D = 0.9, 10 clutter detections
    per scan, σ = 10 m, 200 scans of 1 s, over the default region (5 km × 5 km); ``changes`` override any keyword of
    :func:`simulate_scene` (e.g. ``births=True``)."""
    settings = dict(
        targets=20,
        scans=200,
        interval=1.0,
        detection_probability=0.9,
        clutter_per_scan=10.0,
        sigma=10.0,
        turn_rate=(0.5, 4.0),
        births=False,
    )
    return simulate_scene(**(settings | changes), seed=seed)
