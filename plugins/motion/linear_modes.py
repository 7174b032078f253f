"""The five linear motion modes of the hybrid model (SPEC §1; seed 000 §"Модель", eq. 1–3).

x_k = Φ_p x_{k-1} + B_p u + G_p w_{k-1}, u ≡ 1, w ~ N(0, Q_p), with per-axis
blocks Φ = blockdiag(Φ_axis, Φ_axis):

* straight (CV):  Φ_axis = [[1, τ], [0, 1]], B = 0
* left / right turn of radius r: Φ_axis = [[cos ωτ, sin ωτ/ω], [−ω sin ωτ, cos ωτ]],
  B = [x_c(1 − cos ωτ), ω x_c sin ωτ, y_c(1 − cos ωτ), ω y_c sin ωτ] with the
  turn centre (x_c, y_c) = (x_s ∓ v_ys/ω, y_s ± v_xs/ω) (upper sign: left) and
  ω = |v_s|/r fixed at the switching moment s (seed 000 eqs. for modes 2–3)
* constant acceleration: Φ_axis = [[1, τ, τ²/2], [0, 1, τ], [0, 0, 1]], B = 0
* stop: Φ_axis = [[1, 0], [0, 0]], B = 0

G = [[0,1,0,0],[0,0,0,1]]ᵀ for the 4-state modes (noise on the velocities),
[[0,0,1,0,0,0],[0,0,0,0,0,1]]ᵀ for constant acceleration (noise on the
accelerations).  Layouts: ("x", "vx", "y", "vy") and ("x", "vx", "ax", "y", "vy", "ay").

Entering constant acceleration augments the state: the acceleration is the
segment's ``acceleration`` parameter if given, zero otherwise (then only the
noise drives it).  Leaving it drops the acceleration (the velocity reached is
kept).  A turn entered at zero speed has ω = 0 and moves as the straight mode:
the formulas below use (1 − cos ωτ)/ω = 2 sin²(ωτ/2)/ω and sin(ωτ)/ω = τ·sinc,
so nothing divides by zero.

Process noise, either per step or per second:

* ``noise_cov`` (the seeds' form, default Q of Example 1): w ~ N(0, Q_p) on
  the velocities (accelerations) of each step, whatever its length;
* ``noise_density`` q, in physical units per second
  (:mod:`hybridtrack.sdk.process_noise`): each axis block gets the discretized
  continuous white-noise Q(Δt) — straight and the turns white acceleration,
  q [[Δt³/3, Δt²/2], [Δt²/2, Δt]], q in m²/s³ (for a turn this is the
  constant-velocity Q, the usual approximation for ωΔt ≪ 1); constant
  acceleration white jerk (order 3, q in m²/s⁵); stop a position random walk
  of q in m²/s, the velocity the mean velocity of that walk over the step,
  p⁺ = p + w, v⁺ = w/Δt, w ~ N(0, q Δt), i.e. Q_axis = q [[Δt, 1], [1, 1/Δt]]
  (heading undefined, speed ~ √(q/Δt)).  Written G(Δt) w with w ~ N(0, q I),
  G(Δt) a factor of Q(Δt)/q, so ``noise_cov`` = q I is the transition's Q.

Inputs checked (ValueErrors naming the parameter): ``radius`` a finite number
of metres ≥ :data:`MIN_RADIUS` (10⁻⁶ m); ``tau`` finite and > 0; a step whose
F, B or G Q Gᵀ would exceed the filters' float64 arithmetic
(:func:`hybridtrack.core.validation.transition_excess`: |F| ≤ 10⁷⁵, e.g. τ ≤ 10⁷⁵ s
for straight, 4.5·10³⁷ s for constant acceleration) names ``tau`` and the
usable range of τ for the mode, or, for a turn whose rate ω = |v_s|/r is the
cause, ``radius``, the switch speed and the smallest usable radius.
"""

from __future__ import annotations

import itertools
import math
from abc import abstractmethod
from collections.abc import Callable, Sequence
from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import LinearTransition, MotionModel, TransitionBank, convert_layout
from hybridtrack.core.validation import TRANSITION_MAGNITUDE_LIMIT, as_float_array, check_covariance, check_positive, transition_excess
from hybridtrack.sdk.process_noise import check_density, white_noise_root

LAYOUT_4 = ("x", "vx", "y", "vy")
LAYOUT_6 = ("x", "vx", "ax", "y", "vy", "ay")
G_4 = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
G_6 = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
#: Q of Example 1 (seed 000), the default process-noise covariance of every mode
DEFAULT_NOISE = ((0.01, 0.0), (0.0, 0.01))


def _noise_cov(value) -> np.ndarray | None:
    return None if value is None else check_covariance(value, "noise_cov", 2, readonly=True)


def _noise_density(value) -> float | None:
    return None if value is None else check_density(value, "noise_density", "units²/s per derivative order (m²/s³ for a velocity)")


def _noise_field():
    return attrs.field(default=None, converter=_noise_cov, eq=attrs.cmp_using(eq=np.array_equal))


@attrs.frozen
class _Noise:
    """The noise of a linear mode (module docstring): ``noise_cov`` per step or ``noise_density`` per second, not
    both; without either the Q of Example 1 per step.  Under a density ``noise_cov`` reads q I (the Q of the
    transition) and :meth:`noise_gain` is the factor G(Δt) of the axis blocks."""

    noise_cov: np.ndarray | None = _noise_field()
    noise_density: float | None = attrs.field(default=None, converter=_noise_density, kw_only=True)

    #: the white-noise order of an axis block under a density (2: white acceleration, 3: white jerk)
    order: ClassVar[int] = 2

    def __attrs_post_init__(self):
        if self.noise_density is None:
            object.__setattr__(self, "noise_cov", _noise_cov(DEFAULT_NOISE) if self.noise_cov is None else self.noise_cov)
        elif self.noise_cov is not None:
            raise ValueError(
                f"noise_cov, noise_density: give the noise per step (noise_cov) or per second (noise_density), not both;"
                f" got noise_cov {self.noise_cov.tolist()} and noise_density {self.noise_density!r}"
            )
        else:
            q = np.eye(self.axis_gain(1.0).shape[1] * 2) * self.noise_density
            q.flags.writeable = False
            object.__setattr__(self, "noise_cov", q)

    def axis_gain(self, tau: float) -> np.ndarray:
        """G_axis(Δt), the factor of one axis block's Q(Δt)/q."""
        return white_noise_root(tau, self.order)

    def noise_gain(self, tau) -> np.ndarray:
        """G of the transition: the seeds' fixed G (per-step noise) or blockdiag(G_axis(Δt), G_axis(Δt)); for an
        array of Δt (S,), (S, n, r)."""
        if self.noise_density is None:
            G = G_6 if self.state_dim == 6 else G_4
            return G if np.ndim(tau) == 0 else np.broadcast_to(G, np.shape(tau) + G.shape)
        axis = self.axis_gain(tau)
        k, r = axis.shape[-2:]
        G = np.zeros(axis.shape[:-2] + (2 * k, 2 * r))
        G[..., :k, :r] = G[..., k:, r:] = axis
        return G


def _check_tau(tau: float) -> float:
    return check_positive(tau, "tau", "the sampling period")


def step_lengths(tau, rows: int) -> np.ndarray:
    """``tau`` (one step length for all, or one per row) as (rows,) seconds, each finite and > 0, else a ValueError
    naming ``tau`` and the first bad entry."""
    if type(tau) is np.ndarray and tau.shape == (rows,) and tau.dtype == np.float64 and ((tau > 0) & (tau < math.inf)).all():
        return tau  # the common case, checked at once (NaN fails both comparisons)
    steps = np.broadcast_to(np.asarray(tau, dtype=float), (rows,)) if np.ndim(tau) == 0 else as_float_array(tau, "tau", (rows,))
    bad = ~(np.isfinite(steps) & (steps > 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"tau: expected step lengths in seconds, finite and > 0, got tau[{i}] = {float(steps[i])!r}")
    return steps


def transition_stack(F: np.ndarray, B: np.ndarray, G: np.ndarray, noise_cov: np.ndarray) -> TransitionBank:
    """The bank of F (S, n, n), B (S, n) and G (S, n, r) with w ~ N(0, Q_w = ``noise_cov``): Q = G Q_w Gᵀ and the
    noise root G chol(Q_w) (None for a singular Q_w), as ``TransitionBank.stack`` of the rows builds them."""
    try:
        root = G @ np.linalg.cholesky(noise_cov)
    except np.linalg.LinAlgError:
        root = None
    return TransitionBank(F, B, G @ noise_cov @ np.swapaxes(G, -1, -2), root)


#: the smallest turn radius (metres) a turn mode takes: below, ω = |v|/r exceeds 10⁶ rad/s per m/s of speed
MIN_RADIUS = 1e-6


def _radius(value) -> float:
    """The turn radius in metres: a finite number ≥ :data:`MIN_RADIUS`, else a ValueError naming ``radius``."""
    number = None
    if not isinstance(value, (bool, np.bool_)) and np.ndim(value) == 0:
        try:
            number = float(value)
        except (TypeError, ValueError):
            pass
    if number is None or not (math.isfinite(number) and number > 0):
        raise ValueError(f"radius: expected a finite number of metres > 0 (the turn radius), got {value!r}")
    if number < MIN_RADIUS:
        raise ValueError(
            f"radius: expected a turn radius of at least {MIN_RADIUS:g} m (the turn rate is ω = |v|/r; a tighter turn is taken"
            f" for a unit mistake), got {value!r}"
        )
    return number


def _usable(ok: Callable[[float], bool], bad: float, good: float) -> float | None:
    """The value nearest to ``bad`` for which ``ok`` still holds, going from ``good`` towards ``bad`` (bisection of the
    logarithm); None when ``ok(good)`` fails too.  Only for error messages (the usable range of a parameter)."""
    if not ok(good):
        return None
    low, high = math.log(good), math.log(bad)
    for _ in range(60):
        middle = (low + high) / 2
        low, high = (middle, high) if ok(math.exp(middle)) else (low, middle)
    return math.exp(low)


def _checked(F, B, G, Q, why: Callable[[str], str]) -> None:
    """A ValueError if the transition (F, B, G Q Gᵀ) of a step exceeds the filters' float64 arithmetic
    (:func:`~hybridtrack.core.validation.transition_excess`); ``why(excess)`` names the parameter and its usable range."""
    with np.errstate(over="ignore", invalid="ignore"):
        excess = transition_excess(F, B, G @ Q @ np.swapaxes(G, -1, -2))
    if excess is not None:
        raise ValueError(why(excess))


def _tau_message(name: str, tau: float, excess: str, ok: Callable[[float], bool]) -> str:
    bound = _usable(ok, tau, 1.0)
    side = "" if bound is None else f"; expected tau {'≤' if tau > 1.0 else '≥'} {bound:.3g} s for this mode"
    return (
        f"tau: a step of {tau!r} s gives the {name!r} transition {excess}, beyond the float64 arithmetic of the filters"
        f" (the prediction F P Fᵀ + G Q Gᵀ overflows){side}"
    )


def _blockdiag(axis: np.ndarray) -> np.ndarray:
    """blockdiag(A, A) of A (..., k, k)."""
    k = axis.shape[-1]
    F = np.zeros(axis.shape[:-2] + (2 * k, 2 * k))
    F[..., :k, :k] = F[..., k:, k:] = axis
    return F


@attrs.frozen
class _FixedMatrixMode(_Noise, MotionModel):
    """A mode whose Φ depends on τ only (B = 0): subclasses give Φ_axis."""

    layout: ClassVar[tuple[str, ...]] = LAYOUT_4

    @abstractmethod
    def axis_matrix(self, tau) -> np.ndarray:
        """Φ_axis, the block of one axis ((..., k, k) for an array of Δt)."""

    def arrays(self, tau) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """F, B, G of a step of ``tau`` seconds (or of each of an array of steps; unchecked: :meth:`transition` checks them)."""
        with np.errstate(over="ignore", invalid="ignore"):
            return _blockdiag(self.axis_matrix(tau)), np.zeros(np.shape(tau) + (self.state_dim,)), self.noise_gain(tau)

    def within_arithmetic(self, tau: float) -> bool:
        """Whether the transition of a step of ``tau`` seconds stays within the filters' float64 arithmetic."""
        F, B, G = self.arrays(tau)
        with np.errstate(over="ignore", invalid="ignore"):
            return transition_excess(F, B, G @ self.noise_cov @ G.T) is None

    def transition(self, tau: float, switch_state: np.ndarray | None = None) -> LinearTransition:
        """F, B, G, Q of a step of ``tau`` seconds; a ValueError names ``tau`` (and its usable range) when F, B or
        G Q Gᵀ would exceed the filters' float64 arithmetic (:func:`~hybridtrack.core.validation.transition_excess`)."""
        tau = _check_tau(tau)
        F, B, G = self.arrays(tau)
        _checked(F, B, G, self.noise_cov, lambda excess: _tau_message(self.name, tau, excess, self.within_arithmetic))
        return LinearTransition(F, B, G, self.noise_cov)

    def transition_bank(self, tau, switch_states: np.ndarray) -> TransitionBank:
        """The transitions of the S rows over ``tau`` (one or (S,)): Φ does not depend on the switch state, so one
        transition per distinct step, vectorized, indexed back to the rows (a step beyond the float64 arithmetic is
        :meth:`transition`'s ValueError).  The transitions of the steps seen before come from the model's table
        (:class:`_StepTable`: irregular report times revisit the same Δt), the new ones are computed in one call."""
        table = self.__dict__.get("_step_table")
        if table is None:  # the instance's own (attrs frozen: set through __dict__; not part of eq or the fields)
            table = self.__dict__["_step_table"] = _StepTable()
        rows = np.shape(switch_states)[0]
        if not (type(tau) is float and 0.0 < tau < math.inf):
            return table.bank(step_lengths(tau, rows), self._distinct_bank)
        last = self.__dict__.get("_last_step")  # one step for all rows (the common case): its row, repeated
        if last is None or last[0] != tau:
            last = self.__dict__["_last_step"] = (tau, table.bank(np.array([tau]), self._distinct_bank))
        one = last[1]
        return TransitionBank(*(None if a is None else np.repeat(a, rows, axis=0) for a in (one.F, one.B, one.Q, one.noise_root)))

    def prepare_steps(self, steps) -> None:
        """Build the transitions of the step lengths ``steps`` (any shape; those finite and > 0) in one vectorized
        call and keep them (:class:`_StepTable`): what a batch of runs about to step through them asks first (the
        multiple-model estimator gives every Δt of its runs), so that its steps find them built.  An optional
        extension of the MotionModel protocol; nothing else changes."""
        steps = np.asarray(steps, dtype=float).reshape(-1)
        steps = np.unique(steps[np.isfinite(steps) & (steps > 0)])
        if steps.size:
            self.transition_bank(steps, np.zeros((steps.size, self.state_dim)))

    def _distinct_bank(self, distinct: np.ndarray) -> TransitionBank:
        """The transitions of the distinct steps (D,), vectorized (a step beyond the float64 arithmetic is
        :meth:`transition`'s ValueError)."""
        F, B, G = self.arrays(distinct)
        bank = transition_stack(F, B, G, self.noise_cov)
        with np.errstate(over="ignore", invalid="ignore"):
            if transition_excess(bank.F, bank.B, bank.Q) is not None:
                for t in distinct:
                    self.transition(float(t))
        return bank


class _StepTable:
    """The transitions a mode built, by step length: rows of F, B, Q and the noise root (None when the bank had
    none), stored with room to grow (doubling), and the row of each Δt; at most :data:`STEP_TABLE_SIZE` steps (then
    it starts afresh)."""

    def __init__(self):
        self.row: dict[float, int] = {}
        self.arrays: tuple = ()

    def bank(self, steps: np.ndarray, build: Callable[[np.ndarray], TransitionBank]) -> TransitionBank:
        """The bank of ``steps`` (S,), building the transitions of the steps not in the table by ``build`` (distinct
        sorted steps (D,) → their bank) in one call."""
        keys = steps.tolist()
        index = np.fromiter(map(self.row.get, keys, itertools.repeat(-1)), np.intp, len(keys))
        if index.size and index.min() < 0:
            new = sorted({t for t, r in zip(keys, index.tolist()) if r < 0})
            if len(self.row) + len(new) > STEP_TABLE_SIZE:  # full: start afresh with this call's steps
                self.row, self.arrays, new = {}, (), sorted(set(keys))
            self._add(new, build(np.array(new)))
            index = np.fromiter(map(self.row.__getitem__, keys), np.intp, len(keys))
        return TransitionBank(*(None if a is None else a.take(index, axis=0) for a in self.arrays))

    def _add(self, steps: list[float], bank: TransitionBank) -> None:
        """Append the transitions of the new ``steps`` (the table grown to twice what it holds when full)."""
        used = len(self.row)
        root = bank.noise_root if used == 0 or self.arrays[3] is not None else None  # a root for every row, or none
        parts = (bank.F, bank.B, bank.Q, root)
        if self.arrays and root is None:
            self.arrays = self.arrays[:3] + (None,)
        if not self.arrays or used + len(steps) > self.arrays[0].shape[0]:
            room = max(64, 2 * (used + len(steps)))
            grown = tuple(None if a is None else np.empty((room,) + a.shape[1:]) for a in parts)
            for old, a in zip(self.arrays, grown):
                if a is not None and old is not None:
                    a[:used] = old[:used]
            self.arrays = grown
        for old, a in zip(self.arrays, parts):
            if old is not None:
                old[used : used + len(steps)] = a
        self.row.update(zip(steps, range(used, used + len(steps))))


#: the most step lengths a linear mode keeps the transitions of (:class:`_StepTable`; 4 × 4 modes: about 20 MB)
STEP_TABLE_SIZE = 50_000


@attrs.frozen
class Straight(_FixedMatrixMode):
    """Straight uniform motion (constant velocity): Φ_axis = [[1, τ], [0, 1]] (seed 000, mode 1)."""

    name: ClassVar[str] = "straight"

    def axis_matrix(self, tau):
        A = np.zeros(np.shape(tau) + (2, 2))
        A[..., 0, 0] = A[..., 1, 1] = 1.0
        A[..., 0, 1] = tau
        return A


@attrs.frozen
class Stop(_FixedMatrixMode):
    """Stop: position held, velocity reset to the noise, Φ_axis = [[1, 0], [0, 0]] (SPEC §1)."""

    name: ClassVar[str] = "stop"

    def axis_matrix(self, tau):
        A = np.zeros(np.shape(tau) + (2, 2))
        A[..., 0, 0] = 1.0
        return A

    def axis_gain(self, tau) -> np.ndarray:
        """[√Δt, 1/√Δt]ᵀ: p⁺ = p + w, v⁺ = w/Δt with w ~ N(0, q Δt) (module docstring); (..., 2, 1) for an array."""
        root = np.sqrt(_check_tau(tau) if np.ndim(tau) == 0 else step_lengths(tau, np.size(tau)).reshape(np.shape(tau)))
        return np.stack([root, 1.0 / root], axis=-1)[..., None]


@attrs.frozen
class ConstantAcceleration(_FixedMatrixMode):
    """Constant acceleration: Φ_axis = [[1, τ, τ²/2], [0, 1, τ], [0, 0, 1]], 6-state (SPEC §1).

    Entering augments the state with the segment's ``acceleration`` (default 0).
    """

    name: ClassVar[str] = "constant_acceleration"
    layout: ClassVar[tuple[str, ...]] = LAYOUT_6
    order: ClassVar[int] = 3

    def axis_matrix(self, tau):
        A = np.zeros(np.shape(tau) + (3, 3))
        A[..., 0, 0] = A[..., 1, 1] = A[..., 2, 2] = 1.0
        A[..., 0, 1] = A[..., 1, 2] = tau
        A[..., 0, 2] = np.multiply(tau, tau) / 2
        return A

    def enter(self, state, layout: Sequence[str], parameters: dict | None = None) -> np.ndarray:
        acceleration = (parameters or {}).get("acceleration") or (0.0, 0.0)
        fill = {} if "ax" in layout else {"ax": acceleration[0], "ay": acceleration[1]}
        return convert_layout(state, layout, self.layout, fill)


@attrs.frozen
class _Turn(_Noise, MotionModel):
    """Uniform circular motion of radius r (seed 000, modes 2–3); ``direction`` +1 left, −1 right."""

    radius: float = attrs.field(default=5.0, converter=_radius)
    noise_cov: np.ndarray | None = _noise_field()

    layout: ClassVar[tuple[str, ...]] = LAYOUT_4
    direction: ClassVar[int] = 1
    example_parameters: ClassVar[dict] = {"radius": 5.0}

    def turn_centre(self, switch_state: np.ndarray) -> np.ndarray:
        """(x_c, y_c) = (x_s ∓ v_ys/ω, y_s ± v_xs/ω) = position + r · (unit normal towards the turn side)."""
        x, vx, y, vy = switch_state
        speed = np.hypot(vx, vy)
        if speed == 0:
            raise ValueError("turn centre undefined at zero speed")
        return np.array([x - self.direction * self.radius * vy / speed, y + self.direction * self.radius * vx / speed])

    def coefficients(self, tau: float, switch_states: np.ndarray, radius: float | None = None):
        """cos ωτ, sin(ωτ)/ω, −ω sin ωτ (the entries of Φ_axis) and B (..., 4) at switch states (..., 4), ω = |v_s|/r
        (r = ``radius``, default the model's).

        B = [x_c(1−c), ω x_c s, y_c(1−c), ω y_c s] with x_c = x_s − d·v_ys/ω,
        y_c = y_s + d·v_xs/ω (d = ``direction``), written without dividing by ω.
        """
        x, vx, y, vy = switch_states if switch_states.ndim == 1 else (switch_states[..., i] for i in range(4))  # 1-D: scalars
        w = np.hypot(vx, vy) / (self.radius if radius is None else radius)
        c, s = np.cos(w * tau), np.sin(w * tau)
        sin_over_w = tau * np.sinc(w * tau / np.pi)  # sin(ωτ)/ω, τ at ω = 0
        one_minus_cos_over_w = w * (tau * np.sinc(w * tau / (2 * np.pi))) ** 2 / 2  # (1 − cos ωτ)/ω
        d = self.direction
        B = np.empty(switch_states.shape)
        B[..., 0] = x * (1 - c) - d * vy * one_minus_cos_over_w
        B[..., 1] = (w * x - d * vy) * s
        B[..., 2] = y * (1 - c) + d * vx * one_minus_cos_over_w
        B[..., 3] = (w * y + d * vx) * s
        return c, sin_over_w, -w * s, B

    def arrays(self, tau: float, switch_states: np.ndarray, radius: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """F (..., 4, 4), B (..., 4) and G of a step of ``tau`` seconds at switch states (..., 4) (unchecked;
        :meth:`transition` checks them); ``radius`` default the model's."""
        with np.errstate(over="ignore", invalid="ignore"):
            c, sin_over_w, minus_w_sin, B = self.coefficients(tau, switch_states, radius)
            F = np.zeros(np.shape(c) + (4, 4))
            F[..., 0, 0] = F[..., 1, 1] = F[..., 2, 2] = F[..., 3, 3] = c
            F[..., 0, 1] = F[..., 2, 3] = sin_over_w
            F[..., 1, 0] = F[..., 3, 2] = minus_w_sin
            return F, B, self.noise_gain(tau)

    def within_arithmetic(self, tau: float, switch_states: np.ndarray, radius: float | None = None) -> bool:
        """Whether the transitions of a step of ``tau`` seconds at ``switch_states`` stay within the filters' float64 arithmetic."""
        F, B, G = self.arrays(tau, switch_states, radius)
        with np.errstate(over="ignore", invalid="ignore"):
            return transition_excess(F, B, G @ self.noise_cov @ G.T) is None

    def check_arithmetic(self, tau: float, switch_states: np.ndarray, F, B, G) -> None:
        """A ValueError naming ``radius`` or ``tau`` and its usable range when the transition (F, B, G) built at
        ``switch_states`` exceeds the filters' float64 arithmetic: ``radius`` when a wider turn (a smaller ω =
        |v|/r) would fit, else ``tau``."""

        def why(excess: str) -> str:
            rows = np.reshape(switch_states, (-1, 4))
            worst = rows[int(np.argmax(np.hypot(rows[:, 1], rows[:, 3])))]  # the fastest switch state: the largest ω
            if self.within_arithmetic(tau, worst, 1e300):  # a wide enough turn fits: the radius is the cause
                speed = float(np.hypot(worst[1], worst[3]))
                bound = speed / TRANSITION_MAGNITUDE_LIMIT  # ω ≤ 1e75 bounds |ω sin ωτ| in F (and B ≤ ω |x| ≤ 1e225)
                return (
                    f"radius: a turn of radius {self.radius!r} m at the switch speed {speed:.3g} m/s (ω = |v|/r = "
                    f"{speed / self.radius:.3g} rad/s) gives the {self.name!r} transition {excess}, beyond the float64 arithmetic"
                    f" of the filters (the prediction F P Fᵀ overflows); expected radius ≥ |v|/{TRANSITION_MAGNITUDE_LIMIT:.0e} = {bound:.3g} m"
                    " at this speed (ω ≤ 1e75 rad/s)"
                )
            return _tau_message(self.name, tau, excess, lambda t: self.within_arithmetic(t, worst))

        _checked(F, B, G, self.noise_cov, why)

    def transition(self, tau: float, switch_state: np.ndarray) -> LinearTransition:
        """F, B, G, Q of a step of ``tau`` seconds turning about the centre fixed at ``switch_state``; a ValueError
        names ``radius`` or ``tau`` (and the usable range) when they would exceed the filters' float64 arithmetic."""
        tau, switch_state = _check_tau(tau), as_float_array(switch_state, "switch_state", (4,))
        F, B, G = self.arrays(tau, switch_state)
        self.check_arithmetic(tau, switch_state, F, B, G)
        return LinearTransition(F, B, G, self.noise_cov)

    def transition_bank(self, tau, switch_states: np.ndarray) -> TransitionBank:
        """:meth:`transition` at S switch states at once over ``tau`` (one or (S,)): the same formulas, vectorized
        over the rows (a row beyond the float64 arithmetic is :meth:`transition`'s ValueError)."""
        switch_states = as_float_array(switch_states, "switch_states", (None, 4))
        steps = step_lengths(tau, switch_states.shape[0])
        F, B, G = self.arrays(steps, switch_states)
        if np.ndim(tau) == 0:
            self.check_arithmetic(float(steps[0]), switch_states, F, B, G[0])
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                if transition_excess(F, B, G @ self.noise_cov @ np.swapaxes(G, -1, -2)) is not None:
                    for t, x in zip(steps, switch_states):
                        self.transition(float(t), x)
        return transition_stack(F, B, G, self.noise_cov)


@attrs.frozen
class LeftTurn(_Turn):
    """Left (counter-clockwise) uniform turn of radius ``radius`` metres (seed 000, mode 2)."""

    name: ClassVar[str] = "left_turn"
    direction: ClassVar[int] = 1


@attrs.frozen
class RightTurn(_Turn):
    """Right (clockwise) uniform turn of radius ``radius`` metres (seed 000, mode 3)."""

    name: ClassVar[str] = "right_turn"
    direction: ClassVar[int] = -1


@hookimpl
def register_motion_models(registry):
    for model in (Straight, LeftTurn, RightTurn, ConstantAcceleration, Stop):
        registry.add(model.name, model)
