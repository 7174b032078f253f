"""Covariance-form Kalman filter bank (SPEC §3, seed 000 Algorithm 1).

Predict:  x⁻ = F x⁺ + B,  P⁻ = F P⁺ Fᵀ + G Q Gᵀ                       (eqs. 4–5)
Update:   S = H P⁻ Hᵀ + R,  K = P⁻ Hᵀ S⁻¹,  ν = z − H x⁻,  x⁺ = x⁻ + K ν,
          P⁺ = (I − K H) P⁻ (Joseph form by default)                 (eqs. 6–9)
Scores:   ℓ = −½(m ln 2π + ln det S + νᵀS⁻¹ν),  NIS = νᵀS⁻¹ν          (SPEC §4)

All of it over stacked arrays: M filters with their own F, B, Q are one call.
When F, Q, P are block diagonal over equal "axes" and the sensors select one
component per axis with diagonal R (the 4-state modes with position sensors),
the filter runs the exact axis-separable form of ``_separable`` (structure of
arrays, scalar updates); otherwise, or with ``structure=False``, the dense form.
The centralized multisensor filter is this filter given all sensors at once
(H = [H_1; …; H_N], R = blockdiag(R_i), SPEC §2).  ``restart_step`` (the restart lane) starts, predicts and
updates a bank in two compiled passes, each filter with its own missing components (the engine's
``FilterBank.restart_step``: the multiple-model estimators' filters, re-started at every step).
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from functools import cache, cached_property

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack.core.validation import FILTER_MAGNITUDE_LIMIT, SYMMETRY_RTOL
from hybridtrack.sdk.estimation import BankEstimator, CovarianceMoments, bank_field, guarded
from hybridtrack.sdk.measurements import block_diagonal
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters import _separable as sep

#: banks whose compiled predict lane an estimator keeps (irregular sampling alternates between a few Δt)
PREDICT_LANES = 8


@attrs.frozen(eq=False)
class CovarianceState(CovarianceMoments):
    """A bank in covariance form: x (M, n), P (M, n, n), plus the last prediction and innovation."""

    x: np.ndarray = bank_field(0)
    P: np.ndarray = bank_field(0)
    x_predicted: np.ndarray = bank_field(0)
    P_predicted: np.ndarray = bank_field(0)
    innovation: Innovation | None = None
    bank_size = property(lambda self: self.x.shape[0])


@attrs.frozen(eq=False, slots=False)
class AxisState(CovarianceMoments):
    """A bank in axis-separable covariance form: x (d, A, M), P blocks (d, d, A, M) over ``axes``.

    Reads back like :class:`CovarianceState` (``x``, ``P``, ``mean``,
    ``covariance``, ``predicted_*``); the dense arrays are assembled on demand.
    """

    axes: tuple
    n: int
    xa: np.ndarray = bank_field(-1)
    Pa: np.ndarray = bank_field(-1)
    xa_predicted: np.ndarray = bank_field(-1)
    Pa_predicted: np.ndarray = bank_field(-1)
    innovation: Innovation | None = None

    @cached_property
    def _dense(self):
        return sep.from_blocks(self.xa, self.Pa, self.axes, self.n)

    @cached_property
    def _dense_predicted(self):
        if self.xa_predicted is self.xa:
            return self._dense
        return sep.from_blocks(self.xa_predicted, self.Pa_predicted, self.axes, self.n)

    x = property(lambda self: self._dense[0])
    P = property(lambda self: self._dense[1])
    x_predicted = property(lambda self: self._dense_predicted[0])
    P_predicted = property(lambda self: self._dense_predicted[1])
    bank_size = property(lambda self: self.xa.shape[-1])


class KalmanFilter(BankEstimator):
    """Covariance-form Kalman filter bank (Joseph or symmetrised update, Cholesky solves).

    ``form``: ``"joseph"`` (default), ``"symmetric"`` (P⁻ − K S Kᵀ, symmetrised)
    or ``"conventional"`` ((I − K H) P⁻ unsymmetrised, for comparisons only).
    ``structure`` (default True): use the axis-separable fast path when the
    bank, the prior and the sensors allow it (same results to rounding).
    ``engine`` of the dense path: ``"auto"`` (default: the compiled numba kernel
    of ``_kalman_kernel`` for n ≤ 6, m ≤ 3 when numba is installed, numpy
    otherwise), ``"numba"`` (the kernel at every size) or ``"numpy"`` (stacked
    numpy operations, the reference); same results to rounding.
    Linear sensors only; the ``ekf`` estimator takes nonlinear ones.
    """

    name = "kalman"
    #: :meth:`restart_step` takes filters of smaller layouts embedded in the bank's (their transitions map the
    #: components they lack to zero): in the covariance form those stay exactly zero and add exact zeros only
    restart_embeds_layouts = True

    def __init__(self, form: str = "joseph", structure: bool = True, engine: str = "auto"):
        super().__init__()
        if form not in cov_form.UPDATE_FORMS:
            raise ValueError(f"form: expected one of {cov_form.UPDATE_FORMS}, got {form!r}")
        self.engine = cov_form.check_engine(engine)
        self.form = form
        self.structure = bool(structure) and form != "conventional"
        self._split_cache: tuple | None = None
        self._transposed_cache: tuple | None = None
        self._predict_lanes: dict = {}  # id(bank) -> (bank, state form, shape, kernel, operands), the last few banks
        self._lane: _UpdateLane | None = None  # the measurement model of the last update, for the update lane
        self._restart_plans: dict = {}  # (sensor ids, layout) -> (sensors, plan of restart_step)
        self._restart_last: tuple | None = None  # (sensors, layout, plan) of the last restart_step (by identity)

    def dense_engine(self, n: int, m: int = 0) -> str:
        """ "numba" or "numpy": what runs a dense step of state size n and measurement size m under ``engine``."""
        return cov_form.resolve_engine(self.engine, n, m)

    def initialize(self, mean, cov) -> CovarianceState:
        x, P = self.check_prior(mean, cov)
        return CovarianceState(x, P, x, P, None)

    def conform(self, states: list) -> list:
        """Axis-separable states of one layout join as they are; a mix goes to the dense form (exact)."""
        if all(isinstance(s, AxisState) and s.axes == states[0].axes for s in states):
            return states
        return [CovarianceState(s.x, s.P, s.x_predicted, s.P_predicted) if isinstance(s, AxisState) else s for s in states]

    # ------------------------------------------------------------------ predict
    def _split(self, bank: TransitionBank):
        cached = self._split_cache
        if cached is not None and cached[0] is bank:
            return cached[1]
        split = sep.split_bank(bank.F, bank.B, bank.Q)
        self._split_cache = (bank, split)
        return split

    def predict(self, state, transitions: TransitionBank):
        """x⁻ = F x⁺ + B, P⁻ = F P⁺ Fᵀ + Q (eqs. 4–5): the compiled lane when the bank and the state's form and
        shape are those of the last reference prediction (:meth:`_learn_predict_lane`), else (and whenever the
        lane reports a non-finite output) the reference step."""
        lane = self._predict_lanes.get(id(transitions))
        if lane is not None and lane[0] is transitions and type(state) is lane[1]:
            kind, shape, run, args = lane[1], lane[2], lane[3], lane[4]
            if kind is AxisState:
                xa, Pa = state.xa, state.Pa
                if xa.shape == shape and (state.axes is args[0] or state.axes == args[0]):
                    xa_out, Pa_out = np.empty(shape), np.empty(Pa.shape)
                    if not run(xa, Pa, args[1], args[2], args[3], xa_out, Pa_out, args[4]):
                        return AxisState(args[0], state.n, xa_out, Pa_out, xa_out, Pa_out, None)
            else:
                x = state.x
                if x.shape == shape:
                    M, n = shape
                    x_out, P_out = np.empty(shape), np.empty((M, n, n))
                    if not run(x, state.P.reshape(M, n * n), args[0], args[1], args[2], x_out, P_out.reshape(M, n * n), args[3], args[4]):
                        return CovarianceState(x_out, P_out, x_out, P_out, None)
        return self._predict(state, transitions)

    def _learn_predict_lane(self, bank: TransitionBank, result) -> None:
        """After a reference prediction: remember the bank (checked), the form and shape of the result and the
        kernel's operands (the split blocks, or F, B, Q in the filter-blocked layout of
        :func:`._kalman_kernel.lane_blocks`) for the compiled lane of the next ones."""
        lanes = self._predict_lanes
        lanes.pop(id(bank), None)
        if self.engine == "numpy" or not cov_form.NUMBA_AVAILABLE:
            return
        if len(lanes) >= PREDICT_LANES:
            lanes.pop(next(iter(lanes)))  # the oldest
        kernel = cov_form.kernel_module()
        if type(result) is AxisState:
            split = self._split_cache[1]
            d = result.xa.shape[0]
            lanes[id(bank)] = (bank, AxisState, result.xa.shape, kernel.axis_predict, (result.axes, split.F, split.B, split.Q, (0,) * d))
        elif type(result) is CovarianceState and (not self.structure or self._split_cache[1] is None):
            M, n = result.x.shape
            if self.dense_engine(n) != "numba":
                return
            blocks = tuple(kernel.lane_blocks(np.reshape(A, (M, -1))) for A in (bank.F, bank.B, bank.Q))
            lanes[id(bank)] = (bank, CovarianceState, (M, n), kernel.predict_bank_checked, (*blocks, (0,) * n, (0,) * kernel.LANE_WIDTH))
        # else a dense state under structure=True with a separable bank: the reference decides each time

    @guarded
    def _predict(self, state, transitions: TransitionBank):
        M, n = state.bank_size, (state.n if isinstance(state, AxisState) else state.x.shape[1])
        bank = self.check_transitions(
            transitions, M, n, state.mean if callable(transitions) and not isinstance(transitions, TransitionBank) else None
        )
        split = self._split(bank) if self.structure else None
        if split is not None and isinstance(state, AxisState) and state.axes == split.axes:
            blocks = state.xa, state.Pa
        elif split is not None and sep.is_block_diagonal(state.P, split.axes):
            blocks = sep.to_blocks(state.x, state.P, split.axes)
        else:
            blocks = None
        if blocks is not None:
            xa, Pa = sep.predict(*blocks, split)
            self.check_finite("predict", predicted_mean=xa, predicted_covariance=Pa)
            result = AxisState(split.axes, n, xa, Pa, xa, Pa, None)
        else:
            engine = self.dense_engine(n)
            Ft = self._transposed(bank) if engine == "numpy" else None
            x, P = cov_form.predict(state.x, state.P, bank.F, bank.B, bank.Q, Ft, engine=engine)
            self.check_finite("predict", predicted_mean=x, predicted_covariance=P)
            result = CovarianceState(x, P, x, P, None)
        if bank is transitions:  # not a bank linearized for this step (EKF)
            self._learn_predict_lane(bank, result)
        return result

    def _transposed(self, bank: TransitionBank) -> np.ndarray:
        """Fᵀ as a contiguous stack, kept with the bank object like the other per-bank caches."""
        cached = self._transposed_cache
        if cached is not None and cached[0] is bank and cached[1] is bank.F:
            return cached[2]
        Ft = np.ascontiguousarray(np.swapaxes(bank.F, -1, -2))
        self._transposed_cache = (bank, bank.F, Ft)
        return Ft

    # ------------------------------------------------------------------ restart
    def restart_step(self, mean, cov, transitions, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        """A bank started at N(mean, cov) ((M, n), (M, n, n)), predicted with ``transitions`` and updated with each
        filter's own row of z (M, Σm), NaN components not measured in any pattern per row: what ``initialize``,
        ``predict`` and ``update`` (one per missing pattern) give, to rounding, in two compiled passes
        (:func:`._kalman_kernel.restart_predict`, :func:`._kalman_kernel.update_rows`; the state-dependent part of R at
        each x⁻ in between).  Returns (state, ℓ (M,), NIS (M,), measured components (M,)), or None when the lane cannot
        take the step: the numpy engine or no numba, the conventional form, a sensor that is not linear with a
        selection H and an R independent of z, or a check of the reference failing (prior, transitions, z, S
        positive definite, finite outputs), a subclass with its own predict or update — the caller then takes the
        reference steps, which raise its errors."""
        plan = self._restart_plan(sensors, layout)
        if plan is None or type(z) is not np.ndarray or type(mean) is not np.ndarray or type(cov) is not np.ndarray:
            return None
        sel, noise, dependent, offset, span, m_tuple = plan
        M, n = mean.shape
        if n != len(layout) or cov.shape != (M, n, n) or z.shape != (M, sel.size):
            return None
        if callable(transitions) and not isinstance(transitions, TransitionBank):
            if not self.accepts_nonlinear:
                return None
            transitions = transitions(mean)
        if not isinstance(transitions, TransitionBank) or any(
            np.shape(A) != shape for A, shape in ((transitions.F, (M, n, n)), (transitions.B, (M, n)), (transitions.Q, (M, n, n)))
        ):
            return None
        kernel = cov_form.kernel_module()
        x0, P0, F, B, Q = (
            np.ascontiguousarray(A, dtype=float).reshape(M, -1) for A in (mean, cov, transitions.F, transitions.B, transitions.Q)
        )
        x_pred, P_pred = np.empty((M, n)), np.empty((M, n, n))
        n_tuple = (0,) * n
        if kernel.restart_predict(x0, P0, F, B, Q, FILTER_MAGNITUDE_LIMIT, SYMMETRY_RTOL, x_pred, P_pred.reshape(M, n * n), n_tuple):
            return None
        # R(x⁻) = R + the state-dependent blocks at each filter's prediction (MeasurementStep.with_state_noise); the
        # blocks go to the kernel as they come (one sensor) or side by side over their span
        extra = _NO_EXTRA
        if dependent:
            with np.errstate(all="ignore"):
                if len(dependent) == 1:
                    extra = np.ascontiguousarray(dependent[0][0].state_noise(x_pred, layout), dtype=float)
                else:
                    extra = np.zeros((M, span, span))
                    for sensor, block in dependent:
                        extra[:, block, block] = sensor.state_noise(x_pred, layout)
        x, P = np.empty((M, n)), np.empty((M, n, n))
        loglik, nis, dims = np.empty(M), np.empty(M), np.empty(M, dtype=np.intp)
        zc = np.ascontiguousarray(z, dtype=float)
        outputs = (x, P.reshape(M, n * n), loglik, nis, dims)
        if (
            extra.shape[1:] != (span, span)
            or extra.shape[0] not in (1, M)
            or kernel.update_rows(
                x_pred,
                P_pred.reshape(M, n * n),
                zc,
                sel,
                noise,
                extra,
                offset,
                kernel.FORMS[self.form],
                FILTER_MAGNITUDE_LIMIT,
                *outputs,
                n_tuple,
                m_tuple,
            )
        ):
            return None
        return CovarianceState(x, P, x_pred, P_pred, None), loglik, nis, dims

    def _restart_plan(self, sensors, layout):
        """What :meth:`restart_step` needs of the sensors in ``layout``, kept per sensors and layout: the state index
        each stacked z component measures (Σm,), R = blockdiag of the sensors' R (flattened), the sensors whose R
        depends on the state with their blocks relative to the first one, the first one's offset and the blocks'
        span in z, and a tuple of length Σm; None when the lane cannot take them."""
        if isinstance(sensors, Sensor):  # one sensor given alone: the reference step takes it
            return None
        last = self._restart_last
        if last is not None and last[1] is layout and len(last[0]) == len(sensors) and all(map(operator.is_, last[0], sensors)):
            return last[2]
        if (
            self.engine == "numpy"
            or not cov_form.NUMBA_AVAILABLE
            or self.form == "conventional"
            or any(getattr(type(self), name) is not getattr(KalmanFilter, name) for name in ("predict", "_predict", "update", "_update"))
        ):  # a subclass with its own maths (the sigma-point prediction) takes its own steps
            return None
        key = (tuple(map(id, sensors)), tuple(layout))
        cached = self._restart_plans.get(key)
        if cached is not None and all(map(operator.is_, cached[0], sensors)):
            self._restart_last = (tuple(sensors), layout, cached[1])
            return cached[1]
        plan = None
        try:
            models = [self.assembler.sensor_model(s, key[1]) for s in sensors]
        except ValueError:  # the reference step raises it
            models = None
        if models and all(
            mdl.selection is not None and mdl.plain_residual and type(mdl.sensor).measurement_noise is Sensor.measurement_noise
            for mdl in models
        ):
            sel = np.array([i for mdl in models for i in mdl.selection], dtype=np.intp)
            noise = block_diagonal([np.asarray(mdl.sensor.noise_cov, dtype=float) for mdl in models])
            starts = np.cumsum([0] + [mdl.dim for mdl in models])
            blocks = [
                (mdl.sensor, int(a), int(b)) for mdl, a, b in zip(models, starts[:-1], starts[1:]) if mdl.sensor.noise_depends_on_state
            ]
            offset = blocks[0][1] if blocks else 0
            span = blocks[-1][2] - offset if blocks else 0
            dependent = tuple((sensor, slice(a - offset, b - offset)) for sensor, a, b in blocks)
            plan = (sel, np.ascontiguousarray(noise).reshape(-1), dependent, offset, span, (0,) * sel.size)
        if len(self._restart_plans) >= PREDICT_LANES:
            self._restart_plans.pop(next(iter(self._restart_plans)))
        self._restart_plans[key] = (tuple(sensors), plan)
        self._restart_last = (tuple(sensors), layout, plan)
        return plan

    # ------------------------------------------------------------------ update
    def _update_axes(self, state: AxisState, step, plan):
        c, measured, order = plan
        M, m = state.bank_size, step.dim
        z = step.z[:, order].T  # (A_m, 1 or M)
        r = np.diagonal(step.R, axis1=-2, axis2=-1)[..., order]
        r = r[:, None] if r.ndim == 1 else r.T
        xa, Pa, nu_a, s_a, loglik, nis = sep.update(state.xa, state.Pa, c, measured, z, r, self.form)
        nu = np.empty((M, m))
        nu[:, order] = nu_a.T
        S = np.zeros((M, m, m))
        S[:, order, order] = s_a.T
        innovation = Innovation(nu, S, loglik, nis)
        return AxisState(state.axes, state.n, xa, Pa, state.xa_predicted, state.Pa_predicted, innovation), innovation

    def update(self, state, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        """The Kalman update (eqs. 6–9, scores of SPEC §4): the compiled lane when z, the sensors and the layout
        are those the last update learned (:class:`_UpdateLane`), else (and whenever the lane reports a NaN or
        too large z, an S not positive definite or a non-finite output) the reference step, which handles
        missing components and raises the usual errors."""
        lane = self._lane
        if (
            lane is not None
            and type(state) is lane.kind
            and type(z) is np.ndarray
            and z.shape == lane.z_shape
            and z.dtype == np.float64
            and (layout is lane.layout or tuple(layout) == lane.layout)
            and len(sensors) == len(lane.sensors)
            and all(map(operator.is_, sensors, lane.sensors))
        ):
            result = lane.update(state, z)
            if result is not None:
                return result
        return self._update(state, z, sensors, layout)

    def _learn_lane(self, state, z, sensors, layout, step, plan=None):
        """Remember this update's measurement model for the compiled lane when the lane can run it: z a float
        array, every sensor present with all components, linear with a selection H, a constant R (m, m)
        (diagonal and axis-aligned on the separable path), plain residuals, a compiled engine."""
        if (
            self.engine == "numpy"
            or not cov_form.NUMBA_AVAILABLE
            or type(z) is not np.ndarray
            or z.dtype != np.float64
            or isinstance(sensors, Sensor)
            or step.selection is None
            or not step.plain_residual
            or step.R.ndim != 2
            or len(step.models) != len(sensors)
            or any(mdl.rows is not None or type(mdl.sensor).measurement_noise is not Sensor.measurement_noise for mdl in step.models)
        ):
            return
        m = step.dim
        kernel = cov_form.kernel_module()
        if isinstance(state, AxisState):
            if plan is None:
                return
            c, measured, order = plan
            axis_row = np.empty(m, dtype=np.intp)
            axis_row[order] = np.arange(len(state.axes)) if measured is None else measured
            run = kernel.axis_update
            payload = (int(c), axis_row, np.ascontiguousarray(np.diagonal(step.R)), (0,) * state.xa.shape[0], state.axes)
            shape = (state.n, state.bank_size)
        else:
            M, n = state.x.shape
            if self.dense_engine(n, m) != "numba":
                return
            run = kernel.update_bank_blocked  # blocked across filters; the sizes and the form in tuples' lengths
            selection, R = np.array(step.selection, dtype=np.intp), np.ascontiguousarray(step.R, dtype=float).reshape(-1)
            tail = ((0,) * n, (0,) * m, (0,) * (kernel.FORMS[self.form] + 1), (0,) * kernel.LANE_WIDTH)
            payload = ((selection, R, FILTER_MAGNITUDE_LIMIT), tail)
            shape = (M, n)
        self._lane = _UpdateLane(type(state), tuple(sensors), tuple(layout), z.shape, shape, m, run, kernel.FORMS[self.form], payload)

    @guarded
    def _update(self, state, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        """The reference update (dense or axis-separable).  Overflow: :func:`guarded` checks ℓ and NIS, which are
        non-finite whenever S or ν is (x⁺ = x⁻ + K ν is finite for a finite x⁻, ν and positive definite S)."""
        M, n = state.bank_size, (state.n if isinstance(state, AxisState) else state.x.shape[1])
        step = self.measurement_step(z, sensors, layout, M, n, state)
        if step is None:
            return self.unmeasured(state, M)
        if isinstance(state, AxisState):
            plan = _axis_plan(step.selection, state.axes) if step.selection is not None and step.R_diagonal else None
            if plan is not None:
                result = self._update_axes(state, step, plan)
                self._learn_lane(state, z, sensors, layout, step, plan)
                return result
            state = CovarianceState(state.x, state.P, state.x_predicted, state.P_predicted, state.innovation)
        step, nu, H = self.linearize(state.x, z, sensors, layout, step)
        engine = self.dense_engine(n, nu.shape[-1])
        x, P, S, loglik, nis = cov_form.update_scored(state.x, state.P, nu, H, step.R, step.selection, self.form, engine)
        innovation = Innovation(nu, S, loglik, nis)
        self._learn_lane(state, z, sensors, layout, step)
        return CovarianceState(x, P, state.x_predicted, state.P_predicted, innovation), innovation


#: the state-dependent part of R when no sensor has one (:meth:`KalmanFilter.restart_step`)
_NO_EXTRA = np.zeros((1, 0, 0))


@cache
def _axis_plan(selection: tuple[int, ...], axes: tuple) -> tuple | None:
    """How a selection H (the state indices it measures, R diagonal) maps onto the axes, or None if it does not
    separate: needs one row per axis and the same component position c in each measured axis."""
    where = {i: (a, block.index(i)) for a, block in enumerate(axes) for i in block}
    rows = [where[i] for i in selection]
    if len({a for a, _ in rows}) != len(rows) or len({c for _, c in rows}) != 1:
        return None
    order = np.argsort([a for a, _ in rows])  # rows sorted by axis
    measured = np.array(sorted(a for a, _ in rows))
    return rows[0][1], None if len(rows) == len(axes) else measured, order


class _UpdateLane:
    """The measurement model of an update, kept for the next ones: the sensors (by identity), the layout, z's
    shape, the bank's shape and state form, the kernel, the update form's code and the kernel's operands —
    separable: the measured component c, the axis of each z row, the variances r (for the state's axes);
    dense: the operands before the outputs (the selected state indices, R flattened, the magnitude limit) and
    after them (the size, form and block-width tuples)."""

    __slots__ = ("kind", "sensors", "layout", "z_shape", "shape", "m", "run", "form", "payload")

    def __init__(self, kind, sensors, layout, z_shape, shape, m, run, form, payload):
        self.kind, self.sensors, self.layout, self.z_shape, self.shape, self.m = kind, sensors, layout, z_shape, shape, m
        self.run, self.form, self.payload = run, form, payload

    def update(self, state, z: np.ndarray):
        """The compiled update, or None when the kernel reports a step the reference must take (or the bank changed)."""
        m = self.m
        z2 = z.reshape(-1, m)
        if self.kind is AxisState:
            xa, Pa = state.xa, state.Pa
            M = xa.shape[-1]
            c, axis_row, r, d_tuple, axes = self.payload
            if (state.n, M) != self.shape or not (state.axes is axes or state.axes == axes):
                return None
            xa_out, Pa_out = np.empty(xa.shape), np.empty(Pa.shape)
            nu, S, loglik, nis = np.empty((M, m)), np.empty((M, m, m)), np.empty(M), np.empty(M)
            if self.run(xa, Pa, z2, axis_row, c, r, self.form, FILTER_MAGNITUDE_LIMIT, xa_out, Pa_out, nu, S, loglik, nis, d_tuple):
                return None
            innovation = Innovation(nu, S, loglik, nis)
            return AxisState(state.axes, state.n, xa_out, Pa_out, state.xa_predicted, state.Pa_predicted, innovation), innovation
        x = state.x
        if x.shape != self.shape:
            return None
        M, n = self.shape
        head, tail = self.payload
        x_out, P_out = np.empty((M, n)), np.empty((M, n, n))
        nu, S, loglik, nis = np.empty((M, m)), np.empty((M, m, m)), np.empty(M), np.empty(M)
        outputs = (x_out, P_out.reshape(M, n * n), nu, S.reshape(M, m * m), loglik, nis)
        if self.run(x, state.P.reshape(M, n * n), z2, *head, *outputs, *tail):
            return None
        innovation = Innovation(nu, S, loglik, nis)
        return CovarianceState(x_out, P_out, state.x_predicted, state.P_predicted, innovation), innovation


@hookimpl
def register_estimators(registry):
    registry.add(KalmanFilter.name, KalmanFilter)
