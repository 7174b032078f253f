"""The five interfaces of hybridtrack: MotionModel, Sensor, Estimator, Detector, Solver.

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

Every implementation is checked by :mod:`hybridtrack.testing` (also a pytest
plugin), which third-party plugins can run on their own components.

Contract-check conventions (optional attributes a component may define so that
the checks, and ``tests/contract``, can build and exercise it without help):

* ``example_parameters`` (any kind) on the registered factory: a dict of
  keyword arguments, or a classmethod/staticmethod returning one, used to build
  an example instance, e.g. ``example_parameters = {"radius": 5.0}``.  Without
  it the factory is called with no arguments, so a component whose parameters
  all have defaults needs nothing.
* ``example_layout`` (Sensor): the state layout the checks feed to
  ``measure``/``jacobian``; default ``("x", "vx", "y", "vy")``.
* ``example_innovations(rng)`` (Detector): a list of :class:`Innovation`, one
  per step, of the bank this detector expects; default: 20 steps of a bank of
  M = 3 filters with m = 2, drawn from ``rng``.
* ``exact_kalman`` (Estimator, default True): the estimator computes the Kalman
  filter exactly (in any algebraic form), so the checks compare it with the
  covariance form; an approximate one (e.g. PDA in clutter) sets it False.
* ``sampling`` (Estimator, default False): the estimator represents each
  filter by random samples (a particle filter): ℓ is its own estimate of
  ln p(z_k | z_1:k−1), not the Gaussian formula of (ν, S), and a filter
  re-initialized from its (x, P) draws new samples, so the checks compare
  only the filters that kept their state (each filter draws from its own
  stream, carried in its state).
* ``example_problem()`` (Solver): a problem ``solve`` accepts, small enough to
  solve in well under a second; without it the checks skip the solve.
"""

from __future__ import annotations

import copy
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import attrs
import numpy as np

from hybridtrack.core.validation import FILTER_MAGNITUDE_LIMIT, as_float_array, check_covariance, check_magnitude, readonly_array_field

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
    with required arguments defines ``example_parameters`` (module docstring).
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

    def transition_bank(self, tau: float, switch_states: np.ndarray) -> TransitionBank:
        """This mode's transitions at each of the switch states (S, n), stacked as a :class:`TransitionBank`.

        Optional (used by batched runs, where many runs switch at once): the
        default stacks ``transition(tau, x)`` for every row; a model may
        vectorize it, with entries equal to the default's (the motion tests check).
        """
        return TransitionBank.stack([self.transition(tau, x) for x in np.asarray(switch_states, dtype=float)])

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
        """R to use with the measurement z ((m,) → (m, m), or (..., m) → (..., m, m)).

        ``noise_cov`` for ordinary sensors; pseudo-measurement sensors whose R
        depends on the measurement (radar converted to Cartesian coordinates)
        override it.  Estimators take R from here.
        """
        return self.noise_cov

    def simulate(self, x: np.ndarray, layout: Sequence[str], rng: np.random.Generator) -> np.ndarray:
        """z = h(x) + v, v ~ N(0, R), for x of shape (..., n)."""
        z = self.measure(x, layout)
        L = np.linalg.cholesky(self.noise_cov)
        return z + rng.standard_normal(z.shape) @ L.T


# --------------------------------------------------------------------------- labels


class Labelled:
    """An instance label, separate from the registry name.

    ``name`` (class attribute) is the registry name; ``label`` names this
    instance in a run (result keys, recorded entity paths) and defaults to
    ``name``, so two instances of one class with different parameters coexist
    (``("signal_function", {"window": 10}, "sf10")`` or ``det.label = "sf10"``).
    """

    name: ClassVar[str]

    @property
    def label(self) -> str:
        return self.__dict__.get("_label") or self.name

    @label.setter
    def label(self, value: str) -> None:
        if not isinstance(value, str) or not value.strip() or "/" in value:
            raise ValueError(f"label: expected a non-empty name without '/', got {value!r}")
        self.__dict__["_label"] = value


def require(component: Any, protocol: type, role: str) -> Any:
    """``component`` if it implements ``protocol`` (an ABC of this module), else a TypeError naming what is missing.

    ``role`` names the argument (e.g. ``"detector"``).  The message lists the
    protocol's methods and declared attributes the object lacks, so a plugin
    author learns from it what to implement.
    """
    if isinstance(component, protocol):
        return component
    wanted = sorted(getattr(protocol, "__abstractmethods__", ())) + list(getattr(protocol, "declared_attributes", ()))
    missing = [m for m in wanted if not hasattr(component, m)]
    what = f"; it lacks {', '.join(missing)}" if missing else ""
    raise TypeError(
        f"{role}: {type(component).__name__} does not implement hybridtrack.core.interfaces.{protocol.__name__}"
        f" (subclass it and implement {', '.join(wanted) or 'its methods'}){what}"
    )


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


@attrs.frozen(eq=False)
class Association:
    """What one clutter-aware update of a bank did with one sensor's scan (SPEC §6).

    ``candidates`` (L, m); ``predicted`` ẑ (M, m); ``S`` (M, m, m); ``gate`` γ;
    ``distances`` d² (M, L); ``gated`` (M, L) bool; ``weights`` β_i (M, L)
    (nearest neighbour: 1 for the chosen candidate); ``missed`` β_0 (M,)
    (nearest neighbour: 1 when nothing was gated); ``selected`` (M,) the chosen
    (NN) or most probable (PDA) candidate, −1 for none; ``loglik`` (M,)
    ln Λ (PDA) or the Gaussian ℓ of the chosen candidate (NN, NaN when none).
    """

    sensor: str
    candidates: np.ndarray
    predicted: np.ndarray
    S: np.ndarray
    gate: float
    distances: np.ndarray
    gated: np.ndarray
    weights: np.ndarray
    missed: np.ndarray
    selected: np.ndarray
    loglik: np.ndarray


@attrs.frozen(eq=False)
class ClutterInnovation(Innovation):
    """An :class:`Innovation` of a clutter-aware update plus its :class:`Association` per scan.

    ``nu`` is the innovation the update used: the combined ν = Σ β_i ν_i (PDA)
    or the chosen candidate's (NN; 0 for a filter with nothing gated); S, ℓ and
    NIS go with it as in every Innovation.  ``association_loglik`` (M,) sums
    ln Λ over the scans of the step (0 when no scan was processed).  The
    pipeline records gates and weights from ``associations``.
    """

    associations: tuple[Association, ...] = ()

    @property
    def association_loglik(self) -> np.ndarray:
        if not self.associations:
            return np.zeros(self.nu.shape[0])
        return np.sum([a.loglik for a in self.associations], axis=0)


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
            try:
                root = np.stack([t.G @ np.linalg.cholesky(t.Q) for t in transitions])
            except np.linalg.LinAlgError:
                root = None
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
    ``sampling`` (False; True: a particle filter, see the module docstring —
    every draw of a filter comes from a stream carried in its own state, so a
    step of a filter depends on that filter's state only).

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
    #: steps not yet streamed (at most ``STATE_CHUNK`` of them) and hands them over
    records_states: ClassVar[bool] = False

    def record_states(self, recorder, names: Sequence[str], steps: np.ndarray, states: Sequence[Any], layout, times=None) -> None:
        """Log what the states hold beyond mean and covariance (particle clouds, mixture components, hypotheses).

        Optional (set ``records_states = True`` when overriding): ``states`` one bank state per step of
        ``steps`` (K,), ``names`` the M filter names, ``times`` (K,) seconds or None.  The pipeline logs
        every estimator's means, covariances and scores itself.
        """


def check_prior(mean, cov) -> tuple[np.ndarray, np.ndarray]:
    """Validate a bank prior: mean (M, n), cov (M, n, n) symmetric positive definite, within the filters' arithmetic.

    Every entry of mean and cov must have |value| ≤ ``FILTER_MAGNITUDE_LIMIT``
    (1e150) and every variance be ≥ its inverse 1e-150 (the information forms
    invert P): beyond, the filters' products overflow float64.  Errors are
    ValueErrors naming the argument.
    """
    mean = as_float_array(mean, "mean", (None, None))
    M, n = mean.shape
    cov = as_float_array(cov, "cov", (M, n, n))
    check_magnitude(mean, "mean", "prior mean")
    check_magnitude(cov, "cov", "prior covariance")
    variances = np.diagonal(cov, axis1=-2, axis2=-1)
    tiny = (variances > 0) & (variances < 1.0 / FILTER_MAGNITUDE_LIMIT)
    if tiny.any():
        index = tuple(int(i) for i in np.argwhere(tiny)[0])
        raise ValueError(
            f"cov: prior variance {float(variances[index]):.3g} at index {index + index[-1:]} is too small for the float64 "
            f"arithmetic of the filter (its inverse, the information, overflows); expected variances ≥ {1.0 / FILTER_MAGNITUDE_LIMIT:.0e}"
        )
    check_covariance(cov, "cov", n, definite=True)
    return mean, cov


def check_prior_mixture(means, covs, weights) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validate a bank's prior mixtures Σ_c w_c N(means_c, covs_c): means (M, C, n), covs (M, C, n, n) each as
    :func:`check_prior` requires, weights (M, C) ≥ 0 with a positive sum per filter.

    Returns (means, covs, weights, totals (M,)) as float arrays; errors are ValueErrors naming the argument.
    """
    means = as_float_array(means, "means", (None, None, None))
    M, C, n = means.shape
    covs = as_float_array(covs, "covs", (M, C, n, n))
    weights = as_float_array(weights, "weights", (M, C))
    if (weights < 0).any():
        raise ValueError(f"weights: expected weights ≥ 0, got a minimum of {float(weights.min())!r}")
    total = weights.sum(axis=1)
    if not (total > 0).all():
        raise ValueError(f"weights: every filter needs a positive total weight, got sums {total.tolist()}")
    check_prior(means.reshape(M * C, n), covs.reshape(M * C, n, n))
    return means, covs, weights, total


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

    @abstractmethod
    def reset(self) -> None: ...

    @abstractmethod
    def step(self, step: int, innovation: Innovation) -> DetectorStep: ...

    @classmethod
    def step_runs(cls, detectors: Sequence[Detector], step: int, innovations: Sequence[Innovation]) -> list[DetectorStep]:
        """One step of R runs at once: ``detectors[r]`` (instances of this class, one per run) fed ``innovations[r]``.

        Batched pipelines (``Pipeline.run_batch``) call it with each run's own
        copy of a detector; the result must equal ``[d.step(step, i) for …]``
        (the default), which a class may override to vectorize over the runs.
        """
        return [detector.step(step, innovation) for detector, innovation in zip(detectors, innovations)]


class ScoreDetector(Detector):
    """A detector that reads only per-filter scores: ℓ (M,), NIS (M,) and m.

    ``observe(step, loglik, nis, m)`` is the entry point; ``step`` calls it
    with the innovation's scores.  The same detector then runs on the scores
    a node of a decentralized filter computes locally
    (:meth:`Estimator.node_scores`), so the adaptive estimators run one copy
    per node.
    """

    def step(self, step: int, innovation: Innovation) -> DetectorStep:
        return self.observe(step, np.asarray(innovation.loglik, float), np.asarray(innovation.nis, float), innovation.measurement_dim)

    @abstractmethod
    def observe(self, step: int, loglik: np.ndarray, nis: np.ndarray, m: int) -> DetectorStep:
        """Consume one step's scores: ℓ (M,), NIS (M,), m (0 = no measurement this step)."""

    @classmethod
    def observe_runs(cls, detectors: Sequence[ScoreDetector], step: int, loglik: np.ndarray, nis: np.ndarray, m: int) -> list[DetectorStep]:
        """:meth:`observe` for R runs at once: ``detectors[r]`` (one per run, instances of this class) fed row r of
        ℓ (R, M) and NIS (R, M); m is shared (the runs of one call measured the same components).

        Batched pipelines call it instead of :meth:`Detector.step_runs` when the
        class keeps ScoreDetector's ``step``.  The result must equal
        ``[d.observe(step, loglik[r], nis[r], m) for …]`` (the default); a class
        may override it to vectorize over the runs.
        """
        return [detector.observe(step, loglik[r], nis[r], m) for r, detector in enumerate(detectors)]


class HypothesisTest(ScoreDetector):
    """A sequential test between the hypotheses of a fixed bank (seed 001 Algorithm 1 drives one).

    Declared attributes, read and set by the driver:

    * ``hypotheses`` (tuple of names, one per filter, or None) — set before
      :meth:`reset` at every switching moment;
    * ``decided`` — index of the accepted hypothesis once the test has
      decided (the step's ``DetectorStep.decision`` is set then), else None;
    * ``upper``, ``lower`` — the thresholds A and B (recorded beside ln λ).

    ``observe`` reports ``statistics["log_ratio"]`` (M,) and may report
    ``statistics["active"]`` (M,), 1 for the hypotheses still in play.
    """

    declared_attributes: ClassVar[tuple[str, ...]] = ("hypotheses", "decided", "upper", "lower")
    hypotheses: tuple[str, ...] | None = None
    decided: int | None = None
    upper: float
    lower: float

    def batch(self, runs: int) -> HypothesisTestBatch:
        """``runs`` independent copies of this test fed together (Monte Carlo runs stacked in one bank).

        Optional: the default loops over deep copies (:class:`HypothesisTestBatch`),
        so a third-party test needs nothing; a test overrides it with a
        vectorized version whose outputs equal the copies' (``sprt_pairwise``).
        """
        return HypothesisTestBatch(self, runs)


@attrs.frozen(eq=False)
class BatchStep:
    """One step of a :class:`HypothesisTestBatch` for the U runs observed: ``log_ratio`` (U, H), ``active``
    (U, H) (1 for the hypotheses in play), ``decided`` (U,) the accepted hypothesis or −1, ``decisions`` (U,)
    the step's Decision of each run or None."""

    log_ratio: np.ndarray
    active: np.ndarray
    decided: np.ndarray
    decisions: tuple


class HypothesisTestBatch:
    """R independent copies of one :class:`HypothesisTest` over banks of H hypotheses (the batch contract).

    ``reset(hypotheses)`` starts every copy anew (a switching moment of all
    runs); ``observe(step, runs, loglik (U, H), nis (U, H), m (U,))`` feeds the
    runs ``runs`` (indices into 0 … R−1) and returns a :class:`BatchStep`; each
    copy sees exactly what ``observe(step, loglik[u], nis[u], m[u])`` of a
    single test would.  This default keeps deep copies and loops over them (the
    fallback for tests without a vectorized batch).
    """

    def __init__(self, detector: HypothesisTest, runs: int):
        self.detector = detector
        self.runs = int(runs)
        self.upper, self.lower = detector.upper, detector.lower
        self.copies = [copy.deepcopy(detector) for _ in range(self.runs)]

    def reset(self, hypotheses: tuple[str, ...] | None) -> None:
        for c in self.copies:
            c.hypotheses = hypotheses
            c.reset()

    def observe(self, step: int, runs: np.ndarray, loglik: np.ndarray, nis: np.ndarray, m: np.ndarray) -> BatchStep:
        runs = np.asarray(runs, dtype=int)
        U, H = np.shape(loglik)
        ratio, active, decided, decisions = np.zeros((U, H)), np.zeros((U, H)), np.full(U, -1), []
        for u, r in enumerate(runs):
            out = self.copies[r].observe(step, loglik[u], nis[u], int(m[u]))
            ratio[u] = out.statistics["log_ratio"]
            active[u] = np.asarray(out.statistics.get("active", np.ones(H)), dtype=float)
            if out.decision is not None:
                decided[u] = int(self.copies[r].decided)
            decisions.append(out.decision)
        return BatchStep(ratio, active, decided, tuple(decisions))


class ChangeTimeTest(HypothesisTest):
    """A test for a change at an unknown time over a growing bank (seed 000 Algorithm 3 drives one).

    Row 0 of the bank is the current mode; the driver starts one filter per
    alternative at every step and tells the test with :meth:`add`; rows
    1 … E of each innovation are those entries in the order added.

    Besides :class:`HypothesisTest`'s attributes (``hypotheses[0]`` is the
    current mode; ``decided`` is the alternative p ≥ 1 on a change, 0 on "no
    change"): ``alpha``, ``beta`` (error probabilities), ``pruning`` (one of
    :data:`PRUNING_RULES`), ``starts`` (E,) the change step of each entry,
    ``chosen_entry`` (the entry followed after a change).
    """

    PRUNING_RULES: ClassVar[tuple[str, ...]] = ("oldest", "nearest_lower")
    declared_attributes: ClassVar[tuple[str, ...]] = HypothesisTest.declared_attributes + (
        "alpha",
        "beta",
        "pruning",
        "starts",
        "chosen_entry",
    )
    alpha: float
    beta: float
    pruning: str
    starts: np.ndarray
    chosen_entry: int | None = None

    @abstractmethod
    def add(self, modes: Sequence[int], start: int) -> None:
        """Append one entry per alternative in ``modes`` (1 … M−1) hypothesising the change at ``start``."""

    @abstractmethod
    def keep(self, rows: Sequence[int]) -> None:
        """Keep only the entries ``rows`` (indices into the entries, in order)."""

    @abstractmethod
    def prune(self, bank_size: int | None = None) -> np.ndarray:
        """Bound the entries to ``bank_size`` by the pruning rule; return the entry rows kept."""

    @abstractmethod
    def log_ratios(self) -> np.ndarray:
        """ln λ_p for each alternative p = 1 … M−1."""

    def batch(self, runs: int) -> ChangeTimeTestBatch:
        """``runs`` independent copies of this test fed together (optional; default: looped deep copies,
        :class:`ChangeTimeTestBatch`; ``sprt_unknown_change`` vectorizes it)."""
        return ChangeTimeTestBatch(self, runs)


@attrs.frozen(eq=False)
class ChangeTimeStep:
    """One step of a :class:`ChangeTimeTestBatch` for all R runs: ``log_ratio`` (R, P) ln λ_p; ``decided`` (R,)
    −1 (continue), 0 (no change: the run's test restarted) or the alternative p ≥ 1; ``chosen_entry`` (R,) the
    entry followed after a change (index among the run's entries, −1 otherwise) and ``chosen_start`` (R,) its
    change step; ``decisions`` (R,) the step's Decision or None."""

    log_ratio: np.ndarray
    decided: np.ndarray
    chosen_entry: np.ndarray
    chosen_start: np.ndarray
    decisions: tuple


class ChangeTimeTestBatch:
    """R independent copies of one :class:`ChangeTimeTest` (the batch contract of Algorithm 3's test).

    The entries of all runs form one flat sequence, run by run (the rows of the
    runs' stacked banks without each run's filter 0).  ``restart(runs,
    hypotheses)`` resets those runs' tests with new hypothesis names (one tuple
    per run); ``add(start)`` appends, in every run, one entry per alternative
    1 … P hypothesising the change at ``start``; ``observe(step, loglik0 (R,),
    loglik (E,), nis0 (R,), nis (E,), m (R,))`` feeds filter 0's and the
    entries' scores and returns a :class:`ChangeTimeStep`; ``prune(runs,
    caps)`` bounds the entries of ``runs`` (cap −1: the test's own
    ``bank_size``) by the pruning rule and returns the kept mask over the
    entries (E,); ``counts`` (R,) entries per run.  Each copy sees what a
    single test would.  This default keeps deep copies and loops over them.
    """

    def __init__(self, detector: ChangeTimeTest, runs: int):
        self.detector = detector
        self.runs = int(runs)
        self.upper, self.lower, self.pruning = detector.upper, detector.lower, detector.pruning
        self.copies = [copy.deepcopy(detector) for _ in range(self.runs)]

    @property
    def counts(self) -> np.ndarray:
        return np.array([c.starts.size for c in self.copies], dtype=int)

    def restart(self, runs: Sequence[int], hypotheses: Sequence[tuple[str, ...]]) -> None:
        for r, names in zip(runs, hypotheses):
            self.copies[r].hypotheses = tuple(names)
            self.copies[r].reset()

    def add(self, start: int) -> None:
        for c in self.copies:
            c.add(np.arange(1, len(c.hypotheses)), start)

    def observe(self, step: int, loglik0, loglik, nis0, nis, m) -> ChangeTimeStep:
        counts = self.counts
        ends = np.cumsum(counts)
        ratios, decided, entry, start, decisions = [], np.full(self.runs, -1), np.full(self.runs, -1), np.full(self.runs, -1), []
        for r, c in enumerate(self.copies):
            block = slice(ends[r] - counts[r], ends[r])
            out = c.observe(step, np.concatenate([[loglik0[r]], loglik[block]]), np.concatenate([[nis0[r]], nis[block]]), int(m[r]))
            ratios.append(np.asarray(out.statistics["log_ratio"], dtype=float))
            decisions.append(out.decision)
            if out.decision is not None:
                decided[r] = int(c.decided or 0)
                if c.decided:
                    entry[r] = int(c.chosen_entry)
                    start[r] = int(c.starts[entry[r]])
        return ChangeTimeStep(np.stack(ratios), decided, entry, start, tuple(decisions))

    def prune(self, runs: Sequence[int], caps: Sequence[int]) -> np.ndarray:
        keep = [np.ones(c.starts.size, dtype=bool) for c in self.copies]
        for r, cap in zip(runs, caps):
            rows = self.copies[r].prune(None if cap < 0 else int(cap))
            keep[r] = np.zeros(keep[r].size, dtype=bool)
            keep[r][rows] = True
        return np.concatenate(keep) if keep else np.zeros(0, dtype=bool)


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
