"""Motion modes for recorded motion: the turn rate or the along-track acceleration in the state, noise per second.

**Coordinated turn** ``coordinated_turn``, state (x, vx, y, vy, ω) (Bar-Shalom,
Li & Kirubarajan 2001, §11.7.1; Li & Jilkov 2003, §4.2.2): with a = ω̄ Δt,
ω̄ = clip(ω, −ω_max, ω_max),

    x⁺ = x + Δt (vx s₁(a) − vy c₁(a))     vx⁺ = vx cos a − vy sin a
    y⁺ = y + Δt (vx c₁(a) + vy s₁(a))     vy⁺ = vx sin a + vy cos a      ω⁺ = ω̄

s₁ = sin a / a, c₁ = (1 − cos a)/a: the ship turn of seed 003
(:mod:`.ship`, whose f and Jacobian this reuses with the components
reordered), smooth through ω = 0 (straight motion).  ω_max (``max_rate``, rad/s)
is the physical limit of the vehicle: the prediction holds ω inside it, so an
EKF with reports 10 s apart cannot run away to a turn no ship or aircraft
makes (∂ω⁺/∂ω = 0 where the limit holds).  The direction of the turn is the sign
of ω (positive: left, counter-clockwise).

**Speed change** ``speed_change``, state (x, vx, y, vy, a_along): the speed
changes at a_along (m/s²) along the current heading u = v/|v|,

    p⁺ = p + v Δt + a_along u Δt²/2     v⁺ = v + a_along u Δt     a_along⁺ = a_along

(u = 0 at zero speed: a stopped object has no heading to accelerate along).

Noise per second (:mod:`hybridtrack.sdk.process_noise`): white acceleration
of density q (``noise_density``, m²/s³, as for the linear modes) on each axis, Q_axis(Δt) =
q [[Δt³/3, Δt²/2], [Δt²/2, Δt]], and a random walk of the extra component,
``rate_density`` (rad²/s³: var ω grows by q_ω Δt) or ``jerk_density``
((m/s²)²/s).  Written G(Δt) w, w ~ N(0, diag(q, q, q, q, q_extra)), G(Δt) the
Cholesky factor of the unit-density blocks.
"""

from __future__ import annotations

import functools
import importlib.util
from abc import abstractmethod
from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import LinearTransition, MotionModel, TransitionBank
from hybridtrack.core.validation import as_float_array, check_positive
from hybridtrack.sdk.process_noise import check_density, white_noise_root
from hybridtrack_plugins.motion.linear_modes import step_lengths
from hybridtrack_plugins.motion.ship import ShipTurn

#: numba is installed: the coordinated turn's bank is compiled (:mod:`._turn_kernel`, imported on first use)
NUMBA_AVAILABLE = importlib.util.find_spec("numba") is not None
#: (x, vx, y, vy, ω) ↔ the ship turn's (x, y, vx, vy, ω): the same permutation both ways
_SHIP_ORDER = np.array([0, 2, 1, 3, 4])


@functools.cache
def _turn_kernel():
    """:mod:`._turn_kernel`, imported (and numba with it) on first use."""
    from hybridtrack_plugins.motion import _turn_kernel as kernel

    return kernel


@attrs.frozen
class _FiveStateMode(MotionModel):
    """A nonlinear 5-state mode (x, vx, y, vy, extra) with the noise of the module docstring."""

    noise_density: float = attrs.field(default=0.01, converter=lambda v: check_density(v, "noise_density", "m²/s³"))

    linear: ClassVar[bool] = False
    extra_density: ClassVar[str] = ""

    @property
    def noise_cov(self) -> np.ndarray:
        """diag(q, q, q, q, q_extra): the covariance of w in G(Δt) w."""
        q = self.noise_density
        return np.diag([q, q, q, q, getattr(self, self.extra_density)])

    @staticmethod
    def noise_gain(tau) -> np.ndarray:
        """G(Δt) (5, 5): blockdiag(G_axis, G_axis, √Δt) in the layout's order; (S, 5, 5) for Δt (S,)."""
        axis = white_noise_root(tau, 2)
        G = np.zeros(np.shape(tau) + (5, 5))
        G[..., :2, :2] = G[..., 2:4, 2:4] = axis
        G[..., 4, 4] = np.sqrt(tau)
        return G

    @abstractmethod
    def f(self, x: np.ndarray, tau: float) -> np.ndarray:
        """The noise-free step f(x) for x of shape (..., 5)."""

    @abstractmethod
    def jacobian(self, x: np.ndarray, tau: float) -> np.ndarray:
        """∂f/∂x at x (..., 5) → (..., 5, 5)."""

    def propagate(self, x: np.ndarray, tau: float, switch_state: np.ndarray | None = None) -> np.ndarray:
        """The exact nonlinear step f(x) (the switch state plays no role)."""
        return self.f(x, check_positive(tau, "tau", "the step length in seconds"))

    def linearize(self, tau, x: np.ndarray) -> TransitionBank:
        """The bank linearized at every row of x (M, 5) over ``tau`` (one step or (M,), one per row):
        F_m = ∂f/∂x(x_m), B_m = f(x_m) − F_m x_m, Q_m = G(Δt_m) Q_w G(Δt_m)ᵀ."""
        x = as_float_array(x, "x", (None, 5))
        M = x.shape[0]
        if np.ndim(tau) == 0:
            tau = check_positive(tau, "tau", "the step length in seconds")
            root = self.noise_gain(tau) * np.sqrt(np.diag(self.noise_cov))
            Q, root = np.broadcast_to(root @ root.T, (M, 5, 5)), np.broadcast_to(root, (M, 5, 5))
        else:
            tau = step_lengths(tau, M)
            root = self.noise_gain(tau) * np.sqrt(np.diag(self.noise_cov))
            Q = root @ np.swapaxes(root, -1, -2)
        F = self.jacobian(x, tau)
        return TransitionBank(F, self.f(x, tau) - np.einsum("mij,mj->mi", F, x), Q, root)

    def transition_bank(self, tau, switch_states: np.ndarray) -> TransitionBank:
        """:meth:`transition` at each row of ``switch_states`` (S, 5) over ``tau`` (one or (S,)): :meth:`linearize`."""
        return self.linearize(tau, switch_states)

    def transition(self, tau: float, switch_state: np.ndarray) -> LinearTransition:
        """The linearization at ``switch_state``: F = ∂f/∂x, B = f(x_s) − F x_s, G = G(Δt), Q = ``noise_cov``."""
        tau = check_positive(tau, "tau", "the step length in seconds")
        xs = as_float_array(switch_state, "switch_state", (5,))
        F = self.jacobian(xs, tau)
        return LinearTransition(F, self.f(xs, tau) - F @ xs, self.noise_gain(tau), self.noise_cov)

    def linearizer(self, tau: float):
        """``lambda x: self.linearize(tau, x)``: what ``ekf.predict`` takes to relinearize at each step."""
        return lambda x: self.linearize(tau, x)


@attrs.frozen
class CoordinatedTurn(_FiveStateMode):
    """Coordinated turn with the turn rate ω in the state, bounded by ``max_rate`` (module docstring)."""

    rate_density: float = attrs.field(default=1e-6, converter=lambda v: check_density(v, "rate_density", "rad²/s³"))
    max_rate: float = attrs.field(
        default=0.2, converter=float, validator=lambda i, a, v: check_positive(v, "max_rate", "the largest turn rate in rad/s")
    )

    name: ClassVar[str] = "coordinated_turn"
    layout: ClassVar[tuple[str, ...]] = ("x", "vx", "y", "vy", "omega")
    extra_density: ClassVar[str] = "rate_density"

    def _bounded(self, x: np.ndarray) -> np.ndarray:
        """x in the ship turn's order with ω clipped to ±ω_max."""
        ship = np.asarray(x, dtype=float)[..., _SHIP_ORDER]
        ship[..., 4] = np.clip(ship[..., 4], -self.max_rate, self.max_rate)
        return ship

    def f(self, x: np.ndarray, tau: float) -> np.ndarray:
        return ShipTurn.f(self._bounded(x), tau)[..., _SHIP_ORDER]

    def jacobian(self, x: np.ndarray, tau: float) -> np.ndarray:
        J = ShipTurn.jacobian(self._bounded(x), tau)[..., _SHIP_ORDER, :][..., _SHIP_ORDER]
        inside = np.abs(np.asarray(x, dtype=float)[..., 4]) < self.max_rate
        J[..., :, 4] *= inside[..., None]  # ω̄ = clip(ω): no derivative where the limit holds
        return J

    def linearize(self, tau, x: np.ndarray) -> TransitionBank:
        """:meth:`_FiveStateMode.linearize`, row by row in compiled code (:mod:`._turn_kernel`) when numba is installed
        (the same formulas, to rounding); the numpy path without numba, and wherever the compiled one meets a
        value that is not finite (the numpy path then raises its error)."""
        if not NUMBA_AVAILABLE or type(x) is not np.ndarray or x.ndim != 2 or x.shape[1] != 5 or x.dtype != np.float64:
            return super().linearize(tau, x)
        M = x.shape[0]
        steps = np.full(M, check_positive(tau, "tau", "the step length in seconds")) if np.ndim(tau) == 0 else step_lengths(tau, M)
        q_root = self.__dict__.get("_noise_root")  # √(q, q, q, q, q_ω), kept on the instance (attrs frozen: through __dict__)
        if q_root is None:
            q_root = self.__dict__["_noise_root"] = np.sqrt(np.array([self.noise_density] * 4 + [self.rate_density]))
        out = _turn_kernel().linearized_bank(x, steps, self.max_rate, q_root)
        return super().linearize(tau, x) if out is None else TransitionBank(*out)


@attrs.frozen
class SpeedChange(_FiveStateMode):
    """Speed changing at an along-track acceleration in the state (module docstring)."""

    jerk_density: float = attrs.field(default=1e-4, converter=lambda v: check_density(v, "jerk_density", "(m/s²)²/s"))

    name: ClassVar[str] = "speed_change"
    layout: ClassVar[tuple[str, ...]] = ("x", "vx", "y", "vy", "a_along")
    extra_density: ClassVar[str] = "jerk_density"

    @staticmethod
    def _heading(vx, vy):
        """u = v/|v| (0 at zero speed) and |v|."""
        speed = np.hypot(vx, vy)
        safe = np.where(speed > 0, speed, 1.0)
        return np.where(speed > 0, vx / safe, 0.0), np.where(speed > 0, vy / safe, 0.0), speed

    def f(self, x: np.ndarray, tau: float) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        px, vx, py, vy, a = np.moveaxis(x, -1, 0)
        ux, uy, _ = self._heading(vx, vy)
        return np.stack(
            [px + vx * tau + a * ux * tau * tau / 2, vx + a * ux * tau, py + vy * tau + a * uy * tau * tau / 2, vy + a * uy * tau, a],
            axis=-1,
        )

    def jacobian(self, x: np.ndarray, tau: float) -> np.ndarray:
        """∂f/∂x: the heading's derivative ∂u/∂v = (I − u uᵀ)/|v| (0 at zero speed)."""
        x = np.asarray(x, dtype=float)
        _, vx, _, vy, a = np.moveaxis(x, -1, 0)
        ux, uy, speed = self._heading(vx, vy)
        inverse = np.where(speed > 0, 1.0 / np.where(speed > 0, speed, 1.0), 0.0)
        du = np.stack([np.stack([1 - ux * ux, -ux * uy], -1), np.stack([-ux * uy, 1 - uy * uy], -1)], -2) * inverse[..., None, None]
        J = np.zeros(x.shape[:-1] + (5, 5))
        J[..., 0, 0] = J[..., 1, 1] = J[..., 2, 2] = J[..., 3, 3] = J[..., 4, 4] = 1.0
        J[..., 0, 1] = J[..., 2, 3] = tau
        velocity = (1, 3)
        for row, (position, speed_row) in enumerate(((0, 1), (2, 3))):
            for col in range(2):
                J[..., position, velocity[col]] += a * tau * tau / 2 * du[..., row, col]
                J[..., speed_row, velocity[col]] += a * tau * du[..., row, col]
        J[..., 0, 4], J[..., 1, 4] = ux * tau * tau / 2, ux * tau
        J[..., 2, 4], J[..., 3, 4] = uy * tau * tau / 2, uy * tau
        return J


@hookimpl
def register_motion_models(registry):
    for model in (CoordinatedTurn, SpeedChange):
        registry.add(model.name, model)
