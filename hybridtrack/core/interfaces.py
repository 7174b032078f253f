"""The five interfaces of hybridtrack: MotionModel, Sensor, Estimator, Detector, Solver, and the values they return.

Conventions (symbols in ``docs/notation.md``):

* A state is a float64 vector whose components are named by the model's
  ``layout`` (``("x", "vx", "y", "vy")`` for the 4-state modes,
  ``("x", "vx", "ax", "y", "vy", "ay")`` for constant acceleration).  Units:
  metres, seconds, radians.
* Everything that runs inside a bank of filters works on stacked arrays: a mean
  of shape ``(M, n)``, a covariance ``(M, n, n)``; a single filter is ``M = 1``.
* One step of a motion model is x_k = F x_{k-1} + B u + G w_{k-1}, u ≡ 1,
  w ~ N(0, Q) (SPEC §1, seed 000 eq. 1); a sensor is z = h(x) + v, v ~ N(0, R),
  with h(x) = H x for a linear sensor (SPEC §2).

The protocols the algorithms call on top of these (score detectors, the
hypothesis tests of the adaptive estimators, clutter associations) are in
:mod:`hybridtrack.core.protocols`.  Every implementation is checked by
:mod:`hybridtrack.testing` (also a pytest plugin; the optional ``example_*``
attributes that let the checks build a component are listed in
``docs/plugins.md``).
"""

from __future__ import annotations

import contextlib
import copy
import functools
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import attrs
import numpy as np

from hybridtrack.core.components import Labelled
from hybridtrack.core.validation import readonly_array_field

# --------------------------------------------------------------------------- motion


@attrs.frozen
class LinearTransition:
    """One step x_k = F x_{k-1} + B + G w, w ~ N(0, Q) (B already multiplied by u ≡ 1).

    Shapes: F (n, n), B (n,), G (n, q), Q (q, q) symmetric PSD.
    """

    F: np.ndarray = readonly_array_field((None, None))
    B: np.ndarray = readonly_array_field((None,))
    G: np.ndarray = readonly_array_field((None, None))
    Q: np.ndarray = readonly_array_field(covariance=True)

    def __attrs_post_init__(self):
        if self.Q.ndim != 2:
            raise ValueError(f"Q: expected shape (q, q), got {self.Q.shape}")
        n, q = self.F.shape[0], self.Q.shape[0]
        for name, shape in (("F", (n, n)), ("B", (n,)), ("G", (n, q))):
            if getattr(self, name).shape != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {getattr(self, name).shape}")

    @property
    def process_noise(self) -> np.ndarray:
        """G Q Gᵀ, the covariance the noise adds to the state, shape (n, n)."""
        return self.G @ self.Q @ self.G.T

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Noise-free step F x + B for x of shape (..., n)."""
        return x @ self.F.T + self.B


class MotionModel(ABC):
    """A motion mode: the transition of one step of length ``tau`` seconds.

    Contract:

    * ``name`` is the registry name (class attribute), ``layout`` the state
      component names, ``noise_cov`` Q of shape (q, q).
    * ``transition(tau, switch_state)`` returns a :class:`LinearTransition`.
      ``switch_state`` (shape (n,), this model's layout) is the state at the
      switching moment s; models whose F or B depend on it (a turn fixes ω and
      the turn centre there, SPEC §1) read it, the others ignore it.  A
      nonlinear model returns its linearization at ``switch_state``
      (F = ∂f/∂x, B = f(x_s) − F x_s), so that F x_s + B = f(x_s).
    * ``propagate(x, tau, switch_state)`` is the noise-free step for x of shape
      (..., n); it equals ``transition(...).apply(x)`` for a linear model.
    * ``enter(state, layout)`` converts a state of another mode's layout into
      this one when the trajectory switches to this mode (components matched by
      name; missing ones are set to zero unless the model says otherwise).

    Checked by :func:`hybridtrack.testing.check_motion_model`; a factory
    with required arguments defines ``example_parameters`` (``docs/plugins.md``).
    """

    name: ClassVar[str]
    layout: ClassVar[tuple[str, ...]]
    linear: ClassVar[bool] = True
    #: the turn radius of a turn mode (labels, reports); None for the others
    radius: float | None = None

    noise_cov: np.ndarray

    @property
    def state_dim(self) -> int:
        return len(self.layout)

    @abstractmethod
    def transition(self, tau: float, switch_state: np.ndarray) -> LinearTransition:
        """F, B, G, Q of one step of length ``tau`` (see the class contract)."""

    def transition_bank(self, tau, switch_states: np.ndarray) -> TransitionBank:
        """The transitions at the switch states (S, n) over ``tau`` (one for all, or (S,): one per row), stacked.

        Optional (batched runs): the default stacks ``transition(tau_i, x_i)``; a model may vectorize it, with
        entries equal to the default's (``check_motion_model`` checks)."""
        states = np.asarray(switch_states, dtype=float)
        steps = np.broadcast_to(np.asarray(tau, dtype=float), states.shape[:1])
        return TransitionBank.stack([self.transition(float(t), x) for t, x in zip(steps, states)])

    def propagate(self, x: np.ndarray, tau: float, switch_state: np.ndarray) -> np.ndarray:
        """Noise-free step of x (..., n)."""
        return self.transition(tau, switch_state).apply(x)

    def enter(self, state: np.ndarray, layout: Sequence[str], parameters: dict | None = None) -> np.ndarray:
        """Convert ``state`` given in ``layout`` to this model's layout (by component name).

        ``parameters`` holds segment extras (e.g. ``acceleration``) a model may use.
        """
        return convert_layout(state, layout, self.layout)


def convert_layout(state: np.ndarray, source: Sequence[str], target: Sequence[str], fill: dict | None = None) -> np.ndarray:
    """Copy components of ``state`` (…, len(source)) into a new (…, len(target)) array by name.

    Components of ``target`` missing from ``source`` take ``fill[name]`` or 0.
    """
    state = np.asarray(state, dtype=float)
    fill = fill or {}
    out = np.zeros(state.shape[:-1] + (len(target),))
    index = {name: i for i, name in enumerate(source)}
    for j, name in enumerate(target):
        out[..., j] = state[..., index[name]] if name in index else fill.get(name, 0.0)
    return out


# --------------------------------------------------------------------------- sensors


class Sensor(ABC):
    """A sensor node: z = h(x) + v, v ~ N(0, R) (SPEC §2).

    Contract:

    * ``name`` is the node id (unique within a network), ``registry_name`` the registry
      name (class attribute), ``measurement_dim`` m, ``noise_cov`` R (m, m)
      symmetric positive definite.
    * ``measure(x, layout)`` is h(x) for x of shape (..., n) → (..., m);
      ``jacobian(x, layout)`` is ∂h/∂x at x → (..., m, n) (for a linear sensor
      the constant H broadcast to x's leading shape).
    * ``residual(z, z_pred)`` is the innovation ν = z − h(x) (angles wrapped to
      (−π, π] by sensors that measure angles).
    * ``simulate(x, layout, rng)`` draws z = h(x) + v for x of shape (..., n).
    * ``measurement_noise(z)`` is the R that goes with the measurement z
      (``noise_cov`` unless the sensor's R depends on z, e.g. radar
      pseudo-measurements).
    * ``noise_depends_on_state`` (default False) and ``state_noise(x, layout)``:
      the part of R that depends on the measured object's state, at x (M, n) →
      (M, m, m), added to ``measurement_noise(z)``; estimators evaluate it at
      each filter's predicted state (e.g. a time-stamp jitter δt ~ N(0, σ_t²)
      moves a position fix by v δt: σ_t² v vᵀ along the track).

    Checked by :func:`hybridtrack.testing.check_sensor` on states of
    ``example_layout`` (default ``("x", "vx", "y", "vy")``).
    """

    registry_name: ClassVar[str]
    linear: ClassVar[bool] = True
    #: the state components z measures directly (z = those components + v), e.g. ("x", "y");
    #: None for other sensors.  Recordings draw a sensor measuring ("x", "y") as points in the world view.
    components: tuple[str, ...] | None = None

    name: str
    noise_cov: np.ndarray

    @property
    def measurement_dim(self) -> int:
        return self.noise_cov.shape[0]

    @abstractmethod
    def measure(self, x: np.ndarray, layout: Sequence[str]) -> np.ndarray:
        """h(x): (..., n) → (..., m)."""

    @abstractmethod
    def jacobian(self, x: np.ndarray, layout: Sequence[str]) -> np.ndarray:
        """∂h/∂x: (..., n) → (..., m, n)."""

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        """ν = z − ẑ (override to wrap angles)."""
        return z - z_pred

    def measurement_noise(self, z: np.ndarray) -> np.ndarray:
        """R to use with the measurement z ((m,) → (m, m), or (..., m) → (..., m, m)); estimators take R from here.

        ``noise_cov``; sensors whose R depends on z (radar converted to Cartesian coordinates) override it.
        """
        return self.noise_cov

    @property
    def noise_depends_on_state(self) -> bool:
        """True when :meth:`state_noise` adds to R (the update then evaluates it at each filter's state)."""
        return False

    def state_noise(self, x: np.ndarray, layout: Sequence[str]) -> np.ndarray:
        """The state-dependent part of R at x (M, n) → (M, m, m) (zero unless ``noise_depends_on_state``)."""
        return np.zeros(np.shape(x)[:-1] + self.noise_cov.shape)

    def simulate(self, x: np.ndarray, layout: Sequence[str], rng: np.random.Generator) -> np.ndarray:
        """z = h(x) + v, v ~ N(0, R), for x of shape (..., n)."""
        z = self.measure(x, layout)
        L = np.linalg.cholesky(self.noise_cov)
        return z + rng.standard_normal(z.shape) @ L.T


# --------------------------------------------------------------------------- estimators


@attrs.frozen(eq=False)
class Innovation:
    """What one measurement update of a bank of M filters exposes (SPEC §3–4).

    nu (M, m) innovation ν = z − h(x⁻); S (M, m, m) its covariance H P⁻ Hᵀ + R;
    loglik (M,) ℓ = −½(m ln 2π + ln det S + νᵀS⁻¹ν) (a ``sampling`` estimator
    gives its own estimate of ln p(z_k | z_1:k−1) instead); nis (M,) νᵀS⁻¹ν.
    ``m == 0`` (no measurement at this step) gives empty ν, S and ℓ = nis = 0.
    """

    nu: np.ndarray
    S: np.ndarray
    loglik: np.ndarray
    nis: np.ndarray

    @property
    def measurement_dim(self) -> int:
        return self.nu.shape[-1]

    def take(self, rows: np.ndarray, bank_size: int) -> Innovation:
        """The innovation of the filters ``rows`` of this bank of ``bank_size`` filters, of the same class: every
        array field with ``bank_size`` entries on its first axis is indexed by ``rows`` (ν, S, ℓ, NIS and the
        extras of subclasses, e.g. a particle filter's effective sample sizes), the other fields are kept."""
        changes = {}
        for field in attrs.fields(type(self)):
            value = getattr(self, field.name)
            if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == bank_size:
                changes[field.name] = value[rows]
        return attrs.evolve(self, **changes)


@attrs.frozen(eq=False)
class TransitionBank:
    """Stacked transitions of M filters: F (M, n, n), B (M, n), Q (M, n, n) = G Q Gᵀ.

    ``noise_root`` (optional, (M, n, r)) is a factor W with W Wᵀ = Q, e.g.
    G chol(Q_w); square-root filters use it instead of factoring the singular
    G Q Gᵀ.  ``stack`` fills it when every Q_w is positive definite and all have
    the same size, otherwise leaves it ``None``.
    """

    F: np.ndarray
    B: np.ndarray
    Q: np.ndarray
    noise_root: np.ndarray | None = None

    @classmethod
    def stack(cls, transitions: Sequence[LinearTransition]) -> TransitionBank:
        root = None
        if len({t.Q.shape for t in transitions}) == 1:
            with contextlib.suppress(np.linalg.LinAlgError):
                root = np.stack([t.G @ np.linalg.cholesky(t.Q) for t in transitions])
        return cls(
            np.stack([t.F for t in transitions]),
            np.stack([t.B for t in transitions]),
            np.stack([t.process_noise for t in transitions]),
            root,
        )


#: What ``Estimator.predict`` takes: a bank of transitions, or (estimators with
#: ``accepts_nonlinear``) a callable linearizing the motion at the current
#: means x (M, n): F = ∂f/∂x(x), B = f(x) − F x, so that F x + B = f(x).
Transitions = TransitionBank | Callable[[np.ndarray], TransitionBank]


class Estimator(Labelled, ABC):
    """A bank of M Kalman-type filters run on the same measurements.

    Contract (shapes with M filters, n states, m measured components):

    * ``initialize(mean (M, n), cov (M, n, n))`` → an estimator-specific state
      object (covariance, information or factor form).
    * ``predict(state, transitions)`` → the predicted state; ``transitions`` is
      a :class:`TransitionBank` or, for ``accepts_nonlinear`` estimators, a
      linearizing callable (:data:`Transitions`).
    * ``update(state, z, sensors, layout)`` → ``(state, Innovation)``: ``z`` is
      the stacked measurement of ``sensors`` (shape (Σ m_i,), or (M, Σ m_i) with
      one row per filter).  A NaN component means that component was not
      measured at this step: the update uses the remaining components of that
      sensor (rows of H, the matching block of R); all NaN means prediction
      only (the state is returned unchanged, ``m == 0``).  Estimators with
      ``accepts_scans`` also take, as ``z``, a sequence of
      :class:`~hybridtrack.sdk.scans.Scan` (candidate measurements in clutter,
      one scan per sensor) and return a :class:`ClutterInnovation`.
    * ``mean(state)`` (M, n) and ``covariance(state)`` (M, n, n) read the state
      back in covariance form whatever the internal form.
    * Bank operations, so that a bank keeps its own form between steps
      (square-root factors, per-node states) while it grows and shrinks:
      ``take(state, rows)`` keeps the filters ``rows`` (in that order, repeats
      allowed: a repeated row is a copy of that filter); ``concatenate(states)``
      joins banks of this estimator into one.  Neither goes through (x, P).
    * ``node_scores(state)``: for decentralized estimators, (ℓ, NIS) each of
      the N nodes computed locally for every filter, shape (N, M) each (seed
      000 eq. 22); ``None`` (the default) for a centralized estimator.
    * Bad input (NaN/inf in the prior, wrong shapes) raises ``ValueError``
      naming the argument and the expected shape.

    Capabilities (class attributes with defaults): ``exact_kalman`` (True: the
    estimator computes the Kalman filter exactly, in any algebraic form);
    ``accepts_nonlinear`` (False: linear sensors and a TransitionBank only;
    True: relinearizes, takes nonlinear sensors and a linearizing callable);
    ``accepts_scans`` (False: ``z`` is an array; True: also candidate scans);
    ``sampling`` (False; True: a particle filter: ℓ is its own estimate of
    ln p(z_k | z_1:k−1), and every draw of a filter comes from a stream carried
    in its own state, so a step of a filter depends on that filter's state only).

    Checked by :func:`hybridtrack.testing.check_estimator` (against the
    covariance-form KF unless the class sets ``exact_kalman = False``).
    :class:`hybridtrack.sdk.estimation.BankEstimator` is a base class with the
    input checks, measurement assembly and bank operations already written.
    """

    name: ClassVar[str]
    exact_kalman: ClassVar[bool] = True
    accepts_nonlinear: ClassVar[bool] = False
    accepts_scans: ClassVar[bool] = False
    sampling: ClassVar[bool] = False

    @abstractmethod
    def initialize(self, mean: np.ndarray, cov: np.ndarray) -> Any: ...

    @abstractmethod
    def predict(self, state: Any, transitions: Transitions) -> Any: ...

    @abstractmethod
    def update(
        self, state: Any, z: np.ndarray | Sequence[Any], sensors: Sequence[Sensor], layout: Sequence[str]
    ) -> tuple[Any, Innovation]: ...

    @abstractmethod
    def mean(self, state: Any) -> np.ndarray: ...

    @abstractmethod
    def covariance(self, state: Any) -> np.ndarray: ...

    @abstractmethod
    def take(self, state: Any, rows: Sequence[int]) -> Any:
        """The bank of the filters ``rows`` of ``state`` (in that order; a repeated row copies that filter)."""

    @abstractmethod
    def concatenate(self, states: Sequence[Any]) -> Any:
        """One bank holding the filters of ``states`` in order."""

    def node_scores(self, state: Any) -> tuple[np.ndarray, np.ndarray] | None:
        """(ℓ, NIS) computed at each node, (N, M) each, after an update; None for a centralized estimator."""
        return None

    #: True when :meth:`record_states` logs something: a pipeline with a recorder then keeps the states of the
    #: steps not yet recorded (at most ``hybridtrack.engine.pipeline.STATE_CHUNK``) and hands them over
    records_states: ClassVar[bool] = False

    def record_states(self, recorder, names: Sequence[str], steps: np.ndarray, states: Sequence[Any], layout, times=None) -> None:
        """Log what the states hold beyond mean and covariance (particle clouds, mixture components, hypotheses).

        Optional (set ``records_states = True`` when overriding): ``states`` one bank state per step of
        ``steps`` (K,), ``names`` the M filter names, ``times`` (K,) seconds or None.  The pipeline logs
        every estimator's means, covariances and scores itself.
        """


# --------------------------------------------------------------------------- detectors


@attrs.frozen(eq=False)
class DetectorStep:
    """A detector's output at one step.

    ``statistics`` maps a series name to its value(s) this step (a float or an
    array over hypotheses); ``thresholds`` maps a name to the current threshold;
    ``decision`` is set on the step a decision is taken.
    """

    statistics: dict[str, Any]
    thresholds: dict[str, float] = attrs.field(factory=dict)
    decision: Any = None


class DetectorBatch:
    """R independent copies of one :class:`Detector` fed together.

    ``step(step, runs, innovation)`` feeds the runs ``runs`` (U indices into
    0 … R−1) the innovation of their stacked banks (U·M rows, row u·M + j is
    filter j of run ``runs[u]``) and returns one :class:`DetectorStep` per run,
    each equal to ``copies[r].step(step, <the rows of run r>)``.  This default
    steps deep copies (``copies``, made on first use, also for a vectorized
    batch that keeps its state otherwise) one by one.
    """

    def __init__(self, detector: Detector, runs: int):
        self.detector = detector
        self.runs = int(runs)

    @functools.cached_property
    def copies(self) -> list[Detector]:
        return [copy.deepcopy(self.detector) for _ in range(self.runs)]

    def step(self, step: int, runs: Sequence[int], innovation: Innovation) -> list[DetectorStep]:
        size = np.shape(innovation.loglik)[0]
        M = size // len(runs)
        if len(runs) == 1:
            return [self.copies[int(runs[0])].step(step, innovation)]
        return [self.copies[int(r)].step(step, innovation.take(np.arange(u * M, (u + 1) * M), size)) for u, r in enumerate(runs)]


class Detector(Labelled, ABC):
    """A sequential change detector fed one step at a time.

    Contract: ``reset()`` forgets the past; ``step(step, innovation)`` consumes
    the :class:`Innovation` of the bank it watches at that step and returns a
    :class:`DetectorStep`; ``name`` is the registry name, ``label`` the
    instance's name in a run.  Detectors are deterministic given their input.

    Checked by :func:`hybridtrack.testing.check_detector`, fed
    ``example_innovations(rng)`` when the detector defines it.
    """

    name: ClassVar[str]
    #: the registered algorithm (kind ``algorithm``) whose bank management this detector needs, e.g.
    #: ``"unknown_change"`` for a change-time test, whose hypotheses are filters started at every possible change
    #: time; a :class:`~hybridtrack.engine.pipeline.Pipeline` (a fixed bank) refuses such a detector, naming the
    #: algorithm.  None (the default): the detector runs on any bank.
    requires_bank_management: ClassVar[str | None] = None

    @abstractmethod
    def reset(self) -> None: ...

    @abstractmethod
    def step(self, step: int, innovation: Innovation) -> DetectorStep: ...

    #: what :meth:`batch` builds by default (the protocols of :mod:`hybridtrack.core.protocols` set their own)
    batch_class: ClassVar[type[DetectorBatch]] = DetectorBatch

    def batch(self, runs: int) -> DetectorBatch:
        """``runs`` independent copies of this detector fed together (Monte Carlo runs stacked in one bank).

        The one batching protocol (its specialisations and callers: ``docs/plugins.md`` §1).  Optional: the
        default, ``batch_class(self, runs)``, steps deep copies one by one; a class may return a vectorized batch
        whose outputs equal the copies'.
        """
        return self.batch_class(self, runs)


# --------------------------------------------------------------------------- solvers


@attrs.frozen(eq=False)
class Solution:
    """A batch solver's answer: parameters θ (p,), their covariance (p, p), and diagnostics."""

    parameters: np.ndarray
    covariance: np.ndarray
    cost: float
    iterations: int
    evaluations: int
    converged: bool
    message: str = ""


class Solver(ABC):
    """A batch problem solved at once (e.g. bearings-only target motion analysis).

    Contract: ``solve(problem)`` returns a :class:`Solution` (or a subclass with
    more fields); ``name`` is the registry name; an ill-posed problem (too few
    data, NaN, unobservable) raises ``ValueError`` or warns explicitly, never
    returns a silent wrong answer.

    Checked by :func:`hybridtrack.testing.check_solver` on
    ``example_problem()`` when the solver defines it.
    """

    name: ClassVar[str]

    @abstractmethod
    def solve(self, problem: Any) -> Solution: ...
