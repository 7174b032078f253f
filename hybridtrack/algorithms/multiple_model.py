"""Multiple-model estimators with Markov switching: IMM, GPB1 and GPB2 from one set of parts.

The target's mode is a Markov chain over r motion models with transition
matrix Π, π_ij = P(mode j at k | mode i at k−1) (rows sum to 1), or, given a
mean sojourn time T_i per mode, Π(Δt) = expm(Λ Δt) with the generator
Λ_ii = −1/T_i, Λ_ij = 1/(T_i (r − 1)) (leave mode i at rate 1/T_i, to any
other mode alike).  Each step is built from three parts (Bar-Shalom, Li &
Kirubarajan 2001, *Estimation with Applications to Tracking and Navigation*,
§11.6; Blom & Bar-Shalom 1988, IEEE TAC 33(8)):

1. **Mixing** (what each model-conditioned filter starts from).
   Predicted mode probabilities c̄_j = Σ_i π_ij μ_i; mixing probabilities
   μ_{i|j} = π_ij μ_i / c̄_j; mixed estimate
   x̂_0j = Σ_i μ_{i|j} x̂_i,  P_0j = Σ_i μ_{i|j} (P_i + (x̂_i − x̂_0j)(x̂_i − x̂_0j)ᵀ).
2. **Model-conditioned filtering** with any registered estimator: the filter
   of model j is initialized at (x̂_0j, P_0j), predicted with model j's
   transition and updated with z_k; its innovation gives the likelihood
   Λ_j = N(ν_j; 0, S_j), ln Λ_j = ℓ_j (:class:`~hybridtrack.core.interfaces.Innovation`).
3. **Merging**: μ_j = Λ_j c̄_j / Σ_l Λ_l c̄_l, and the output
   x̂ = Σ_j μ_j x̂_j,  P = Σ_j μ_j (P_j + (x̂_j − x̂)(x̂_j − x̂)ᵀ).

The methods differ in what the filters start from:

* ``"imm"`` — one filter per model, started from its own mixed estimate
  (x̂_0j, P_0j) (Blom & Bar-Shalom 1988; BLK §11.6.6);
* ``"gpb1"`` — one filter per model, every one started from the single
  merged estimate (x̂, P) of the previous step (μ_{i|j} replaced by μ_i;
  BLK §11.6.4);
* ``"gpb2"`` — r² filters, filter (i, j) started from model i's estimate
  (x̂_i, P_i) and run with model j; μ_ij ∝ Λ_ij π_ij μ_i, μ_j = Σ_i μ_ij, and
  model j's estimate merges its r filters with weights μ_ij / μ_j (BLK §11.6.5).

Mode probabilities are kept as logarithms (ln c̄_j and ln μ_j by
log-sum-exp, ln π_ij = −∞ for a forbidden switch), so a model whose
probability falls below the float64 range (e^−745) keeps a finite log
probability over arbitrarily long runs and can recover.

**Turn models** take ω and the turn centre from the estimate each filter
starts from: the transition of model j at step k is
``transition(Δt_k, x̂_0j)`` with x̂_0j its mixed mean (IMM), the merged mean
(GPB1) or x̂_i (GPB2, filter (i, j)), rebuilt every step — a turn of radius r
tangent to the current velocity estimate.  Models whose transition ignores
the switch state (straight, constant acceleration) are unaffected; a
nonlinear model is linearized there (F x̂_0j + B = f(x̂_0j), the EKF prediction).

**Models of different state sizes** (the 6-state ``constant_acceleration``
("x", "vx", "ax", "y", "vy", "ay") with the 4-state ("x", "vx", "y", "vy"))
are mixed and merged in the *union layout* of :mod:`hybridtrack.engine.layouts`
(each component a model lacks at ``missing_mean``, ``missing_variance``), and a
mixed estimate is projected back onto model j's components (the marginal of a
Gaussian: the sub-vector and sub-matrix).  The outputs (means, covariances,
each model's estimate) are in the union layout.

The filters form one :class:`~hybridtrack.engine.bank.FilterBank` of the inner
estimator, grouped by layout (the engine's bank: its transitions, the update
grouped by missing pattern), so a step is one ``initialize``/``predict``/``update`` per
distinct layout over every model and every run (R runs: prior (R, n), measurements (R, K+1, m); one
run is the batch of one) — or, for an estimator with a compiled restart lane (the covariance Kalman filter),
one :meth:`~hybridtrack.engine.bank.FilterBank.restart_step` over every filter of every layout, equal to them
to rounding.  The mixing and the merging of the IMM are :mod:`hybridtrack.engine.mixing` (compiled).  The
inner estimator is re-initialized from the mixed (x̂_0j, P_0j) at every step: a mixture of Gaussians has no
factor form to carry over, so a square-root estimator starts each step from a fresh factor of P_0j.  The
run of a batch builds ln Π(Δt) of all its steps at once and hands every Δt of its runs to the models that
keep their transitions by Δt (``prepare_steps``, an optional extension of the MotionModel protocol).

Step convention (as :class:`~hybridtrack.engine.pipeline.Pipeline`): step 0
updates each model's copy of the prior with z_0 and weighs the models by
μ_j ∝ Λ_j μ_0,j (μ_0 the given initial mode probabilities, no switch before
the first measurement); step k ≥ 1 mixes, predicts over Δt_k and updates.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.algorithms.bank_runs import run_alone
from hybridtrack.algorithms.mode_smoothing import smooth_log_mode_probabilities
from hybridtrack.algorithms.state_smoothing import smooth_models
from hybridtrack.core.interfaces import Estimator, MotionModel, Sensor
from hybridtrack.core.plugins import resolve
from hybridtrack.core.registry import Registry, registry_or_default
from hybridtrack.core.validation import as_float_array, check_positive
from hybridtrack.engine import mixing
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.batch import batch_times, per_run, prior_arrays, stacked_measurements
from hybridtrack.engine.layouts import union_layout
from hybridtrack.engine.pipeline import mode_labels
from hybridtrack.engine.results import RunResult
from hybridtrack.sdk.mixtures import logsumexp, mixture
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import check_tau

METHODS = ("imm", "gpb1", "gpb2")


# --------------------------------------------------------------------------- Markov chain


def markov_matrix(transition_matrix, modes: int) -> np.ndarray:
    """Π (r, r) checked: finite, non-negative, every row summing to 1 (to 1e-9; rows are renormalized)."""
    P = as_float_array(transition_matrix, "transition_matrix", (modes, modes))
    if np.any(P < 0):
        raise ValueError(f"transition_matrix: expected non-negative probabilities, got a minimum of {float(P.min())}")
    sums = P.sum(axis=1)
    bad = np.flatnonzero(np.abs(sums - 1.0) > 1e-9)
    if bad.size:
        raise ValueError(
            f"transition_matrix: row {int(bad[0])} sums to {float(sums[bad[0]])!r}; expected rows π_i· summing to 1 "
            "(π_ij = P(mode j at k | mode i at k−1))"
        )
    return P / sums[:, None]


def sojourn_matrix(sojourn: np.ndarray, dt) -> np.ndarray:
    """Π(Δt) = expm(Λ Δt), Λ_ii = −1/T_i, Λ_ij = 1/(T_i (r − 1)): mean sojourn T_i, equal rates to the others.

    Λ = D A with D = diag(1/T_i) and the symmetric A = (J − r I)/(r − 1) (J all ones), so Λ is similar to the
    symmetric S = D^½ A D^½ = U diag(λ) Uᵀ and expm(Λ Δt) = D^½ U diag(e^{λ Δt}) Uᵀ D^−½ (Moler & Van Loan
    2003, SIAM Review 45(1), method 14, for a matrix similar to a symmetric one): one eigendecomposition for
    every Δt.  ``dt`` one step (→ (r, r)) or an array of steps (D,) (→ (D, r, r)).  Entries are clipped
    at 0 and the rows renormalized against rounding.
    """
    r = sojourn.shape[0]
    steps = np.asarray(dt, dtype=float)
    if r == 1:
        return np.ones(steps.shape + (1, 1))
    root = np.sqrt(1.0 / sojourn)
    A = (np.ones((r, r)) - r * np.eye(r)) / (r - 1)
    lam, U = np.linalg.eigh(root[:, None] * A * root[None, :])
    left, right = root[:, None] * U, U.T / root[None, :]
    P = left @ (np.exp(lam * steps[..., None])[..., :, None] * right)
    P = np.clip(P, 0.0, None)
    return P / P.sum(axis=-1, keepdims=True)


# --------------------------------------------------------------------------- state and result


@attrs.frozen(eq=False)
class MultipleModelState:
    """The estimator between steps, over R runs and r models, everything in the union layout (n).

    ``model_means`` (R, r, n), ``model_covs`` (R, r, n, n): each model's
    estimate x̂_j, P_j (components the model lacks at ``missing_mean`` and
    ``missing_variance``); ``log_mode_probabilities`` (R, r) ln μ_j;
    ``mean`` (R, n), ``cov`` (R, n, n) the combined output;
    ``model_loglik`` (R, r) ln Λ_j of the last update (GPB2: ln Σ_i μ_{i|j} Λ_ij);
    ``loglik`` (R,) ln p(z_k | Z_{k−1}) = ln Σ_j Λ_j c̄_j (0 without a measurement).
    """

    model_means: np.ndarray
    model_covs: np.ndarray
    log_mode_probabilities: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    model_loglik: np.ndarray
    loglik: np.ndarray


@attrs.frozen(eq=False, kw_only=True)
class MultipleModelRun(RunResult):
    """A multiple-model run over steps 0 … K: the :class:`~hybridtrack.engine.results.RunResult` in the union
    ``layout``, ``modes`` the model labels, ``mode`` (K+1,) the most probable model argmax_j μ_j per step, and

    ``method`` (imm, gpb1, gpb2), ``log_mode_probabilities`` (K+1, r) ln μ_j, each model's ``model_means``
    (K+1, r, n), ``model_covs`` (K+1, r, n, n) and ``model_loglik`` (K+1, r) ln Λ_j, the mixture's ``loglik``
    (K+1,) ln p(z_k | Z_{k−1}) (as on :class:`MultipleModelState`).
    """

    method: str
    log_mode_probabilities: np.ndarray
    model_means: np.ndarray
    model_covs: np.ndarray
    model_loglik: np.ndarray
    loglik: np.ndarray

    @property
    def mode_probabilities(self) -> np.ndarray:
        """μ_j per step (K+1, r)."""
        return np.exp(self.log_mode_probabilities)


# --------------------------------------------------------------------------- the estimator


class MultipleModelEstimator:
    """IMM, GPB1 or GPB2 over ``models`` with Markov switching, any registered estimator inside (module docstring).

    ``models``: motion models (objects, registry names or (name, parameters));
    ``transition_matrix`` Π (r, r), π_ij = P(j at k | i at k−1), used as is at
    every step whatever Δt; or ``sojourn`` (seconds, one number or one per
    mode): Π(Δt) = expm(Λ Δt) for each step's Δt (exactly one of the two).
    ``estimator``: the model-conditioned filter (an object or spec, default
    ``"kalman"``).  ``method``: ``"imm"``, ``"gpb1"`` or ``"gpb2"``.
    ``missing_mean`` / ``missing_variance``: the mean and variance a model
    assigns to a union-layout component it lacks (a number for all, or a
    mapping component → value; defaults 0 and 1).
    """

    def __init__(
        self,
        models: Sequence[Any],
        transition_matrix=None,
        *,
        sensors: SensorNetwork | Sequence[Sensor],
        sojourn=None,
        estimator: Any = "kalman",
        method: str = "imm",
        tau: float | None = None,
        missing_mean: float | Mapping[str, float] = 0.0,
        missing_variance: float | Mapping[str, float] = 1.0,
        name: str | None = None,
        registry: Registry | None = None,
    ):
        if method not in METHODS:
            raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
        self.method = method
        registry = registry_or_default(registry)
        if isinstance(models, (str, MotionModel)) or not isinstance(models, Sequence):
            raise TypeError(f"models: expected a sequence of motion models (objects, names or (name, parameters)), got {models!r}")
        self.models: list[MotionModel] = [resolve("motion_model", m, registry) for m in models]
        r = len(self.models)
        if r == 0:
            raise ValueError("models: expected at least one motion model, got an empty sequence")
        self.modes = mode_labels(self.models)
        if (transition_matrix is None) == (sojourn is None):
            raise ValueError("transition_matrix, sojourn: give exactly one (Π of shape (r, r), or the mean sojourn time in seconds)")
        with np.errstate(divide="ignore"):
            self._log_matrix = None if transition_matrix is None else np.log(markov_matrix(transition_matrix, r))
        self._sojourn = None
        if sojourn is not None:
            values = np.broadcast_to(np.asarray(sojourn, dtype=float), (r,)) if np.ndim(sojourn) == 0 else np.asarray(sojourn, float)
            if values.shape != (r,):
                raise ValueError(f"sojourn: expected one mean sojourn time or {r} (one per model), got shape {values.shape}")
            self._sojourn = np.array([check_positive(v, "sojourn") for v in values])
        self._log_matrices: dict[float, np.ndarray] = {}
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.tau = None if tau is None else check_tau(tau)
        self.estimator: Estimator = resolve("estimator", estimator, registry)
        self.name = name or method
        self.layout = union_layout([m.layout for m in self.models])
        self.bank = FilterBank(
            self.estimator, self.layout, self.network.sensors, missing_mean=missing_mean, missing_variance=missing_variance
        )

    def smooth(self, run: MultipleModelRun, lag: float | None = None) -> MultipleModelRun:
        """The run with smoothed mode probabilities (:mod:`hybridtrack.algorithms.mode_smoothing`; fixed interval,
        or fixed lag of ``lag`` seconds): ``log_mode_probabilities`` ln μ_{k|N}, ``mode`` their argmax, ``means`` and
        ``covs`` the models' estimates mixed with them.  Each model's own estimate (``model_means``, ``model_covs``)
        is smoothed by the backward pass of :func:`~hybridtrack.algorithms.state_smoothing.smooth_models`: over the
        whole run (fixed interval, or a lag over the whole run); with a shorter fixed lag L, step k's estimate uses
        the reports up to t_k + L only — the fixed-interval smoother of the run cut at the last step j with
        t_j ≤ t_k + L, run back from j to the first step whose window also ends at j (about L/Δt backward steps
        per step)."""
        times = np.asarray(run.times, dtype=float)
        r = len(self.models)
        log_transitions = np.zeros((times.size, r, r))
        log_transitions[1:] = self.log_transition_matrix(np.diff(times))
        log_mu = smooth_log_mode_probabilities(run.log_mode_probabilities, run.model_loglik, log_transitions, times, lag)
        if lag is None or lag >= times[-1] - times[0]:  # a lag over the whole run is the fixed interval
            model_means, model_covs, means, covs = smooth_models(
                run.model_means, run.model_covs, run.log_mode_probabilities, log_mu, log_transitions, times, self.models, self.layout
            )
        else:
            model_means, model_covs = run.model_means.copy(), run.model_covs.copy()
            last = np.searchsorted(times, times + lag, side="right") - 1  # the window of step k ends at last[k]
            for end in np.unique(last):
                steps = np.flatnonzero(last == end)
                window = slice(int(steps[0]), int(end) + 1)
                log_window = smooth_log_mode_probabilities(
                    run.log_mode_probabilities[window], run.model_loglik[window], log_transitions[window], times[window]
                )
                smoothed_means, smoothed_covs, _, _ = smooth_models(
                    run.model_means[window],
                    run.model_covs[window],
                    run.log_mode_probabilities[window],
                    log_window,
                    log_transitions[window],
                    times[window],
                    self.models,
                    self.layout,
                )
                model_means[steps], model_covs[steps] = smoothed_means[steps - steps[0]], smoothed_covs[steps - steps[0]]
            means, covs = mixture(log_mu, model_means, model_covs)
        return attrs.evolve(
            run,
            log_mode_probabilities=log_mu,
            mode=np.argmax(log_mu, axis=1),
            means=means,
            covs=covs,
            model_means=model_means,
            model_covs=model_covs,
        )

    # ------------------------------------------------------------------ Markov chain
    def log_transition_matrix(self, dt) -> np.ndarray:
        """ln Π (−∞ for a forbidden switch) for one step of ``dt`` seconds (→ (r, r)) or steps (R,) (→ (R, r, r));
        the Δt not seen before are computed in one expm call."""
        if type(dt) is list and len(dt) == 1 and type(dt[0]) is float and self._log_matrix is None:  # one step seen before
            known = self._log_matrices.get(dt[0])
            if known is not None:
                return known[None]
        steps = np.asarray(dt, dtype=float)
        if self._log_matrix is not None:
            return np.broadcast_to(self._log_matrix, steps.shape + self._log_matrix.shape)
        keys = [float(d) for d in steps.reshape(-1)]
        new = sorted({key for key in keys if key not in self._log_matrices})
        if new:
            with np.errstate(divide="ignore"):
                self._log_matrices.update(zip(new, np.log(sojourn_matrix(self._sojourn, np.array(new)))))
        r = len(self.models)
        return np.stack([self._log_matrices[key] for key in keys]).reshape(steps.shape + (r, r))

    # ------------------------------------------------------------------ the parts
    def _filter(self, start_means, start_covs, filter_models: np.ndarray, dt, z: np.ndarray):
        """Model-conditioned filtering of F filters per run: start (R, F, n) in the union layout (or (R, n), one
        start for all F), filter f runs model ``filter_models[f]``; predict over ``dt`` (seconds, one for all runs or (R,) per run; None: update
        only) and update with z (R, Σm), the engine's :class:`~hybridtrack.engine.bank.FilterBank` (grouped by
        layout) re-started at the starts (its transitions built there: a turn's ω and centre from x̂_0j).  Returns
        the posteriors (R, F, n), (R, F, n, n) in the union layout and ℓ (R, F)."""
        (R, n), F = (start_means.shape[0], start_means.shape[-1]), len(filter_models)
        if start_means.ndim == 2:
            start_means, start_covs = start_means[:, None], start_covs[:, None]
        x0 = (start_means if start_means.shape == (R, F, n) else np.broadcast_to(start_means, (R, F, n))).reshape(R * F, n)
        P0 = (start_covs if start_covs.shape == (R, F, n, n) else np.broadcast_to(start_covs, (R, F, n, n))).reshape(R * F, n, n)
        models = [self.models[f] for f in filter_models] * R
        P0, runs = 0.5 * (P0 + np.swapaxes(P0, -1, -2)), np.repeat(np.arange(R), F)
        done = self.bank.restart_step(x0, P0, models, x0, runs, dt, z)  # the compiled lane, if the estimator has one
        if done is not None:
            return done.means.reshape(R, F, n), done.covs.reshape(R, F, n, n), done.loglik.reshape(R, F)
        self.bank.start(x0, P0, models, x0, runs)
        loglik = self.bank.step(dt, z).loglik.reshape(R, F)
        return np.array(self.bank.means).reshape(R, F, n), self.bank.covs.reshape(R, F, n, n), loglik

    def _merge(self, model_means, model_covs, joint, model_loglik) -> MultipleModelState:
        """Merging: ln μ_j = joint_j − ln Σ_l exp(joint_l) (joint_j = ln Λ_j c̄_j), the output x̂, P mixed by μ_j,
        ln p(z_k | Z_{k−1}) = ln Σ_l exp(joint_l)."""
        log_mu, total, mean, cov = mixing.merge(joint, model_means, model_covs)
        return MultipleModelState(model_means, model_covs, log_mu, mean, cov, model_loglik, total)

    # ------------------------------------------------------------------ steps
    def start(self, prior_mean, prior_cov, z0, mode_probabilities=None, prior_layout: Sequence[str] | None = None) -> MultipleModelState:
        """Step 0: every model's copy of the prior (R, n) updated with z0 (R, Σm); μ_j ∝ Λ_j μ_0,j."""
        r = len(self.models)
        mean = np.asarray(prior_mean, dtype=float)
        cov = np.asarray(prior_cov, dtype=float)
        layout = self._prior_layout(mean.shape[-1], prior_layout)
        x, P = self.bank.fill.expand(mean, cov, self.bank.fill.positions(layout))
        if mode_probabilities is None:
            log_mu0 = np.full(r, -np.log(r))
        else:
            mu0 = as_float_array(mode_probabilities, "mode_probabilities", (r,))
            if np.any(mu0 < 0) or abs(mu0.sum() - 1.0) > 1e-9:
                raise ValueError(f"mode_probabilities: expected {r} non-negative probabilities summing to 1, got {mu0.tolist()}")
            with np.errstate(divide="ignore"):
                log_mu0 = np.log(mu0 / mu0.sum())
        means, covs, ell = self._filter(x, P, np.arange(r), None, z0)
        return self._merge(means, covs, ell + log_mu0, ell)

    def step(self, state: MultipleModelState, z: np.ndarray, dt, log_pi: np.ndarray | None = None) -> MultipleModelState:
        """One step k ≥ 1 over Δt = ``dt`` (seconds, one for all runs or (R,) per run) with measurements z (R, Σm)
        (NaN: not measured); ``log_pi``: ln Π(Δt) (1 or R, r, r) if the caller has it (:meth:`log_transition_matrix`)."""
        r = len(self.models)
        if r == 1:  # one model: no mixing, μ = 1 (every method reduces to the model's own filter)
            return self._one_model(state, dt, z)
        if log_pi is None:
            log_pi = self.log_transition_matrix(dt if np.ndim(dt) else [dt])  # ln Π(Δt_r): (1, r, r) shared or (R, r, r)
        log_mu = state.log_mode_probabilities
        if self.method == "imm":
            # model j starts from the mixture of the models i with μ_{i|j} ∝ π_ij μ_i, and ln c̄_j (compiled)
            log_cbar, starts_x, starts_P = mixing.mix(log_pi, log_mu, state.model_means, state.model_covs)
            means, covs, ell = self._filter(starts_x, starts_P, np.arange(r), dt, z)
            return self._merge(means, covs, ell + log_cbar, ell)
        joint_prior = log_pi + log_mu[:, :, None]  # ln π_ij μ_i, (R, i, j)
        log_cbar = logsumexp(joint_prior, axis=1)  # ln c̄_j (R, j)
        if self.method == "gpb2":
            R, n = state.mean.shape
            starts_x = np.repeat(state.model_means, r, axis=1)  # filter (i, j) at row i·r + j starts from model i
            starts_P = np.repeat(state.model_covs, r, axis=1)
            x, P, ell = self._filter(starts_x, starts_P, np.tile(np.arange(r), r), dt, z)
            ell = ell.reshape(R, r, r)
            joint = joint_prior + ell  # ln π_ij μ_i Λ_ij
            log_mu_j = logsumexp(joint, axis=1)
            # model j merges its filters (i, j) with weights μ_ij / μ_j over i
            means, covs = mixture(
                np.swapaxes(joint, 1, 2), np.swapaxes(x.reshape(R, r, r, n), 1, 2), np.swapaxes(P.reshape(R, r, r, n, n), 1, 2)
            )
            return self._merge(means, covs, log_mu_j, np.where(np.isfinite(log_cbar), log_mu_j - log_cbar, 0.0))
        # gpb1: every filter starts from the merged estimate
        means, covs, ell = self._filter(state.mean, state.cov, np.arange(r), dt, z)
        return self._merge(means, covs, ell + log_cbar, ell)

    def update(self, state: MultipleModelState, z: np.ndarray) -> MultipleModelState:
        """The measurement update alone of a predicted ``state`` (a :meth:`step` without a measurement): each model's
        x̂_j, P_j updated with z (R, Σm), ln μ_j ← ln μ_j + ln Λ_j − ln Σ_l μ_l Λ_l (Bar-Shalom, Li & Kirubarajan
        2001, §11.6.6, the mode-probability update).  For the IMM (and one model) :meth:`step` (z) equals this
        update of :meth:`step` (NaN) — the mixing and the prediction do not depend on z — so a caller that needs the
        prediction first (a tracker gating detections) pays for the prediction once.  GPB1/GPB2 merge before they
        update, so for them it is not their step: a ValueError."""
        if self.method != "imm" and len(self.models) > 1:
            raise ValueError(f"update: the measurement update of a prediction is the IMM's step, not {self.method!r}'s; use step")
        r = len(self.models)
        if r == 1:
            return self._one_model(state, None, z)
        means, covs, ell = self._filter(state.model_means, state.model_covs, np.arange(r), None, z)
        return self._merge(means, covs, ell + state.log_mode_probabilities, ell)

    def _one_model(self, state: MultipleModelState, dt, z) -> MultipleModelState:
        """A step (``dt``; None: the update alone) of a one-model estimator: its filter, ln μ = 0, the output the
        model's estimate, ln p(z_k | Z_{k−1}) = ln Λ — the mixing and merging of r = 1, without them."""
        means, covs, ell = self._filter(state.model_means, state.model_covs, np.zeros(1, dtype=np.intp), dt, z)
        return MultipleModelState(means, covs, np.zeros_like(ell), means[:, 0], covs[:, 0], ell, ell[:, 0])

    def _prior_layout(self, n: int, prior_layout) -> tuple[str, ...]:
        if prior_layout is not None:
            layout = tuple(prior_layout)
            missing = sorted(set(layout) - set(self.layout))
            if missing:
                raise ValueError(f"prior_layout: components {missing} are in no model's layout {self.layout}")
            if len(layout) != n:
                raise ValueError(f"prior_layout: {len(layout)} components for a prior mean of {n}")
            return layout
        if n == len(self.layout):
            return self.layout
        for m in self.models:
            if m.state_dim == n:
                return tuple(m.layout)
        raise ValueError(f"prior: mean of {n} components matches neither the union layout {self.layout} nor a model's layout")

    # ------------------------------------------------------------------ the run
    def run(
        self,
        measurements: Mapping[str, np.ndarray],
        prior,
        *,
        times=None,
        mode_probabilities=None,
        prior_layout: Sequence[str] | None = None,
        recorder=None,
        truth=None,
    ) -> MultipleModelRun:
        """One run: :meth:`run_batch` of one, ``measurements`` sensor name → (K+1, m) at ``times`` (K+1,)
        (seconds; default 0, τ, 2τ, …); ``recorder`` gets the finished run (``recorder.log_result``)."""
        options = dict(times=times, recorder=recorder, truth=truth, mode_probabilities=mode_probabilities, prior_layout=prior_layout)
        return run_alone(self, measurements, prior, **options)

    def run_batch(
        self,
        measurements: Mapping[str, np.ndarray],
        prior,
        *,
        times=None,
        truth=None,
        recorders=None,
        mode_probabilities=None,
        prior_layout: Sequence[str] | None = None,
        lengths: Sequence[int] | None = None,
    ) -> list[MultipleModelRun]:
        """R runs vectorized over runs × models, one :class:`MultipleModelRun` per run (the inputs as
        :func:`~hybridtrack.algorithms.bank_runs.run_banks` takes them; all runs in one bank, each recorded run
        handed to ``recorder.log_result``).

        ``prior`` is in the union layout or a model's layout (``prior_layout``
        names it when ambiguous); ``mode_probabilities``: μ_0 (r,), default uniform.
        ``lengths`` (R,): run r's own steps, 1 … K+1 (default K+1 for all); the rows after them (the padding of a
        ragged batch, :func:`~hybridtrack.algorithms.bank_runs.run_ragged`) are neither filtered nor returned: a run
        leaves the bank after its last step (each run's arithmetic is its own, so the others are unchanged).
        """
        z = stacked_measurements(self.network, measurements)
        R, steps = z.shape[:2]
        T, DT = batch_times(times, self.tau, R, steps)
        truths, recorders = per_run(truth, R, "truth"), per_run(recorders, R, "recorders")
        mean, cov = prior_arrays(prior, R)
        lengths = _run_lengths(lengths, R, steps)
        # the runs longest first, so that the runs still going at step k are the first ones of the bank
        order = np.argsort(-lengths, kind="stable")
        going = R - np.searchsorted(np.sort(lengths), np.arange(steps), side="right")  # the runs with lengths > k
        zs, DTs = z[order], DT[order]
        state = self.start(mean[order], cov[order], zs[:, 0], mode_probabilities, prior_layout)
        fields = attrs.fields_dict(MultipleModelState)
        # the runs' steps back to back (longest first, as the bank holds them): run i of the order at rows first[i] …
        first = np.concatenate([[0], np.cumsum(lengths[order])[:-1]]).astype(np.intp)
        out = {name: np.empty((int(lengths.sum()),) + getattr(state, name).shape[1:]) for name in fields}
        same = bool((DT == DT[:1]).all())
        if not same and steps > 1:  # ln Π(Δt) of every step at once: one table row per distinct Δt
            distinct, which = np.unique(DTs, return_inverse=True)
            table, which = self.log_transition_matrix(distinct), which.reshape(DTs.shape)
        if steps > 1:  # models that keep their transitions by Δt build those of every step at once (optional)
            used = DT[np.arange(steps - 1)[None, :] < (lengths - 1)[:, None]]
            for model in {id(m): m for m in self.models}.values():
                prepare = getattr(model, "prepare_steps", None)
                if callable(prepare):
                    prepare(used)
        for k in range(steps):
            if k:
                A = int(going[k])
                if A < state.mean.shape[0]:  # runs that ended leave the bank
                    state = MultipleModelState(*(getattr(state, name)[:A] for name in fields))
                if same:
                    state = self.step(state, zs[:A, k], float(DTs[0, k - 1]))
                else:
                    state = self.step(state, zs[:A, k], DTs[:A, k - 1], table[which[:A, k - 1]])
            rows = first[: state.mean.shape[0]] + k
            for name in fields:
                out[name][rows] = getattr(state, name)
        where = np.empty(R, dtype=np.intp)
        where[order] = np.arange(R)
        own = ("log_mode_probabilities", "model_means", "model_covs", "model_loglik", "loglik")
        runs = []
        for r in range(R):
            L, i = int(lengths[r]), first[where[r]]
            field = {name: out[name][i : i + L] for name in fields}
            runs.append(
                MultipleModelRun(
                    layout=self.layout,
                    modes=self.modes,
                    times=T[r, :L],
                    means=field["mean"],
                    covs=field["cov"],
                    mode=np.argmax(field["log_mode_probabilities"], axis=-1),
                    method=self.method,
                    **{name: field[name] for name in own},
                )
            )
        for r, recorder in enumerate(recorders):
            if recorder is not None:
                measured = self.network.split(z[r, : int(lengths[r])])
                recorder.log_result(runs[r], name=self.name, sensors=self.network.sensors, measurements=measured, truth=truths[r])
        return runs


def _run_lengths(lengths, runs: int, steps: int) -> np.ndarray:
    """``lengths`` as (R,) integers in 1 … K+1 (None: K+1 for every run), else a ValueError naming it."""
    if lengths is None:
        return np.full(runs, steps, dtype=np.intp)
    values = np.asarray(lengths)
    if values.shape != (runs,) or values.dtype.kind not in "iu" or (values < 1).any() or (values > steps).any():
        raise ValueError(f"lengths: expected {runs} integers in 1 … {steps} (each run's steps), got {lengths!r}")
    return values.astype(np.intp)
