"""Observer maneuvers, simulated bearings and the seed 002 scenario (seed 002 §5.1).

The observer sails at constant speed along legs (constant course) joined by
turns at a constant rate ω, each by the shortest direction (seed 002 §5.1:
«циркуляцией с постоянной угловой скоростью ω = 0.5°/с по кратчайшему
направлению»).  Courses follow the bearing convention: clockwise from north
for "north", counter-clockwise from +x for "math"; velocity = V u(course).
During a turn c(t) = c_0 + ε ω t (ε = ±1) and the position is integrated in
closed form, e.g. (north) x(t) = x_0 − V (cos c(t) − cos c_0)/(ε ω),
y(t) = y_0 + V (sin c(t) − sin c_0)/(ε ω).

A 180° course change has no shortest direction; ``tie`` chooses (default
"right": clockwise in the north convention, i.e. increasing course).

No hook: this module is a scenario helper, not a plugin.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack.core.validation import as_float_array
from hybridtrack.sdk.linalg import wrap_angle
from hybridtrack_plugins.sensors.bearing import BearingSensor, check_convention, direction
from hybridtrack_plugins.solvers.tma_model import BearingsProblem, from_polar


@attrs.frozen
class Leg:
    """Hold ``course`` (degrees) for ``duration`` seconds."""

    course: float = attrs.field(converter=float)
    duration: float = attrs.field(converter=float)


@attrs.frozen
class Turn:
    """Turn to ``course`` (degrees) at ``rate`` degrees per second, by ``direction`` "shortest", "right" or "left".

    "right" increases the course (clockwise in the north convention), "left" decreases it.
    """

    course: float = attrs.field(converter=float)
    rate: float = attrs.field(default=0.5, converter=float)
    direction: str = attrs.field(default="shortest", validator=attrs.validators.in_(("shortest", "right", "left")))


@attrs.frozen(eq=False)
class _Piece:
    start: float  # time
    duration: float
    position: np.ndarray  # (2,) at start
    course: float  # radians at start
    rate: float  # signed, rad/s (0 on a leg)


@attrs.frozen(eq=False)
class ObserverPath:
    """A piecewise leg/turn path at constant ``speed`` (m/s) starting at ``start`` (x, y) at time ``t0``.

    Build it with :meth:`build`; :meth:`position` and :meth:`course` accept any array of times.
    """

    speed: float
    pieces: tuple[_Piece, ...]
    convention: str

    @classmethod
    def build(
        cls, segments: Sequence[Leg | Turn], speed: float, start=(0.0, 0.0), t0: float = 0.0, convention: str = "north", tie: str = "right"
    ) -> ObserverPath:
        check_convention(convention)
        if tie not in ("right", "left"):
            raise ValueError(f"tie: expected 'right' or 'left', got {tie!r}")
        if not (np.isfinite(speed) and speed >= 0):
            raise ValueError(f"speed: expected a finite speed ≥ 0, got {speed!r}")
        if not segments or not isinstance(segments[0], Leg):
            raise ValueError("segments: the path must start with a Leg (it sets the initial course)")
        position = as_float_array(start, "start", (2,)).copy()
        t, course = float(t0), np.deg2rad(segments[0].course)
        pieces = []
        for i, seg in enumerate(segments):
            if isinstance(seg, Leg):
                if abs(wrap_angle(np.deg2rad(seg.course) - course)) > 1e-9:
                    raise ValueError(
                        f"segments[{i}]: leg course {seg.course}° differs from the current course {np.rad2deg(course):.6g}°; insert a Turn"
                    )
                if seg.duration < 0:
                    raise ValueError(f"segments[{i}]: negative duration {seg.duration}")
                piece = _Piece(t, seg.duration, position, course, 0.0)
            elif isinstance(seg, Turn):
                if not seg.rate > 0:
                    raise ValueError(f"segments[{i}]: turn rate must be positive, got {seg.rate}")
                delta = float(wrap_angle(np.deg2rad(seg.course) - course))  # (−π, π]
                way = tie if seg.direction == "shortest" and abs(delta) >= np.pi - 1e-12 else seg.direction
                if way == "right" and delta < 0:  # increasing course (clockwise in the north convention)
                    delta += 2 * np.pi
                elif way == "left" and delta > 0:
                    delta -= 2 * np.pi
                omega = np.deg2rad(seg.rate)
                piece = _Piece(t, abs(delta) / omega, position, course, omega if delta >= 0 else -omega)
            else:
                raise ValueError(f"segments[{i}]: expected Leg or Turn, got {type(seg).__name__}")
            pieces.append(piece)
            end = piece.start + piece.duration
            position = _advance(piece, np.array([end]), speed, convention)[0]
            t, course = end, piece.course + piece.rate * piece.duration
        return cls(float(speed), tuple(pieces), convention)

    @property
    def duration(self) -> float:
        last = self.pieces[-1]
        return last.start + last.duration - self.pieces[0].start

    def _piece_index(self, times):
        starts = np.array([p.start for p in self.pieces])
        return np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(self.pieces) - 1)

    def position(self, times) -> np.ndarray:
        """Observer positions (..., 2) at ``times`` (extrapolating the last piece beyond its end)."""
        times = as_float_array(times, "times")
        out = np.empty(times.shape + (2,))
        index = self._piece_index(times)
        for i, piece in enumerate(self.pieces):
            mask = index == i
            if mask.any():
                out[mask] = _advance(piece, times[mask], self.speed, self.convention)
        return out

    def course(self, times) -> np.ndarray:
        """Course (radians, wrapped) at ``times``."""
        times = as_float_array(times, "times")
        index = self._piece_index(times)
        c0, rate, start = np.array([(p.course, p.rate, p.start) for p in self.pieces])[index].T
        return wrap_angle(c0 + rate * (times - start))


def _advance(piece: _Piece, times: np.ndarray, speed: float, convention: str) -> np.ndarray:
    """Position at ``times`` on one piece: straight V u(c) t, or the closed-form turn integral."""
    dt = times - piece.start
    if piece.rate == 0.0:
        ux, uy = direction(piece.course, convention)
        return piece.position + speed * dt[:, None] * np.array([ux, uy])
    c0, c = piece.course, piece.course + piece.rate * dt
    # ∫ sin c dt = −(cos c − cos c0)/ω̇, ∫ cos c dt = (sin c − sin c0)/ω̇
    int_sin = -(np.cos(c) - np.cos(c0)) / piece.rate
    int_cos = (np.sin(c) - np.sin(c0)) / piece.rate
    pair = (int_sin, int_cos) if convention == "north" else (int_cos, int_sin)
    return piece.position + speed * np.stack(pair, axis=-1)


def simulate_bearings(
    theta, times, observer, sigma: float, rng: np.random.Generator, convention="north", reference_time: float | None = None
) -> np.ndarray:
    """Bearings X (..., n) of targets θ (..., 4) (at ``reference_time``, default ``times[0]``) with noise σ (radians).

    Uses the bearing sensor plugin: X = wrap(φ + N(0, σ²)); σ = 0 gives exact bearings.
    """
    theta = as_float_array(theta, "theta")
    times = as_float_array(times, "times", (None,))
    observer = as_float_array(observer, "observer", (len(times), 2))
    t_r = times[0] if reference_time is None else reference_time
    positions = theta[..., None, :2] + theta[..., None, 2:] * (times - t_r)[:, None]  # x0 + v (t − t_r), (..., n, 2)
    sensor = BearingSensor(sigma=sigma if sigma > 0 else 1.0, observer=observer, convention=convention)
    if sigma < 0:
        raise ValueError(f"sigma: expected σ ≥ 0, got {sigma}")
    if sigma == 0:
        return sensor.measure(positions, ("x", "y"))[..., 0]
    return sensor.simulate(positions, ("x", "y"), rng)[..., 0]


# --------------------------------------------------------------------------- seed 002 scenario


@attrs.frozen
class Seed002Scenario:
    """The seed's three-leg, 20-minute observer and target distribution (seed 002 §5.1).

    Observer at 5 m/s: course 0° for 180 s, turn to 270° at 0.5°/s (180 s), 270°
    for 300 s, turn to 90° (360 s), 90° for 180 s; bearings every 2 s from
    t = 0 (600 bearings, the last at 1198 s).  Prior guess: bearing 0°, range
    25 km, course 90°, 10 m/s.  Targets at the start of the observation:
    bearing 0°, range U(5, 50) km, course U(0°, 180°), speed U(5, 15) m/s.
    """

    speed: float = 5.0
    interval: float = 2.0
    duration: float = 1200.0
    turn_rate: float = 0.5
    convention: str = "north"
    tie: str = "right"
    prior: tuple[float, float, float, float] = (0.0, 25_000.0, 90.0, 10.0)  # bearing °, range m, course °, speed m/s
    range_limits: tuple[float, float] = (5_000.0, 50_000.0)
    course_limits: tuple[float, float] = (0.0, 180.0)
    speed_limits: tuple[float, float] = (5.0, 15.0)

    def observer_path(self) -> ObserverPath:
        r = self.turn_rate
        segments = [Leg(0, 180), Turn(270, r), Leg(270, 300), Turn(90, r), Leg(90, 180)]
        return ObserverPath.build(segments, self.speed, convention=self.convention, tie=self.tie)

    def times(self) -> np.ndarray:
        return np.arange(0.0, self.duration, self.interval)

    def observer(self) -> np.ndarray:
        return self.observer_path().position(self.times())

    def prior_theta(self) -> np.ndarray:
        b, rng_, c, v = self.prior
        return from_polar(np.deg2rad(b), rng_, np.deg2rad(c), v, self.observer()[0], self.convention)

    def draw_targets(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """θ (size, 4) at t = 0 drawn uniformly as the seed says."""
        ranges = rng.uniform(*self.range_limits, size)
        courses = np.deg2rad(rng.uniform(*self.course_limits, size))
        speeds = rng.uniform(*self.speed_limits, size)
        return from_polar(np.zeros(size), ranges, courses, speeds, self.observer()[0], self.convention)


def example_problem(interval: float = 20.0, sigma_deg: float = 0.5, seed: int = 0) -> BearingsProblem:
    """A small seed 002 problem (one target, bearings every ``interval`` s, noise σ) for contract checks and demos."""
    scenario = Seed002Scenario(interval=interval)
    rng = np.random.default_rng(seed)
    theta = scenario.draw_targets(rng, 1)[0]
    times, observer = scenario.times(), scenario.observer()
    sigma = np.deg2rad(sigma_deg)
    bearings = simulate_bearings(theta, times, observer, sigma, rng, scenario.convention)
    return BearingsProblem(times, bearings, observer, sigma=sigma, initial=scenario.prior_theta(), convention=scenario.convention)
