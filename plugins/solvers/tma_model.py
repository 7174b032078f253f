"""Bearings-only TMA model shared by the solvers (seed 002, §4.1–4.2).

The target moves uniformly, θ = (x0, y0, vx, vy) being its position at the
reference time t_r and its velocity (seed 002, eq. 1):

    x(t) = x0 + vx (t − t_r),   y(t) = y0 + vy (t − t_r).

Bearing k, taken at t_k from the observer at (x̃_k, ỹ_k), is
X_k = f_k(θ) + N(0, σ²) with f_k(θ) = φ(x(t_k) − x̃_k, y(t_k) − ỹ_k) (eq. 2–3;
φ and its convention from :mod:`hybridtrack_plugins.sensors.bearing`).  Maximum
likelihood is least squares (eq. 5):

    F(θ) = Σ_k r_k²,  r_k = wrap(X_k − f_k(θ)) ∈ (−π, π].

**Parameter scaling.**  The solvers work in dimensionless parameters
s = ((x0 − x̃_0)/L, (y0 − ỹ_0)/L, vx T/L, vy T/L) with times τ_k = (t_k − t_r)/T
and observer positions õ_k = (o_k − o_0)/L, where o_0 is the first observer
position, L = max(range of the initial guess from o_0, extent of the observer
path, 1 m) and T = max |t_k − t_r|.  Then every
column of J = ∂f/∂s is of order one whether θ is in km or m/s (seed 002 §4.3
notes the vanishing gradient of atan far from the origin); f is unchanged by the
scaling (bearings are scale-free), so F is the same function.

With p_k = ∂φ/∂Δx and q_k = ∂φ/∂Δy at point k (scaled units), the Jacobian row is
J_k = (p_k, q_k, p_k τ_k, q_k τ_k), so H = JᵀJ and g = Jᵀr only need the
sums Σ w τ^j of w ∈ {p², pq, q², pr, qr} (:func:`normal_equations`).
"""

from __future__ import annotations

import warnings
from abc import abstractmethod
from typing import ClassVar

import attrs
import numpy as np
from scipy import special

from hybridtrack.core.interfaces import Solution, Solver
from hybridtrack.core.validation import as_float_array
from hybridtrack.sdk.linalg import wrap_angle
from hybridtrack.sdk.timestamps import check_times
from hybridtrack_plugins.sensors.bearing import angle_difference, bearing, bearing_gradient, check_convention, direction

#: θ has four components
N_PARAMETERS = 4
#: observer paths whose deviation from a straight constant-velocity line is below
#: this fraction of their extent count as "never maneuvering"
MANEUVER_RTOL = 1e-9
#: reciprocal condition number of the scaled JᵀJ below which θ is declared unobservable
RCOND_MIN = 1e-12
#: bearings are radians: a magnitude above 2π cannot be one (degrees passed by mistake)
MAX_BEARING = 2.0 * np.pi
#: significance level of the constant-bearing test (σ known): bearings that fit one line of
#: sight with P(χ²(n−1) ≥ F_c/σ²) ≥ this are "constant within the noise"
CONSTANT_BEARING_ALPHA = 0.01
#: bearings all within this many radians of one line of sight (modulo π) are constant whatever σ
CONSTANT_BEARING_ATOL = 1e-9
#: message of an answer refused because the bearings are constant
CONSTANT_BEARING_MESSAGE = (
    "unobservable: constant bearing (all bearings equal modulo π within the noise), the range is not determined; θ set to NaN"
)
#: message suffix of an answer (σ unknown) that a constant bearing fits as well (:func:`constant_fits_as_well`)
CONSTANT_FIT_MESSAGE = "unobservable: a constant bearing fits the bearings as well (F-test), the range is not determined"


class UnobservableError(ValueError):
    """The range is unobservable: the observer never maneuvers (constant velocity)."""


class UnobservabilityWarning(UserWarning):
    """The information matrix JᵀJ at the answer is numerically singular."""


# --------------------------------------------------------------------------- problems


#: the largest |coordinate| (metres) of an observer position: the solvers work in offsets from the first observer
#: position, and float64 resolves positions of up to 1e9 m (beyond the Moon's orbit) to about 1e-7 m; far beyond,
#: the offsets of the observer's path and the target's range are lost in rounding (the fit fails on the start)
MAX_OBSERVER_COORDINATE = 1e9


def _check_observer(observer: np.ndarray, batch: bool) -> np.ndarray:
    """``observer`` (finite already) if every coordinate has |value| ≤ :data:`MAX_OBSERVER_COORDINATE`, else a
    ValueError naming the observer positions, the first bad index and the usable range."""
    big = np.abs(observer) > MAX_OBSERVER_COORDINATE
    if big.any():
        index = tuple(int(i) for i in np.argwhere(big)[0])
        where = (f"problem {index[0]}, " if batch and observer.ndim == 3 else "") + f"position {index[-2]}, {'xy'[index[-1]]}"
        raise ValueError(
            f"observer: observer positions must be finite with |coordinate| ≤ {MAX_OBSERVER_COORDINATE:.0e} m, got"
            f" {float(observer[index]):.3g} m ({where}); beyond, float64 rounding loses the observer's path and the"
            " target's range (use coordinates about a local origin, e.g. the first observer position)"
        )
    return observer


def _check_count(n: int) -> None:
    if n < N_PARAMETERS:
        raise ValueError(f"bearings: bearings-only TMA needs at least {N_PARAMETERS} bearings to fit θ = (x0, y0, vx, vy), got {n}")


def _check_radians(bearings: np.ndarray, batch: bool) -> None:
    """Refuse |θ| > 2π: such a bearing cannot be radians (degrees passed by mistake?)."""
    if np.abs(bearings).max() > MAX_BEARING:
        bad = np.argwhere(np.abs(bearings) > MAX_BEARING)
        index = tuple(int(i) for i in bad[0])
        where = f"problem {index[0]}, bearing {index[1]}" if batch else f"index {index[0]}"
        raise ValueError(
            f"bearings: {where} is {float(bearings[index])!r}, not an angle in radians (expected |θ| ≤ 2π);"
            " were degrees passed by mistake? convert with np.deg2rad"
        )


def _batch_array(value, name: str, shape, expected: str = ""):
    """``value`` as a read-only float array of ``shape`` (None = free axis) whose first axis is the problem;
    NaN/inf errors name the problem."""
    try:
        array = np.array(value, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name}: expected a numeric array, got {type(value).__name__} ({error})") from None
    if shape is not None and (array.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, array.shape))):
        raise ValueError(f"{name}: expected shape {expected}, got {array.shape}")
    if not np.isfinite(array).all():
        bad = np.argwhere(~np.isfinite(array))
        index = tuple(int(i) for i in bad[0])
        rest = f" at index {index[1:]}" if len(index) > 1 else ""
        raise ValueError(f"{name}: problem {index[0]} contains {float(array[index])!r}{rest} (expected finite values)")
    array.setflags(write=False)
    return array


def _sigma(value):
    if value is None:
        return None
    value = float(value)
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"sigma: expected a finite bearing noise σ ≥ 0 in radians (or None), got {value!r}")
    return value


@attrs.frozen(eq=False)
class BearingsProblem:
    """One bearings-only TMA problem.

    ``times`` (n,) seconds, strictly increasing; ``bearings`` (n,) radians, finite
    with |θ| ≤ 2π (wrapped internally; a larger value is refused as probably
    degrees); ``observer`` (n, 2) observer positions (x̃_k, ỹ_k) in metres, |coordinate| ≤ 1e9 (:data:`MAX_OBSERVER_COORDINATE`);
    ``sigma`` the bearing noise in radians when known (used for the χ²(n−4) test
    and the covariance σ²(JᵀJ)⁻¹; otherwise σ² is estimated by F/(n−4));
    ``initial`` a guess of θ at ``reference_time`` (default ``times[0]``);
    ``convention`` the bearing convention ("north" default, see the sensor).
    NaN/inf anywhere, times not strictly increasing, |θ| > 2π, fewer than 4
    bearings or mismatched shapes raise ``ValueError`` naming the field and index.
    """

    times: np.ndarray = attrs.field(converter=lambda v: check_times(v, "times"))
    bearings: np.ndarray = attrs.field(converter=lambda v: as_float_array(v, "bearings", (None,), readonly=True))
    observer: np.ndarray = attrs.field(converter=lambda v: _check_observer(as_float_array(v, "observer", (None, 2), readonly=True), False))
    sigma: float | None = attrs.field(default=None, converter=_sigma)
    initial: np.ndarray | None = attrs.field(
        default=None, converter=lambda v: None if v is None else as_float_array(v, "initial", (N_PARAMETERS,), readonly=True)
    )
    reference_time: float = attrs.field(default=None)
    convention: str = attrs.field(default="north", validator=lambda i, a, v: check_convention(v))

    def __attrs_post_init__(self):
        n = self.bearings.shape[0]
        _check_count(n)
        if self.times.shape != (n,) or self.observer.shape != (n, 2):
            raise ValueError(
                f"times {self.times.shape}, bearings {self.bearings.shape} and observer {self.observer.shape}:"
                f" expected shapes (n,), (n,), (n, 2) with the same n"
            )
        _check_radians(self.bearings, batch=False)
        t_r = self.times[0] if self.reference_time is None else self.reference_time
        object.__setattr__(self, "reference_time", float(as_float_array(t_r, "reference_time", ())))

    @property
    def size(self) -> int:
        return self.bearings.shape[0]

    def batch(self) -> BearingsBatch:
        """This problem as a batch of one."""
        return BearingsBatch(self.times, self.bearings[None], self.observer, self.sigma, self.initial, self.reference_time, self.convention)


@attrs.frozen(eq=False)
class BearingsBatch:
    """B independent problems on one time grid (e.g. Monte Carlo targets of one scenario).

    ``times`` (n,) shared; ``bearings`` (B, n); ``observer`` (n, 2) shared or
    (B, n, 2); ``initial`` (4,) shared or (B, 4); ``sigma`` one value or None;
    ``reference_time`` and ``convention`` as in :class:`BearingsProblem`.  The
    same checks as there, plus at least one problem; errors name the problem.
    """

    times: np.ndarray = attrs.field(converter=lambda v: check_times(v, "times"))
    bearings: np.ndarray = attrs.field(converter=lambda v: _batch_array(v, "bearings", (None, None), "(B, n)"))
    observer: np.ndarray = attrs.field(converter=lambda v: _check_observer(_batch_array(v, "observer", None), True))
    sigma: float | None = attrs.field(default=None, converter=_sigma)
    initial: np.ndarray | None = attrs.field(default=None, converter=lambda v: None if v is None else _batch_array(v, "initial", None))
    reference_time: float = attrs.field(default=None)
    convention: str = attrs.field(default="north", validator=lambda i, a, v: check_convention(v))

    def __attrs_post_init__(self):
        B, n = self.bearings.shape
        if B == 0:
            raise ValueError(f"bearings: the batch holds no problem (shape {self.bearings.shape}); expected shape (B, n) with B ≥ 1")
        _check_count(n)
        if self.times.shape != (n,):
            raise ValueError(f"times: expected shape ({n},) to match bearings {self.bearings.shape}, got {self.times.shape}")
        if self.observer.shape not in ((n, 2), (B, n, 2)):
            raise ValueError(f"observer: expected shape ({n}, 2) or ({B}, {n}, 2), got {self.observer.shape}")
        if self.initial is not None and self.initial.shape not in ((N_PARAMETERS,), (B, N_PARAMETERS)):
            raise ValueError(f"initial: expected shape (4,) or ({B}, 4), got {self.initial.shape}")
        _check_radians(self.bearings, batch=True)
        t_r = self.times[0] if self.reference_time is None else self.reference_time
        object.__setattr__(self, "reference_time", float(as_float_array(t_r, "reference_time", ())))

    def __len__(self) -> int:
        return self.bearings.shape[0]

    @property
    def size(self) -> int:
        return self.bearings.shape[1]

    def observer_of(self, i: int) -> np.ndarray:
        return self.observer if self.observer.ndim == 2 else self.observer[i]

    def initial_of(self, i: int):
        return self.initial if self.initial is None or self.initial.ndim == 1 else self.initial[i]

    def subset(self, rows) -> BearingsBatch:
        """The problems ``rows`` (an index array) as a batch of their own."""
        return attrs.evolve(
            self,
            bearings=self.bearings[rows],
            observer=self.observer if self.observer.ndim == 2 else self.observer[rows],
            initial=self.initial_of(rows),
        )

    def problem(self, i: int) -> BearingsProblem:
        """Problem ``i`` on its own."""
        return BearingsProblem(
            self.times, self.bearings[i], self.observer_of(i), self.sigma, self.initial_of(i), self.reference_time, self.convention
        )


# --------------------------------------------------------------------------- observability


def maneuver_deviation(times: np.ndarray, observer: np.ndarray) -> np.ndarray:
    """Largest distance of the observer path (..., n, 2) from its best constant-velocity fit, relative to its extent.

    A constant-velocity observer sees the same bearings for every target whose
    relative motion is scaled by a common factor, so the range is unobservable
    (seed 002 §6: a good maneuver is what makes the solution unique).
    """
    t = times - times.mean()
    design = np.stack([np.ones_like(t), t], axis=1)  # (n, 2)
    coef, *_ = np.linalg.lstsq(design, np.moveaxis(observer, -2, 0).reshape(len(t), -1), rcond=None)
    fitted = (design @ coef).reshape((len(t),) + observer.shape[:-2] + (2,))
    deviation = np.linalg.norm(np.moveaxis(fitted, 0, -2) - observer, axis=-1).max(axis=-1)
    extent = np.ptp(observer, axis=-2).max(axis=-1)
    return deviation / np.maximum(extent, 1.0)


def require_problem(problem, kind, name: str, start: bool = False):
    """``problem`` if it is a ``kind`` (:class:`BearingsProblem` or :class:`BearingsBatch`) whose observer path
    maneuvers and, with ``start``, has an ``initial`` guess; else ``ValueError``, :class:`UnobservableError` when
    the observer never maneuvers."""
    argument = "problem" if kind is BearingsProblem else "batch"
    if not isinstance(problem, kind):
        raise ValueError(f"{argument}: expected a {kind.__name__}, got {type(problem).__name__}")
    bad = np.atleast_1d(maneuver_deviation(problem.times, problem.observer) <= MANEUVER_RTOL)
    if bad.any():
        which = "" if problem.observer.ndim == 2 else f" (problems {np.flatnonzero(bad)[:10].tolist()}…)"
        raise UnobservableError(
            "observer never maneuvers (constant velocity): the range is unobservable from bearings alone"
            f"{which}; add a course or speed change"
        )
    if start and problem.initial is None:
        raise ValueError(f"{name}: {argument}.initial is None; give a starting guess θ (e.g. the N-bearings answer or a prior)")
    return problem


def _line_deviations(X):
    """d_k = wrap(2(X_k − φ̄))/2, the deviations of the bearings (..., n) from their best common line φ̄ (mod π)."""
    doubled = 2.0 * X
    centre = np.arctan2(np.sin(doubled).sum(axis=-1), np.cos(doubled).sum(axis=-1))
    d = wrap_angle(doubled - centre[..., None])
    return wrap_angle(d - d.mean(axis=-1, keepdims=True)) / 2.0


def constant_fits_as_well(bearings, F, alpha: float = CONSTANT_BEARING_ALPHA) -> np.ndarray:
    """True where a constant bearing explains the bearings (..., n) as well as the answer's F (σ unknown).

    F-test of the constant-bearing model (1 parameter, cost F_c, see
    :func:`constant_bearing`) against uniform motion (4 parameters, cost F):
    ((F_c − F)/3) / (F/(n − 4)) ~ F(3, n − 4) when the bearing is constant;
    P ≥ ``alpha`` means the data do not show the bearing change that determines
    the range.  Always False for n = 4 (no degrees of freedom).
    """
    X = np.asarray(bearings, dtype=float)
    n = X.shape[-1]
    F = np.asarray(F, dtype=float)
    if n <= N_PARAMETERS:
        return np.zeros(F.shape, bool)
    d = _line_deviations(X)
    F_c = np.einsum("...k,...k->...", d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        statistic = ((F_c - F) / (N_PARAMETERS - 1)) / (F / (n - N_PARAMETERS))
    return special.fdtrc(N_PARAMETERS - 1, n - N_PARAMETERS, np.maximum(np.where(np.isnan(statistic), np.inf, statistic), 0.0)) >= alpha


def constant_bearing(bearings, sigma, alpha: float = CONSTANT_BEARING_ALPHA) -> np.ndarray:
    """True for each problem (bearings (..., n)) whose bearings are all equal modulo π within the noise.

    Then the range and the radial speed are not determined (seed 002 §6; cases: docs/tma.md, "The constant-bearing test").
    The line is estimated on doubled angles (so that φ and φ + π are the same line):
    φ̄ = arg(Σ e^{2iX_k})/2, refined once by the mean deviation; d_k = wrap(2(X_k − φ̄))/2 and F_c = Σ d_k² (the least-squares
    cost of a constant bearing).  Constant when every |d_k| ≤
    :data:`CONSTANT_BEARING_ATOL`, or, σ > 0 known, when the χ²(n − 1) test does
    not reject a constant bearing: P(χ²(n−1) ≥ F_c/σ²) ≥ ``alpha``.
    """
    X = np.asarray(bearings, dtype=float)
    n = X.shape[-1]
    rows = X.reshape(-1, n)
    # exact screen, cheap for a large batch: for disjoint pairs (a, b) of bearings, F_c ≥ Σ δ²/2 and every
    # |d| ≥ |δ|/2 with δ = wrap(2(X_a − X_b))/2, so rows where up to 64 pairs (k, k + n/2) already show
    # Σ δ²/2 > q σ² (q the 1 − α quantile of χ²(n−1)) and max |δ| > 2·ATOL are not constant: no trigonometry
    half = n // 2
    k = np.unique(np.linspace(0, half - 1, min(half, 64)).astype(int))
    delta = (np.mod(2.0 * (rows[:, k] - rows[:, k + half]) + np.pi, 2.0 * np.pi) - np.pi) / 2.0
    slack = 1.0 - 1e-9
    changes = np.abs(delta).max(axis=-1) * slack > 2.0 * CONSTANT_BEARING_ATOL
    if sigma is not None and sigma > 0:
        changes &= np.einsum("ik,ik->i", delta, delta) / 2.0 * slack > special.chdtri(n - 1, alpha) * sigma**2
    candidate = np.flatnonzero(~changes)
    constant = np.zeros(rows.shape[0], bool)
    if candidate.size:
        d = _line_deviations(rows[candidate])
        test = np.abs(d).max(axis=-1) <= CONSTANT_BEARING_ATOL
        if sigma is not None and sigma > 0:
            F_c = np.einsum("...k,...k->...", d, d)
            test |= special.chdtrc(n - 1, F_c / sigma**2) >= alpha
        constant[candidate] = test
    return constant.reshape(X.shape[:-1])


def warn_constant_bearing(rows, method: str, fit: bool = False) -> None:
    """Warn (:class:`UnobservabilityWarning`) that the problems ``rows`` (−1: the one problem) have a constant bearing.

    ``fit``: found after solving by :func:`constant_fits_as_well` (σ unknown), only the covariance is NaN.
    """
    rows = np.atleast_1d(rows)
    which = "" if rows.size == 1 and rows[0] < 0 else f" in problem(s) {rows[:10].tolist()}{'…' if rows.size > 10 else ''}"
    what = "a constant bearing fits as well as uniform motion (F-test)" if fit else "all bearings equal modulo π within the noise"
    nan = "covariance" if fit else "θ and covariance"
    warnings.warn(
        f"{method}: constant bearing{which} ({what}): the range is unobservable ({nan} set to NaN, converged=False)",
        UnobservabilityWarning,
        stacklevel=3,
    )


#: ``numbers`` of a lone problem (not part of a batch): warnings and errors do not number it
LONE = np.array([-1])


def solve_observable_rows(batch: BearingsBatch, solve, method: str, numbers=None) -> BatchTMASolution:
    """``solve(sub_batch, numbers)`` on the problems without a constant bearing; the others get NaN answers.

    ``numbers`` (B,) name the problems in warnings and errors (default 0 … B − 1;
    :data:`LONE` for a problem on its own).  Constant-bearing problems
    (:func:`constant_bearing`) are not solved: their θ, covariance, cost and
    statistics are NaN, ``converged`` False, their message
    :data:`CONSTANT_BEARING_MESSAGE` (one :class:`UnobservabilityWarning` names them).
    """
    numbers = np.arange(len(batch)) if numbers is None else numbers
    constant = constant_bearing(batch.bearings, batch.sigma)
    if not constant.any():
        return solve(batch, numbers)
    warn_constant_bearing(numbers[constant], method)
    rows = np.flatnonzero(~constant)
    B, n = batch.bearings.shape
    nan, zeros = np.full(B, np.nan), np.zeros(B, int)
    theta, cov = np.full((B, N_PARAMETERS), np.nan), np.full((B, N_PARAMETERS, N_PARAMETERS), np.nan)
    messages = np.full(B, CONSTANT_BEARING_MESSAGE, dtype=object)
    whole = answers(batch, theta, cov, nan, fit_statistics(nan, n, batch.sigma), zeros, zeros.copy(), zeros > 0, messages, method)
    if not rows.size:
        return whole
    part = solve(batch.subset(rows), numbers[rows])
    for name in ("parameters", "covariance", "cost", "iterations", "evaluations", "converged", "sqrt_ka", "chi2_statistic", "chi2_pvalue"):
        getattr(whole, name)[rows] = getattr(part, name)
    if whole.consistent is not None:  # the χ² test is defined (False for the constant ones)
        whole.consistent[rows] = part.consistent
    messages[rows] = part.messages
    return attrs.evolve(whole, messages=tuple(messages))


def scaled_start(batch: BearingsBatch, i: int, theta0, number) -> tuple[ScaledProblem, np.ndarray]:
    """Problem ``i`` of ``batch`` in scaled units and its start s0 (the guess θ0 (4,) scaled).

    Refuses a start whose track meets the observer at a bearing time: there the
    bearing and its gradient (1/ρ²) are undefined, F or JᵀJ is NaN and the LM
    cannot take a step.  ``number`` is the problem's number in the caller's
    batch (< 0: a lone problem, not numbered).
    """
    scaled = ScaledProblem.build(batch.times, batch.bearings[i], batch.observer_of(i), theta0, batch.reference_time, batch.convention)
    s = scaled.scaling.to_scaled(theta0)
    dx, dy = relative(s, scaled.tau, scaled.ox, scaled.oy)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        bad = np.flatnonzero(~np.isfinite(1.0 / (dx * dx + dy * dy)))
    if bad.size:
        which = "" if number < 0 else f" of problem {int(number)}"
        raise ValueError(
            f"initial: the starting guess{which} puts the target on the observer at bearing {int(bad[0])}"
            f" (t = {float(batch.times[bad[0]])!r} s), where the bearing is undefined;"
            " start at a positive range (e.g. a prior along the first bearing)"
        )
    return scaled, s


class BearingsSolver(Solver):
    """A TMA solver written once over a :class:`BearingsBatch`: ``solve(problem)`` is a batch of one.

    Subclasses give :meth:`solve_rows`; ``needs_start``: the problems must carry
    an ``initial`` guess (:func:`require_problem`).  Constant-bearing problems are
    not solved (:func:`solve_observable_rows`).
    """

    needs_start: ClassVar[bool] = True

    def solve(self, problem: BearingsProblem) -> TMASolution:
        require_problem(problem, BearingsProblem, self.name, start=self.needs_start)
        return solve_observable_rows(problem.batch(), self.solve_rows, self.name, LONE).solution(0)

    def solve_batch(self, batch: BearingsBatch) -> BatchTMASolution:
        require_problem(batch, BearingsBatch, self.name, start=self.needs_start)
        return solve_observable_rows(batch, self.solve_rows, self.name)

    @abstractmethod
    def solve_rows(self, batch: BearingsBatch, numbers: np.ndarray) -> BatchTMASolution:
        """Solve every problem of ``batch`` (problem ``numbers`` of the caller's batch, for warnings and errors)."""


# --------------------------------------------------------------------------- scaling


@attrs.frozen(eq=False)
class Scaling:
    """θ ↔ s = ((x0, y0) − o_0)/L, (vx, vy) T/L) for arrays (..., 4) (see the module doc).

    ``origin`` (..., 2), ``length`` L (...,), ``duration`` T and ``reference_time`` t_r.
    """

    origin: np.ndarray
    length: np.ndarray
    duration: float
    reference_time: float

    @classmethod
    def build(cls, times, observer, initial, reference_time) -> Scaling:
        origin = observer[..., 0, :]
        extent = np.linalg.norm(np.ptp(observer, axis=-2), axis=-1)
        length = np.maximum(extent, 1.0)
        if initial is not None:
            length = np.maximum(np.linalg.norm(initial[..., :2] - origin, axis=-1), length)
        if length.ndim and origin.ndim == 1 and np.all(length == length.flat[0]):
            length = length.flat[0]  # one L for a batch sharing observer and guess: õ stays (n,)
        duration = float(max(np.abs(times - reference_time).max(), 1e-9))
        return cls(origin, np.asarray(length, dtype=float), duration, reference_time)

    @property
    def factors(self) -> np.ndarray:
        """D = ∂θ/∂s = diag(L, L, L/T, L/T) as (..., 4)."""
        L = np.asarray(self.length)[..., None]
        return L * np.array([1.0, 1.0, 1.0 / self.duration, 1.0 / self.duration])

    def to_scaled(self, theta):
        theta = np.asarray(theta, dtype=float)
        shifted = np.concatenate([theta[..., :2] - self.origin, theta[..., 2:]], axis=-1)
        return shifted / self.factors

    def from_scaled(self, s):
        theta = np.asarray(s) * self.factors
        return np.concatenate([theta[..., :2] + self.origin, theta[..., 2:]], axis=-1)

    def tau(self, times):
        return (times - self.reference_time) / self.duration

    def observer(self, observer):
        """õ = (o − o_0)/L, shape (..., n, 2)."""
        return (observer - self.origin[..., None, :]) / np.asarray(self.length)[..., None, None]


# --------------------------------------------------------------------------- model (scaled units)


def relative(s, tau, ox, oy):
    """Δx_k, Δy_k = s_0 + s_2 τ_k − õx_k, s_1 + s_3 τ_k − õy_k for s (..., 4) → (..., n)."""
    s = np.asarray(s)
    dx = s[..., 0, None] + s[..., 2, None] * tau - ox
    dy = s[..., 1, None] + s[..., 3, None] * tau - oy
    return dx, dy


def time_powers(tau) -> np.ndarray:
    """T_k = (1, τ_k, τ_k²), shape (n, 3)."""
    return np.stack([np.ones_like(tau), tau, tau * tau], axis=-1)


def normal_equations(p, q, r, powers, out=None):
    """H = JᵀJ (..., 4, 4) and g = Jᵀr (..., 4) from p, q, r (..., n) and T = time_powers(τ) (n, 3).

    S_ij = Σ_k w_i,k τ_k^j for w = (p², pq, q², pr, qr), one matrix product
    W T; H and g are read off S (J_k = (p, q, pτ, qτ)).  ``out`` is an optional
    C-contiguous (..., 5, n) buffer for W.
    """
    n = p.shape[-1]
    lead = np.broadcast_shapes(p.shape, q.shape, r.shape)[:-1]
    W = np.empty(lead + (5, n)) if out is None else out
    for i, (u, v) in enumerate(((p, p), (p, q), (q, q), (p, r), (q, r))):
        np.multiply(u, v, out=W[..., i, :])
    S = (W.reshape(-1, n) @ powers).reshape(lead + (15,))  # one 2-D product for the whole stack
    return S[..., _H_FROM_S].reshape(lead + (4, 4)), S[..., _G_FROM_S]


# S flattened as 3 i + j (weight i, power j): H_ab and g_a read off it, H rows Σ(p, q, pτ, qτ)·(p, q, pτ, qτ)
_H_FROM_S = np.array([[0, 3, 1, 4], [3, 6, 4, 7], [1, 4, 2, 5], [4, 7, 5, 8]]).ravel()
_G_FROM_S = np.array([9, 12, 10, 13])  # g = Σpr, Σqr, Σprτ, Σqrτ


@attrs.frozen(eq=False)
class ScaledProblem:
    """A problem in scaled units: τ (n,), õx, õy (..., n), X (..., n), with its :class:`Scaling`."""

    tau: np.ndarray
    ox: np.ndarray
    oy: np.ndarray
    X: np.ndarray
    convention: str
    scaling: Scaling

    @classmethod
    def build(cls, times, bearings, observer, initial, reference_time, convention) -> ScaledProblem:
        scaling = Scaling.build(times, observer, initial, reference_time)
        o = scaling.observer(observer)
        return cls(scaling.tau(times), o[..., 0], o[..., 1], wrap_angle(bearings), convention, scaling)

    def residuals(self, s):
        """r_k = wrap(X_k − f_k(s)) (seed 002 eq. 5, wrapped to (−π, π]; X already lies there)."""
        dx, dy = relative(s, self.tau, self.ox, self.oy)
        return angle_difference(self.X, bearing(dx, dy, self.convention))

    def cost(self, s):
        r = self.residuals(s)
        return np.einsum("...k,...k->...", r, r), r

    def jacobian(self, s):
        """J = ∂f/∂s, rows (p_k, q_k, p_k τ_k, q_k τ_k), shape (..., n, 4)."""
        p, q = bearing_gradient(*relative(s, self.tau, self.ox, self.oy), self.convention)
        return np.stack([p, q, p * self.tau, q * self.tau], axis=-1)


# --------------------------------------------------------------------------- answers


@attrs.frozen(eq=False, kw_only=True)
class TMASolution(Solution):
    """A TMA answer: θ = (x0, y0, vx, vy) at ``reference_time`` and its covariance.

    ``cost`` is F(θ) in rad²; ``sqrt_ka`` = √(F/n) in radians (seed 002 §5.1,
    "Ka"), ``sqrt_ka_deg`` in degrees; ``chi2_statistic`` = F/σ² tested against
    χ²(n − 4) (seed 002 §4.2): ``chi2_pvalue`` = P(χ²(n−4) ≥ F/σ²) and
    ``consistent`` = p ≥ ``alpha`` (None when σ is unknown or zero).
    """

    reference_time: float
    sqrt_ka: float
    chi2_statistic: float = float("nan")
    chi2_dof: int = 0
    chi2_pvalue: float = float("nan")
    consistent: bool | None = None
    method: str = ""

    @property
    def sqrt_ka_deg(self) -> float:
        return float(np.rad2deg(self.sqrt_ka))


@attrs.frozen(eq=False)
class BatchTMASolution:
    """B answers stacked: parameters (B, 4), covariance (B, 4, 4), cost, sqrt_ka, chi2_pvalue (B,), iterations, evaluations (B,), converged (B,)."""

    parameters: np.ndarray
    covariance: np.ndarray
    cost: np.ndarray
    iterations: np.ndarray
    evaluations: np.ndarray
    converged: np.ndarray
    sqrt_ka: np.ndarray
    chi2_statistic: np.ndarray
    chi2_dof: int
    chi2_pvalue: np.ndarray
    consistent: np.ndarray | None
    reference_time: float
    messages: tuple[str, ...]
    method: str = ""

    def __len__(self) -> int:
        return self.parameters.shape[0]

    @property
    def sqrt_ka_deg(self) -> np.ndarray:
        return np.rad2deg(self.sqrt_ka)

    def solution(self, i: int) -> TMASolution:
        scalars = ("cost", "iterations", "evaluations", "converged", "sqrt_ka", "chi2_statistic", "chi2_pvalue")
        return TMASolution(
            parameters=self.parameters[i],
            covariance=self.covariance[i],
            message=self.messages[i],
            reference_time=self.reference_time,
            chi2_dof=self.chi2_dof,
            consistent=None if self.consistent is None else bool(self.consistent[i]),
            method=self.method,
            **{name: getattr(self, name)[i].item() for name in scalars},
        )


def propagate(theta, dt):
    """Position of θ = (x0, y0, vx, vy) moved by dt: (x0 + vx dt, y0 + vy dt, vx, vy), θ and dt broadcast."""
    theta = np.asarray(theta, dtype=float)
    position = theta[..., :2] + theta[..., 2:] * np.asarray(dt, dtype=float)[..., None]
    return np.concatenate([position, np.broadcast_to(theta[..., 2:], position.shape)], axis=-1)


def summarize(scaling, s, F, H, n, sigma, alpha=0.01):
    """θ, covariance, √Ka and the χ²(n−4) test for answers s (..., 4) with F (...,) and H = JᵀJ (..., 4, 4) in scaled units.

    Covariance (Cramér–Rao, seed 002 §4.2): C_θ = σ² D (JᵀJ)⁻¹ D with D = ∂θ/∂s, σ²
    the known noise or F/(n − 4).  Answers whose JᵀJ has reciprocal condition
    below :data:`RCOND_MIN`, or is not finite, get a NaN covariance and ``observable`` False.
    Returns (theta, covariance, sqrt_ka, chi2_statistic, chi2_pvalue, consistent, observable).
    """
    F = np.asarray(F, dtype=float)
    theta = scaling.from_scaled(s)
    dof = n - N_PARAMETERS
    # Jacobi-equilibrate before factorizing: C = E (E H E)⁻¹ E with E = diag(H)^(-1/2)
    d = np.sqrt(np.maximum(np.diagonal(H, axis1=-2, axis2=-1), np.finfo(float).tiny))
    with np.errstate(invalid="ignore"):
        Hn = H / (d[..., :, None] * d[..., None, :])
    finite = np.isfinite(Hn).all(axis=(-2, -1))  # NaN/inf H (e.g. a zero range): eigvalsh would fail
    eig = np.linalg.eigvalsh(np.where(finite[..., None, None], Hn, np.eye(4)))
    observable = (eig[..., 0] > RCOND_MIN * eig[..., -1]) & finite
    Hn_safe = np.where(observable[..., None, None], Hn, np.eye(4))
    Lc = np.linalg.cholesky(Hn_safe)
    Linv = np.linalg.solve(Lc, np.broadcast_to(np.eye(4), Lc.shape))  # 4×4 triangular, off the hot path
    Hinv = (np.swapaxes(Linv, -1, -2) @ Linv) / (d[..., :, None] * d[..., None, :])
    if sigma is not None:
        variance = np.full(F.shape, sigma**2)
    else:
        variance = F / dof if dof > 0 else np.full(F.shape, np.nan)
    D = scaling.factors
    with np.errstate(over="ignore", invalid="ignore"):  # unobservable rows are overwritten with NaN
        cov = variance[..., None, None] * Hinv * (D[..., :, None] * D[..., None, :])
    cov = np.where(observable[..., None, None], cov, np.nan)
    return (theta, cov) + fit_statistics(F, n, sigma, alpha) + (observable,)


def fit_statistics(F, n, sigma, alpha=0.01):
    """√Ka = √(F/n) (seed 002 §5.1) and the χ²(n−4) test of F/σ² (seed 002 §4.2).

    Returns (sqrt_ka, statistic, pvalue, consistent); the last three are NaN /
    None when σ is unknown or zero or n = 4.
    """
    F = np.asarray(F, dtype=float)
    dof = n - N_PARAMETERS
    sqrt_ka = np.sqrt(F / n)
    if sigma is not None and sigma > 0 and dof > 0:
        statistic = F / sigma**2
        pvalue = special.chdtrc(dof, statistic)
        return sqrt_ka, statistic, pvalue, pvalue >= alpha
    nan = np.full(F.shape, np.nan)
    return sqrt_ka, nan, nan.copy(), None


def warn_unobservable(count: int, method: str) -> None:
    warnings.warn(
        f"{method}: JᵀJ is numerically singular at {count} answer(s): θ is unobservable from these bearings"
        " (covariance set to NaN, converged=False)",
        UnobservabilityWarning,
        stacklevel=3,
    )


def flag_constant_fits(batch: BearingsBatch, F, candidates, numbers, method: str) -> np.ndarray:
    """The ``candidates`` (B,) that a constant bearing fits as well (:func:`constant_fits_as_well`, σ unknown only); warns."""
    if batch.sigma is not None:  # σ known: the pre-check (constant_bearing) has decided
        return np.zeros(len(candidates), bool)
    fit = candidates & constant_fits_as_well(batch.bearings, F)
    if fit.any():
        warn_constant_bearing(numbers[fit], method, fit=True)
    return fit


def conclude(batch, scaling, s, F, H, iterations, evaluations, converged, messages, numbers, method) -> BatchTMASolution:
    """The answers s (B, 4) of an iterative solver, with F (B,) and H = JᵀJ (B, 4, 4) there (scaled units).

    θ, covariance and tests by :func:`summarize`.  A singular JᵀJ, or (σ unknown)
    a constant bearing that fits as well (:func:`flag_constant_fits`), makes the
    answer unobservable: a warning, covariance NaN, ``converged`` False, a note in its message.
    """
    theta, cov, *statistics, observable = summarize(scaling, s, F, H, batch.size, batch.sigma)
    if not observable.all():
        warn_unobservable(int((~observable).sum()), method)
    fit = flag_constant_fits(batch, F, observable, numbers, method)
    notes = ("unobservable: JᵀJ singular" if not o else CONSTANT_FIT_MESSAGE if f else "" for o, f in zip(observable, fit))
    messages = ["; ".join(filter(None, (m, note))) for m, note in zip(messages, notes)]
    cov = np.where(fit[:, None, None], np.nan, cov)
    converged = np.asarray(converged) & observable & ~fit
    return answers(batch, theta, cov, F, statistics, iterations, evaluations, converged, messages, method)


def answers(batch, theta, cov, F, statistics, iterations, evaluations, converged, messages, method) -> BatchTMASolution:
    """The :class:`BatchTMASolution` of ``batch`` from θ (B, 4), covariance, F and ``statistics`` =
    (√Ka, χ², p-value, consistent) of :func:`fit_statistics`."""
    ska, stat, pval, cons = statistics
    return BatchTMASolution(
        parameters=theta,
        covariance=cov,
        cost=F,
        iterations=np.asarray(iterations),
        evaluations=np.asarray(evaluations),
        converged=converged,
        sqrt_ka=ska,
        chi2_statistic=stat,
        chi2_dof=batch.size - N_PARAMETERS,
        chi2_pvalue=pval,
        consistent=cons,
        reference_time=batch.reference_time,
        messages=tuple(messages),
        method=method,
    )


# --------------------------------------------------------------------------- kinematics


def kinematics(theta, t, reference_time, observer_position, convention="north"):
    """Bearing, range, course and speed of the target θ at time t seen from ``observer_position`` (..., 2).

    Course is the bearing of the velocity vector in the same convention.
    Returns four arrays (radians, metres, radians, m/s).
    """
    state = propagate(theta, np.asarray(t) - reference_time)
    dx = state[..., 0] - observer_position[..., 0]
    dy = state[..., 1] - observer_position[..., 1]
    return (
        bearing(dx, dy, convention),
        np.hypot(dx, dy),
        bearing(state[..., 2], state[..., 3], convention),
        np.hypot(state[..., 2], state[..., 3]),
    )


def from_polar(bearing_angle, range_, course, speed, observer_position, convention="north"):
    """θ (..., 4) of a target at ``bearing``/``range`` from ``observer_position`` moving on ``course`` at ``speed``."""
    ux, uy = direction(bearing_angle, convention)
    cx, cy = direction(course, convention)
    observer_position = np.asarray(observer_position, dtype=float)
    return np.stack([observer_position[..., 0] + range_ * ux, observer_position[..., 1] + range_ * uy, speed * cx, speed * cy], axis=-1)
