"""Gaussian-sum filter bank: each filter a weighted mixture of EKF components (Sorenson & Alspach 1971).

Each of the M filters of the bank carries C Gaussian components
(x_c (M, C, n), P_c (M, C, n, n), ln w_c (M, C), Σ_c w_c = 1); a slot with
ln w_c = −∞ is empty (banks whose filters hold different numbers of
components share one array width C).

* Predict, component by component as an EKF (:mod:`._covariance`,
  seed 000 eqs. 4–5; a linearizing ``transitions`` callable is evaluated at
  each component mean, F = ∂f/∂x(x_c), B = f(x_c) − F x_c):
  x_c⁻ = F_c x_c + B_c, P_c⁻ = F_c P_c F_cᵀ + Q; the weights are unchanged.
* Update, component by component (ẑ_c = h(x_c⁻), H_c = ∂h/∂x(x_c⁻),
  ν_c = residual(z, ẑ_c) with angles wrapped, S_c = H_c P_c⁻ H_cᵀ + R, Joseph
  update by default) and the weights by Bayes' rule in log space:
  ℓ_c = ln N(ν_c; 0, S_c),  ℓ = ln Σ_c w_c⁻ N(ν_c; 0, S_c) = logsumexp_c(ln w_c⁻ + ℓ_c),
  ln w_c⁺ = ln w_c⁻ + ℓ_c − ℓ (Alspach & Sorenson 1972, eq. 16; SPEC §4 for ℓ_c).
  ℓ is the mixture's predictive log-likelihood ln p(z_k | z_1:k−1).  The
  reported innovation is the moment-matched one of that predictive density:
  ν = Σ_c w_c⁻ ν_c, S = Σ_c w_c⁻ (S_c + (ν_c − ν)(ν_c − ν)ᵀ), NIS = νᵀS⁻¹ν
  (ℓ is *not* the Gaussian score of (ν, S) when C > 1).
* Reduction after each update: pruning (components with w_c < ``prune_threshold``
  dropped, the heaviest always kept), merging (greedy, heaviest first: every
  component j with d²_ij = (x_j − x_i)ᵀ P_i⁻¹ (x_j − x_i) ≤ ``merge_threshold``
  joins the leader i, the cluster replaced by its moment-matched Gaussian
  W = Σ w_j, x̄ = Σ w_j x_j / W, P̄ = Σ w_j (P_j + (x_j − x̄)(x_j − x̄)ᵀ) / W —
  Salmond 1990's joining of close components, the Mahalanobis criterion of
  Vo & Ma 2006 (GM-PHD, Table II); Runnalls 2007 shows the moment-matched merge
  is the KL-optimal one), then at most ``max_components`` kept (the heaviest),
  and the weights renormalised.
* Read-out: mean = Σ_c w_c x_c, covariance = Σ_c w_c (P_c + (x_c − x̄)(x_c − x̄)ᵀ)
  (the moment-matched mixture); one component is exactly the EKF.

* In clutter (``accepts_scans``: ``z`` a :class:`~hybridtrack.sdk.scans.Scan` or a
  sequence of them; linear sensors with a constant R): the exact Bayes update of
  a Gaussian mixture on a scan is again a mixture — every component c branches
  into a "missed" child (x_c⁻, P_c⁻, weight ∝ w_c (1 − P_D P_G)) and one child per
  gated candidate r (the Kalman update with ν_cr, weight ∝ w_c (P_D/λ) N(ν_cr; 0, S_c)),
  Salmond 1990 ("Mixture reduction algorithms for target tracking in clutter",
  Proc. SPIE 1305) — which the reduction above brings back to at most
  ``max_components``.  ℓ = ln Σ_c w_c⁻ [(1 − P_D P_G) + (P_D/λ) Σ_r N(ν_cr; 0, S_c)],
  the mixture's PDA association likelihood ln Λ (for λ = 0 the λ-factor is
  left out, and the miss term too when a candidate is gated, as in PDA).  The
  gate γ (P(χ²_m ≤ γ) = P_G) is per component; the association record holds the
  mixture's ẑ, S (moment-matched), β_r = Σ_c (weight of the children of r),
  β_0 = Σ_c (weight of the missed children).  One component, P_D = 1, λ = 0, no
  gate and one candidate: the Kalman update.

:func:`range_parameterised` builds the range-parameterised initial mixture for
bearings-only tracking (Peach 1995; Arulampalam & Ristic 2000).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack.core.protocols import Association, ClutterInnovation
from hybridtrack.core.validation import as_float_array, check_positive, check_positive_int, check_prior, check_prior_mixture
from hybridtrack.sdk.estimation import BankEstimator, bank_field, check_layout, guarded
from hybridtrack.sdk.linalg import CholeskyFactor, cholesky, forward_substitute
from hybridtrack.sdk.mixtures import logsumexp, mixture, moment_match, normalized_weights
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters._association import (
    as_scans,
    candidate_residuals,
    distances,
    gate_threshold,
    log_half_det_2pi_s,
    pad_axis,
    scan_by_scan,
    set_clutter_model,
    stacked_innovation,
    summed_loglik,
)
from hybridtrack_plugins.filters.clutter_recording import RecordsFilterStates
from hybridtrack_plugins.sensors.bearing import check_convention, direction

_LAYOUT = ("x", "vx", "y", "vy")


@attrs.frozen(eq=False)
class MixtureState:
    """A Gaussian-sum bank: components x (M, C, n), P (M, C, n, n), ln w (M, C) (−∞: empty slot),
    the moment-matched mean (M, n) / covariance (M, n, n) and those of the last prediction."""

    x: np.ndarray = bank_field(0)
    P: np.ndarray = bank_field(0)
    log_weights: np.ndarray = bank_field(0)
    mean: np.ndarray = bank_field(0)
    covariance: np.ndarray = bank_field(0)
    predicted_mean: np.ndarray = bank_field(0)
    predicted_covariance: np.ndarray = bank_field(0)
    innovation: Innovation | None = None

    @property
    def component_count(self) -> np.ndarray:
        """Number of occupied components per filter (M,)."""
        return np.isfinite(self.log_weights).sum(axis=1)


def _compact(x, P, log_weights):
    """Sort every filter's components by weight (heaviest first), trim the common width to the largest
    occupied count, and fill empty slots with a copy of the filter's heaviest component (finite arithmetic)."""
    width = max(int(np.isfinite(log_weights).sum(axis=1).max()), 1)
    kept = np.arange(x.shape[0])[:, None], np.argsort(-log_weights, axis=1, kind="stable")[:, :width]
    x, P, log_weights = x[kept], P[kept], log_weights[kept]
    empty = ~np.isfinite(log_weights)
    return np.where(empty[..., None], x[:, :1], x), np.where(empty[..., None, None], P[:, :1], P), log_weights


class GaussianSumFilter(RecordsFilterStates, BankEstimator):
    """Gaussian-sum (weighted bank of EKF components) filter bank.

    ``merge_threshold`` (default 4.0): components within this squared
    Mahalanobis distance d² of a heavier one are merged into it (``None``: no merging);
    ``prune_threshold`` (default 1e-5): weights below it are dropped;
    ``max_components`` (default 16): cap on the components per filter;
    ``form``/``engine``: the component update of :mod:`._covariance`
    (``"joseph"``, numpy/numba as the ``kalman`` estimator).  For scans
    (clutter): ``detection_probability`` P_D in (0, 1], ``clutter_density`` λ ≥ 0,
    ``gate_probability`` P_G in (0, 1) or None (no gate).
    """

    name = "gaussian_sum"
    exact_kalman = False
    accepts_nonlinear = True
    accepts_scans = True

    def __init__(
        self,
        merge_threshold: float | None = 4.0,
        prune_threshold: float = 1e-5,
        max_components: int = 16,
        form: str = "joseph",
        engine: str = "auto",
        detection_probability: float = 1.0,
        clutter_density: float = 0.0,
        gate_probability: float | None = 0.99,
    ):
        super().__init__()
        set_clutter_model(self, detection_probability, clutter_density, gate_probability)
        self.merge_threshold = None if merge_threshold is None else float(merge_threshold)
        if self.merge_threshold is not None and not (math.isfinite(self.merge_threshold) and self.merge_threshold >= 0):
            raise ValueError(f"merge_threshold: expected a finite squared Mahalanobis distance ≥ 0 or None, got {self.merge_threshold!r}")
        self.prune_threshold = float(prune_threshold)
        if not (0.0 <= self.prune_threshold < 1.0):
            raise ValueError(f"prune_threshold: expected a weight in [0, 1), got {self.prune_threshold!r}")
        self.max_components = check_positive_int(max_components, "max_components")
        if form not in cov_form.UPDATE_FORMS:
            raise ValueError(f"form: expected one of {cov_form.UPDATE_FORMS}, got {form!r}")
        self.form = form
        self.engine = cov_form.check_engine(engine)

    def initialize(self, mean, cov) -> MixtureState:
        """One component per filter (weight 1): the EKF's prior."""
        x, P = check_prior(mean, cov)
        return self._state(x[:, None], P[:, None], np.zeros((x.shape[0], 1)))

    def initialize_mixture(self, means, covs, weights) -> MixtureState:
        """A prior mixture per filter: means (M, C, n), covs (M, C, n, n) positive definite, weights (M, C) ≥ 0
        (each row with a positive sum; renormalised; zero weights are empty slots)."""
        means, covs, weights, total = check_prior_mixture(means, covs, weights)
        with np.errstate(divide="ignore"):
            log_weights = np.log(weights / total[:, None])
        return self._state(*_compact(means, covs, log_weights))

    @staticmethod
    def _state(x, P, log_weights, prior: MixtureState | None = None, innovation=None) -> MixtureState:
        """The state of the components (x, P, ln w); the prediction is ``prior``'s, or the mixture itself."""
        mean, cov = mixture(log_weights, x, P)
        pm, pc = (mean, cov) if prior is None else (prior.predicted_mean, prior.predicted_covariance)
        return MixtureState(x, P, log_weights, mean, cov, pm, pc, innovation)

    def conform(self, states: list) -> list:
        """Pad every state to the widest component count with empty slots (ln w = −∞, copies of component 0)."""
        width = max(s.x.shape[1] for s in states)

        def widen(a):
            return np.concatenate([a, np.repeat(a[:, :1], width - a.shape[1], axis=1)], axis=1)

        return [attrs.evolve(s, x=widen(s.x), P=widen(s.P), log_weights=pad_axis(s.log_weights, 1, width, -np.inf)) for s in states]

    @guarded
    def predict(self, state: MixtureState, transitions) -> MixtureState:
        """Every component predicted as an EKF; a linearizing callable is evaluated at each component mean."""
        M, C, n = state.x.shape
        if callable(transitions) and not isinstance(transitions, TransitionBank):
            banks = [self.check_transitions(transitions, M, n, state.x[:, c]) for c in range(C)]
            F, B, Q = (np.stack([getattr(b, k) for b in banks], axis=1).reshape((M * C,) + getattr(banks[0], k).shape[1:]) for k in "FBQ")
        else:
            bank = self.check_transitions(transitions, M, n)
            F, B, Q = (np.repeat(getattr(bank, k), C, axis=0) for k in "FBQ")
        engine = cov_form.resolve_engine(self.engine, n)
        x, P = cov_form.predict(state.x.reshape(M * C, n), state.P.reshape(M * C, n, n), F, B, Q, engine=engine)
        x, P = x.reshape(M, C, n), P.reshape(M, C, n, n)
        self.check_finite("predict", predicted_mean=x, predicted_covariance=P)
        return self._state(x, P, state.log_weights)

    @guarded
    def update(self, state: MixtureState, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        """Component-wise EKF updates, Bayes weights in log space, then pruning and merging (module docstring)."""
        M, C, n = state.x.shape
        scans = as_scans(z)
        if scans is not None or (isinstance(z, (list, tuple)) and len(z) == 0):
            return self._update_scans(state, scans or [], sensors, layout)
        z = np.asarray(z, dtype=float)
        z_rows = np.repeat(z, C, axis=0) if z.ndim == 2 else z  # one row per component
        found = self.linearize(state.x.reshape(M * C, n), z_rows, sensors, layout)
        if found is None:
            return self.unmeasured(state, M)
        step, nu, H = found
        engine = cov_form.resolve_engine(self.engine, n, nu.shape[-1])
        x, P, S, loglik_c, _ = cov_form.update_scored(
            state.x.reshape(M * C, n), state.P.reshape(M * C, n, n), nu, H, step.R, step.selection, self.form, engine
        )
        x, P, nu, S, loglik_c = (a.reshape((M, C) + a.shape[1:]) for a in (x, P, nu, S, loglik_c))
        joint = state.log_weights + loglik_c
        loglik = logsumexp(joint, axis=-1)
        log_weights = joint - loglik[:, None]
        # the moment-matched predictive innovation (prior weights)
        nu_mix, S_mix = moment_match(np.exp(state.log_weights), nu, S)
        _, nis = CholeskyFactor(S_mix, "mixture innovation covariance S").scores(nu_mix)
        innovation = Innovation(nu_mix, S_mix, loglik, nis)
        x, P, log_weights = self.reduce(x, P, log_weights)
        self.check_finite("update", updated_mean=x, updated_covariance=P)
        return self._state(x, P, log_weights, state, innovation), innovation

    def _update_scans(self, state: MixtureState, scans: list, sensors, layout):
        """Branch every component on each scan (missed + one child per gated candidate), then reduce (module docstring)."""
        M, _, n = state.x.shape
        check_layout(layout, n)
        mixture = (state.x, state.P, state.log_weights)
        (x, P, log_weights), used, blocks, records = scan_by_scan(self, mixture, scans, sensors, layout, self._branch)
        nu, S, _, nis = stacked_innovation(M, used, blocks, factored=True)
        innovation = ClutterInnovation(nu, S, summed_loglik(records, M), nis, tuple(records))
        self.check_finite("update", updated_mean=x, updated_covariance=P)
        return self._state(x, P, log_weights, state, innovation), innovation

    def _branch(self, mixture, scan, sensor, model):
        """One scan: the children x (M, C(1+L), n), P, ln w (normalised) of the mixture (x, P, ln w), reduced;
        the combined ν, S and the Association (ln Λ (M,) its ``loglik``)."""
        x, P, log_weights = mixture
        M, C, n = x.shape
        L, m = scan.z.shape
        H, R = model.H, np.asarray(sensor.noise_cov, dtype=float)
        flat_x, flat_P = x.reshape(M * C, n), P.reshape(M * C, n, n)
        z_pred = flat_x @ H.T  # (MC, m)
        # the Kalman update of every component (ν = 0 gives the gain and P⁺; the children add K ν_cr)
        _, P_new, S_c, chol_c, K = cov_form.update(flat_x, flat_P, np.zeros((M * C, m)), H, R, model.selection, self.form)
        nu = np.asarray(candidate_residuals(z_pred, scan.z, sensor, model))  # (MC, L, m)
        d2 = distances(nu, chol_c)  # (MC, L)
        gamma = gate_threshold(self.gate_probability, m)
        gated = d2 <= gamma
        half = log_half_det_2pi_s(chol_c)  # ln √|2πS_c|
        child_detect = np.where(gated, self.log_detect - half[:, None] - 0.5 * d2, -np.inf).reshape(M, C, L)
        any_gated = gated.reshape(M, C * L).any(axis=1) if L else np.zeros(M, dtype=bool)
        miss = np.where(
            (self.clutter_density > 0) | ~any_gated, self.log_miss, -np.inf
        )  # λ = 0 and a candidate gated: no miss term (as PDA)
        terms = np.concatenate([np.broadcast_to(miss[:, None, None], (M, C, 1)), child_detect], axis=2)  # (M, C, 1 + L)
        joint = log_weights[:, :, None] + terms
        loglik = logsumexp(joint.reshape(M, -1), axis=-1)
        informative = np.isfinite(loglik)  # else nothing is possible under the model (P_D P_G = 1, nothing gated): the prior
        prior = np.concatenate([log_weights[:, :, None], np.full((M, C, L), -np.inf)], axis=2)
        joint = np.where(informative[:, None, None], joint - np.where(informative, loglik, 0.0)[:, None, None], prior)
        x_children = np.concatenate([flat_x[:, None, :], flat_x[:, None, :] + np.einsum("kij,klj->kli", K, nu)], axis=1)
        P_children = np.concatenate([flat_P[:, None], np.broadcast_to(P_new[:, None], (M * C, L, n, n))], axis=1)
        # association record over the mixture: ẑ = Σ w z_c, S moment-matched, β_r, β_0
        z_hat, S = moment_match(np.exp(log_weights), z_pred.reshape(M, C, m), S_c.reshape(M, C, m, m))
        posterior = np.exp(joint)  # (M, C, 1 + L)
        beta0, beta = posterior[:, :, 0].sum(axis=1), posterior[:, :, 1:].sum(axis=1)
        nu_r = np.asarray(candidate_residuals(z_hat, scan.z, sensor, model))
        d2_mix = distances(nu_r, cholesky(S, "innovation covariance S"))
        combined = np.einsum("ml,mli->mi", beta, nu_r)
        selected = np.where(beta.sum(axis=1) > 0, np.argmax(beta, axis=1), -1).astype(np.int64) if L else np.full(M, -1, dtype=np.int64)
        record = Association(
            sensor.name, scan.z, z_hat, S, gamma, d2_mix, gated.reshape(M, C, L).any(axis=1), beta, beta0, selected, loglik
        )
        children = self.reduce(x_children.reshape(M, C * (1 + L), n), P_children.reshape(M, C * (1 + L), n, n), joint.reshape(M, -1))
        return children, combined, S, record

    def reduce(self, x, P, log_weights):
        """Prune (w < prune_threshold, the heaviest kept), merge (d² ≤ merge_threshold), cap at max_components,
        renormalise; returns compacted (x, P, ln w)."""
        log_weights = self.prune(log_weights)
        x, P, log_weights = _compact(x, P, log_weights)
        if self.merge_threshold is not None and x.shape[1] > 1:
            x, P, log_weights = merge(x, P, log_weights, self.merge_threshold)
        cap = self.max_components  # compacted: heaviest first
        x, P, log_weights = x[:, :cap], P[:, :cap], log_weights[:, :cap]
        log_weights = log_weights - logsumexp(log_weights, axis=-1)[:, None]
        return _compact(x, P, log_weights)

    def prune(self, log_weights: np.ndarray) -> np.ndarray:
        """ln w with the components of normalised weight below ``prune_threshold`` emptied (−∞; each filter's
        heaviest component kept) and the rest renormalised."""
        log_weights = log_weights - logsumexp(log_weights, axis=-1)[:, None]
        if self.prune_threshold > 0:
            keep = (log_weights >= math.log(self.prune_threshold)) | (log_weights == log_weights.max(axis=1, keepdims=True))
            log_weights = np.where(keep, log_weights, -np.inf)
            log_weights = log_weights - logsumexp(log_weights, axis=-1)[:, None]
        return log_weights


def merge(x: np.ndarray, P: np.ndarray, log_weights: np.ndarray, threshold: float):
    """Greedy moment-matched merging of every filter's components (sorted heaviest first, see :func:`_compact`).

    For i = 0, 1, …: if component i is occupied and not yet merged it leads a cluster of the unmerged
    components j ≥ i with d²_ij = (x_j − x_i)ᵀ P_i⁻¹ (x_j − x_i) ≤ threshold (Cholesky solve with P_i);
    each cluster becomes W = Σ w_j, x̄ = Σ w_j x_j / W, P̄ = Σ w_j (P_j + (x_j − x̄)(x_j − x̄)ᵀ) / W
    (Salmond 1990; Vo & Ma 2006, Table II; Runnalls 2007).  Vectorized over the M filters.
    """
    M, C, n = x.shape
    leader = np.full((M, C), -1)
    occupied = np.isfinite(log_weights)
    rows = np.arange(M)
    for i in range(C):
        leads = occupied[:, i] & (leader[:, i] < 0)
        if not leads.any():
            continue
        L = cholesky(P[:, i], "component covariance P")
        r = forward_substitute(L[:, None], x - x[:, i : i + 1])  # (M, C, n)
        d2 = np.einsum("mci,mci->mc", r, r)
        join = leads[:, None] & occupied & (leader < 0) & (d2 <= threshold)
        join[:, :i] = False
        join[rows, i] |= leads
        leader = np.where(join, i, leader)
    one_hot = (leader[:, None, :] == np.arange(C)[None, :, None]) & occupied[:, None, :]  # (M, leader, member)
    member_lw = np.where(one_hot, log_weights[:, None, :], -np.inf)
    merged_lw = logsumexp(member_lw, axis=-1)  # (M, C): −∞ where i leads nothing
    xm, Pm = moment_match(normalized_weights(member_lw), x[:, None], P[:, None])  # weights w_j / W within a cluster
    empty = ~np.isfinite(merged_lw)
    xm = np.where(empty[..., None], x, xm)
    Pm = np.where(empty[..., None, None], P, Pm)
    return _compact(xm, Pm, merged_lw)


def range_parameterised(
    observer_position,
    bearing,
    sigma_bearing: float,
    r_min: float,
    r_max: float,
    components: int,
    speed_sigma: float,
    velocity=(0.0, 0.0),
    layout: Sequence[str] = _LAYOUT,
    convention: str = "north",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Range-parameterised initial mixture for bearings-only tracking (Peach 1995; Arulampalam & Ristic 2000).

    The range interval [r_min, r_max] is cut into C intervals in geometric
    steps, ρ = (r_max / r_min)^{1/C}, interval c = [r_min ρ^c, r_min ρ^{c+1}];
    component c is the moment-matched Gaussian of a uniform density on it:
    r_c = (r_min/2)(ρ^c + ρ^{c+1}), σ_c = r_min(ρ^{c+1} − ρ^c)/√12, so that
    σ_c / r_c = 2(ρ − 1)/(√12 (ρ + 1)) is the same for every component (the
    condition of Peach 1995 for each EKF to stay well conditioned).  Position
    mean = observer + r_c u(β) along the first bearing β (u: the unit vector
    of ``convention``), position covariance = σ_c² u uᵀ + (r_c σ_β)² u⊥ u⊥ᵀ;
    velocity ``velocity`` ± ``speed_sigma`` per axis, uncorrelated; equal
    weights 1/C (a prior uniform in ln r).

    ``observer_position`` (2,) or (M, 2), ``bearing`` scalar or (M,) (radians);
    returns means (M, C, n), covs (M, C, n, n), weights (M, C) for
    :meth:`GaussianSumFilter.initialize_mixture` (M = 1 for scalar input).
    """
    check_convention(convention)
    bearing = as_float_array(np.atleast_1d(bearing), "bearing", (None,))
    M = bearing.shape[0]
    observer = as_float_array(
        np.broadcast_to(np.asarray(observer_position, dtype=float), (M, 2)) if np.ndim(observer_position) == 1 else observer_position,
        "observer_position",
        (M, 2),
    )
    sigma_bearing, speed_sigma = check_positive(sigma_bearing, "sigma_bearing"), check_positive(speed_sigma, "speed_sigma")
    r_min, r_max = float(r_min), float(r_max)
    if not (math.isfinite(r_min) and math.isfinite(r_max) and 0 < r_min < r_max):
        raise ValueError(f"r_min, r_max: expected 0 < r_min < r_max (finite), got r_min={r_min!r}, r_max={r_max!r}")
    C = check_positive_int(components, "components")
    velocity = as_float_array(velocity, "velocity", (2,))
    layout = tuple(layout)
    missing = [k for k in ("x", "y", "vx", "vy") if k not in layout]
    if missing:
        raise ValueError(f"layout: expected a layout naming x, y, vx, vy, got {layout} (missing {missing})")
    if len(layout) != 4:
        raise ValueError(f"layout: range parameterisation sets x, y, vx, vy only, got {layout}")
    n = len(layout)
    ix, iy, ivx, ivy = (layout.index(k) for k in ("x", "y", "vx", "vy"))
    rho = (r_max / r_min) ** (1.0 / C)
    edges = r_min * rho ** np.arange(C + 1)
    r = 0.5 * (edges[:-1] + edges[1:])  # (C,)
    sigma_r = (edges[1:] - edges[:-1]) / math.sqrt(12.0)
    ux, uy = direction(bearing, convention)  # (M,)
    u = np.stack([ux, uy], axis=-1)  # (M, 2)
    v = np.stack([-uy, ux], axis=-1)  # perpendicular
    pos = observer[:, None, :] + r[None, :, None] * u[:, None, :]  # (M, C, 2)
    cross = (r * float(sigma_bearing)) ** 2
    Pxy = (
        sigma_r[None, :, None, None] ** 2 * np.einsum("mi,mj->mij", u, u)[:, None]
        + cross[None, :, None, None] * np.einsum("mi,mj->mij", v, v)[:, None]
    )
    means = np.zeros((M, C, n))
    means[..., [ix, iy]], means[..., [ivx, ivy]] = pos, velocity
    covs = np.zeros((M, C, n, n))
    covs[:, :, [[ix], [iy]], [ix, iy]] = Pxy
    covs[:, :, ivx, ivx] = covs[:, :, ivy, ivy] = float(speed_sigma) ** 2
    weights = np.full((M, C), 1.0 / C)
    return means, covs, weights


@hookimpl
def register_estimators(registry):
    registry.add(GaussianSumFilter.name, GaussianSumFilter)
