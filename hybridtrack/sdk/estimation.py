"""A base for bank estimators: input checks, measurement assembly, bank operations, the reading API.

Written for plugin authors (the built-in filters use it exactly as a third
party would): subclass :class:`BankEstimator`, implement ``initialize``,
``predict`` and ``update_measured`` for one algebraic form (the template
``update`` handles a step without a measurement), and declare the state as an
attrs class whose per-filter arrays are :func:`bank_field` s; ``take`` and
``concatenate`` (the bank operations of the
:class:`~hybridtrack.core.interfaces.Estimator` contract) then work on the state's
own form — square-root factors and per-node copies are selected and joined,
never rebuilt from (x, P).  What every state exposes (``mean``, ``covariance``, the prediction's, ``innovation``):
``docs/estimators.md``, "What every estimator gives".
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from operator import attrgetter
from typing import Any, ClassVar

import attrs
import numpy as np

from hybridtrack.core.interfaces import Estimator, Innovation, TransitionBank
from hybridtrack.core.validation import FILTER_MAGNITUDE_LIMIT, as_float_array, check_prior
from hybridtrack.sdk.measurements import MeasurementAssembler


class NodeMoments:
    """Mixin for decentralized states: ``moments`` = (x (N, M, n), P (N, M, n, n)) over the N nodes, read as
    ``node_means``/``node_covariances``; ``mean``/``covariance`` read node 0 (every node holds the same estimate
    up to rounding)."""

    node_means = property(lambda self: self.moments[0])
    node_covariances = property(lambda self: self.moments[1])
    mean = property(lambda self: self.moments[0][0])
    covariance = property(lambda self: self.moments[1][0])


class PredictedMoments:
    """Mixin: ``predicted_mean``/``predicted_covariance`` read the fields ``x_predicted`` (M, n) and
    ``P_predicted`` (M, n, n) of the last prediction."""

    __slots__ = ()
    predicted_mean = property(attrgetter("x_predicted"))
    predicted_covariance = property(attrgetter("P_predicted"))


class CovarianceMoments(PredictedMoments):
    """Mixin for states that hold the moments themselves: ``mean``/``covariance`` read the fields ``x`` (M, n) and
    ``P`` (M, n, n) (and the prediction's, :class:`PredictedMoments`)."""

    __slots__ = ()
    mean = property(attrgetter("x"))
    covariance = property(attrgetter("P"))


class DerivedMoments(PredictedMoments):
    """Mixin for states whose moments are computed from another form (information, particles): the state
    defines ``moments`` = (x (M, n), P (M, n, n)), typically a ``cached_property``; ``mean``/``covariance`` read it
    (and the prediction's, :class:`PredictedMoments`)."""

    __slots__ = ()
    mean = property(lambda self: self.moments[0])
    covariance = property(lambda self: self.moments[1])


def bank_field(axis: int = 0, **kwargs):
    """An attrs field of a bank state stacked over the M filters on ``axis`` (0 for (M, …), 1 for (N, M, …)).

    The value may be an array, a tuple of arrays (each stacked the same way),
    or None.  :func:`take_rows` and :func:`concatenate_states` act on these
    fields; the other fields (e.g. the last innovation) describe the last step
    and are reset to their defaults.
    """
    return attrs.field(metadata={"bank_axis": axis}, **kwargs)


def _bank_fields(state) -> list:
    if not attrs.has(type(state)):
        raise TypeError(f"state: expected an attrs class with bank_field()s, got {type(state).__name__}")
    return [f for f in attrs.fields(type(state)) if "bank_axis" in f.metadata]


def _reset_fields(state) -> dict:
    """Fields that are not bank fields and have a default (the last step's outputs) go back to it."""
    return {
        f.name: f.default.factory() if isinstance(f.default, attrs.Factory) else f.default
        for f in attrs.fields(type(state))
        if "bank_axis" not in f.metadata and f.default is not attrs.NOTHING
    }


def take_rows(state, rows: Sequence[int]):
    """The state of the filters ``rows`` (in that order, repeats copy a filter) of a bank state with bank_field()s."""
    rows = np.asarray(rows, dtype=np.intp).reshape(-1)
    changes = {}
    for f in _bank_fields(state):
        value, axis = getattr(state, f.name), f.metadata["bank_axis"]
        if isinstance(value, tuple):
            changes[f.name] = tuple(np.take(v, rows, axis=axis) for v in value)
        elif value is not None:
            changes[f.name] = np.take(value, rows, axis=axis)
    return attrs.evolve(state, **changes, **_reset_fields(state))


def concatenate_states(states: Sequence):
    """One state holding the filters of ``states`` (same class, same non-bank fields) in order."""
    states = list(states)
    if not states:
        raise ValueError("states: expected at least one bank state")
    first = states[0]
    if any(type(s) is not type(first) for s in states):
        raise TypeError(f"states: expected states of one class, got {sorted({type(s).__name__ for s in states})}")
    changes = {}
    for f in _bank_fields(first):
        values = [getattr(s, f.name) for s in states]
        axis = f.metadata["bank_axis"]
        if any(v is None for v in values):
            changes[f.name] = None
        elif isinstance(values[0], tuple):
            changes[f.name] = tuple(np.concatenate(parts, axis=axis) for parts in zip(*values))
        else:
            changes[f.name] = np.concatenate(values, axis=axis)
    return attrs.evolve(first, **changes, **_reset_fields(first))


def empty_innovation(bank_size: int) -> Innovation:
    """m = 0: no measurement at this step (prediction only)."""
    return Innovation(np.zeros((bank_size, 0)), np.zeros((bank_size, 0, 0)), np.zeros(bank_size), np.zeros(bank_size))


def guarded(method: Callable) -> Callable:
    """Run an estimator's ``predict``/``update`` under ``np.errstate`` (docs/estimators.md, "Numerics"): the inf/NaN
    of an overflow become, through :meth:`BankEstimator.check_finite` (and, for ``update``, the check of the
    returned ℓ and NIS here), a ValueError naming what overflowed."""

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
            result = method(self, *args, **kwargs)
            if isinstance(result, tuple) and len(result) == 2 and isinstance(result[1], Innovation):
                check_innovation_scores(result[1], self.name)
        return result

    return run


def _overflow_message(name: str, what: str, array: np.ndarray, bad: np.ndarray, estimator: str) -> str:
    index = tuple(int(i) for i in np.argwhere(bad)[0])
    finite = np.abs(array[np.isfinite(array)])
    largest = f" (the largest finite |value| is {float(finite.max()):.3g})" if finite.size and finite.max() > 0 else ""
    return (
        f"{name}: the {what} of {estimator!r} has value {float(array[index])} at index {index}{largest}: the values exceed "
        f"the float64 arithmetic of the filter (measurement, prior mean and prior covariance magnitudes up to "
        f"{FILTER_MAGNITUDE_LIMIT:.0e} are processed, but their products at this step overflowed)"
    )


def check_innovation_scores(innovation: Innovation, estimator: str) -> None:
    """ℓ and NIS of an update finite, else a ValueError naming the first non-finite quantity:
    the innovation covariance S, the innovation ν, or the scores themselves."""
    loglik, nis = np.asarray(innovation.loglik, dtype=float).reshape(-1), np.asarray(innovation.nis, dtype=float).reshape(-1)
    if math.isfinite(loglik @ nis):  # one BLAS dot: NaN/inf whenever an entry is (an overflow of the finite dot is searched below)
        return
    for name, what, array in (
        ("innovation", "innovation covariance S", innovation.S),
        ("innovation", "innovation ν = z − ẑ", innovation.nu),
        ("innovation", "NIS νᵀS⁻¹ν", innovation.nis),
        ("innovation", "log-likelihood ℓ (ln det S)", innovation.loglik),
    ):
        bad = ~np.isfinite(np.asarray(array, dtype=float))
        if bad.any():
            raise ValueError(_overflow_message(name, what, np.asarray(array, dtype=float), bad, estimator))


def check_layout(layout: Sequence[str], n: int) -> None:
    """A ValueError naming ``layout`` unless it has one component name per state component (n)."""
    if len(layout) != n:
        raise ValueError(f"layout: expected {n} component names (the state dimension), got {len(layout)}")


class BankEstimator(Estimator):
    """Common plumbing; subclasses implement the maths of one form.

    ``take``/``concatenate`` work on any attrs state whose per-filter arrays
    are :func:`bank_field` s; override :meth:`conform` when states of one
    estimator can come in several forms that must be made alike before joining.
    """

    def __init__(self):
        self.assembler = MeasurementAssembler()
        self._checked_transitions: tuple | None = None

    # ------------------------------------------------------------------ checks
    #: the prior (mean (M, n), cov (M, n, n) positive definite) checked, ValueError naming the argument
    check_prior = staticmethod(check_prior)

    def check_transitions(self, transitions, bank_size: int, n: int, x: np.ndarray | None = None) -> TransitionBank:
        """F (M, n, n), B (M, n), Q (M, n, n) finite; a bank already checked (same object) is not re-checked.

        Extended filters also take a callable linearizing the motion at the current estimate x (M, n)
        (:data:`~hybridtrack.core.interfaces.Transitions`).
        """
        if callable(transitions) and not isinstance(transitions, TransitionBank):
            if not self.accepts_nonlinear:
                raise ValueError(
                    f"transitions: {self.name!r} takes a TransitionBank; a linearizing callable needs an extended filter ('ekf', 'ekf_sqrt')"
                )
            transitions = transitions(x)
            self._checked_transitions = None
        if not isinstance(transitions, TransitionBank):
            raise ValueError(f"transitions: expected a TransitionBank, got {type(transitions).__name__}")
        checked = self._checked_transitions
        if checked is not None and checked[0] is transitions and checked[1] == (bank_size, n):
            return transitions
        as_float_array(transitions.F, "transitions.F", (bank_size, n, n))
        as_float_array(transitions.B, "transitions.B", (bank_size, n))
        as_float_array(transitions.Q, "transitions.Q", (bank_size, n, n))
        if transitions.noise_root is not None:
            as_float_array(transitions.noise_root, "transitions.noise_root", (bank_size, n, None))
        self._checked_transitions = (transitions, (bank_size, n))
        return transitions

    def check_finite(self, stage: str, **arrays: np.ndarray) -> None:
        """The arrays a step produced (keyword: what they are, e.g. ``predicted_covariance=P``) are finite, else a
        ValueError naming the first non-finite quantity, its value and index (``stage``: ``"predict"`` or
        ``"update"``).  One BLAS dot a·a per array (call it inside a :func:`guarded` method); the entries are
        searched only when a dot is not finite (an overflow of the dot on finite entries finds nothing)."""
        for array in arrays.values():
            flat = array.reshape(-1)
            # chunks of ≤ 8192 entries: OpenBLAS threads a longer dot, which stalls on a loaded machine
            if not all(math.isfinite(part @ part) for part in (flat[i : i + 8192] for i in range(0, flat.size, 8192))):
                break
        else:
            return
        for key, array in arrays.items():
            bad = ~np.isfinite(array)
            if bad.any():
                raise ValueError(_overflow_message(stage, key.replace("_", " "), array, bad, self.name))

    #: state fields holding results of the last update besides ``innovation`` (cleared by :meth:`unmeasured`)
    update_results: ClassVar[tuple[str, ...]] = ()

    @guarded
    def update(self, state, z, sensors: Sequence, layout: Sequence[str]):
        """Template: the step's sensor model (:meth:`measurement_step`); nothing measured → :meth:`unmeasured`,
        else :meth:`update_measured` (the form's maths, given the step).  Forms needing more (scans, node copies,
        compiled lanes) override ``update`` and call :meth:`unmeasured` for a step without a measurement."""
        M, n = self.mean(state).shape
        step = self.measurement_step(z, sensors, layout, M, n, state)
        return self.unmeasured(state, M) if step is None else self.update_measured(state, step, z, sensors, layout)

    def update_measured(self, state, step, z, sensors: Sequence, layout: Sequence[str]):
        """(state, Innovation) after a step with a measurement; ``step`` the assembled MeasurementStep."""
        raise NotImplementedError(f"{type(self).__name__}: override update_measured (or update)")

    def unmeasured(self, state, bank_size: int):
        """The one branch every form shares, a step without a measurement: the prediction is the posterior, the
        innovation empty (m = 0, ℓ = 0, NIS = 0)."""
        innovation = empty_innovation(bank_size)
        return attrs.evolve(state, innovation=innovation, **dict.fromkeys(self.update_results)), innovation

    def measurement_step(self, z, sensors: Sequence, layout: Sequence[str], bank_size: int, n: int, state=None):
        """The present sensors' stacked model of this step (:class:`~hybridtrack.sdk.measurements.MeasurementStep`), or None.

        Checks the layout against n and z's shape; NaN components are left
        out (:mod:`hybridtrack.sdk.measurements`); None means nothing was measured.
        A sensor whose R depends on the state gets it at each filter's mean of ``state`` (this estimator's state, or
        the means (M, n) themselves; the predicted state).
        """
        check_layout(layout, n)
        step = self.assembler.assemble(z, sensors, layout, bank_size)
        if step is None or not step.noise_depends_on_state:
            return step
        if state is None:
            names = [m.sensor.name for m in step.models if m.sensor.noise_depends_on_state]
            raise ValueError(f"sensors: the noise of {names} depends on the state, and {self.name!r} did not give its state")
        return step.with_state_noise(state if isinstance(state, np.ndarray) else self.mean(state), layout)

    def linearize(self, x: np.ndarray, z, sensors: Sequence, layout: Sequence[str], step=None):
        """(step, ν, H) at x (M, n), or None when nothing was measured (prediction only).

        ν = residual(z, h(x)) per sensor (angles wrapped), H = ∂h/∂x at x.
        ``step``: the step's :meth:`measurement_step`, when the caller already assembled it.
        """
        M, n = x.shape
        if step is None:
            step = self.measurement_step(z, sensors, layout, M, n, x)
        if step is None:
            return None
        if step.H is None and not self.accepts_nonlinear:
            names = [m.sensor.name for m in step.models if m.H is None]
            raise ValueError(f"sensors: {self.name!r} takes linear sensors only; {names} are nonlinear (use an extended filter)")
        z_pred, H = step.predicted(x, layout)
        return step, step.residual(z_pred), H

    # ------------------------------------------------------------------ bank operations
    def take(self, state: Any, rows: Sequence[int]) -> Any:
        return take_rows(state, rows)

    def concatenate(self, states: Sequence[Any]) -> Any:
        return concatenate_states(self.conform(list(states)))

    def conform(self, states: list) -> list:
        """Bring states of one bank into one form before :meth:`concatenate` (default: as they are)."""
        return states

    # ------------------------------------------------------------------ reading
    def mean(self, state: Any) -> np.ndarray:
        return state.mean

    def covariance(self, state: Any) -> np.ndarray:
        return state.covariance

    def predicted_mean(self, state: Any) -> np.ndarray:
        """x⁻ of the last prediction (M, n)."""
        return state.predicted_mean

    def predicted_covariance(self, state: Any) -> np.ndarray:
        """P⁻ of the last prediction (M, n, n)."""
        return state.predicted_covariance

    def innovation(self, state: Any) -> Innovation | None:
        """ν, S, ℓ, NIS of the last update (None after a prediction)."""
        return state.innovation
