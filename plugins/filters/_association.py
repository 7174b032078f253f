"""Gating and data association over a bank of filters and a set of candidates (SPEC §6; seed 004).

Shapes: M filters, L candidate measurements of dimension m.  For filter j and
candidate i the innovation is ν_ji = z_i − ẑ_j (ẑ = H x⁻), with the innovation
covariance S_j = H P⁻_j Hᵀ + R, and

    d²_ji = ν_jiᵀ S_j⁻¹ ν_ji                       (squared Mahalanobis distance)
    gate:  d²_ji ≤ γ,   γ = χ²_m quantile of P_G    (the gate probability P_G)

Nearest neighbour (:mod:`.nearest_neighbour`) takes the gated candidate with
the smallest d²; probabilistic data association (:mod:`.pda`, whose docstring
has the equations) weighs them all with β_i ∝ e_i = exp(−½ d²_i) against
b = λ √|2π S| (1 − P_D P_G) / P_D for "none is the target's".

The association likelihood of a scan, the likelihood of the m_k gated
candidates given the filter divided by the clutter-only factor
e^{−λV} λ^{m_k} / m_k! (Bar-Shalom, Li & Kirubarajan 2001 §11.7.4, the IMM-PDA
mode likelihood):

    Λ = (1 − P_D P_G) + (P_D / λ) Σ_i N(ν_i; 0, S)
      = P_D (b + Σ_i e_i) / (λ √|2π S|)                  (λ > 0)

for λ = 0 it is the likelihood itself: P_D Σ_i N(ν_i; 0, S) if a candidate is
gated, 1 − P_D P_G otherwise.  It compares the filters of a bank on the same
scan (mode-change detection in clutter) — the Gaussian ℓ of one innovation
does not, in clutter.

Everything is computed in the log domain (log-sum-exp), so a candidate far
outside the gate does not underflow the weights.
"""

from __future__ import annotations

import functools
import math
from abc import abstractmethod
from collections.abc import Sequence

import attrs
import numpy as np
from scipy import special

from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.protocols import Association, ClutterInnovation
from hybridtrack.core.validation import check_magnitude
from hybridtrack.sdk.estimation import BankEstimator, check_layout, guarded
from hybridtrack.sdk.linalg import LOG_2PI, CholeskyFactor, cholesky, forward_substitute, gaussian_scores, log_det_from_cholesky, symmetrize
from hybridtrack.sdk.measurements import block_diagonal
from hybridtrack.sdk.mixtures import logsumexp, moment_match
from hybridtrack.sdk.scans import RowScan, Scan, check_clutter_density, check_detection_probability
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters.kalman import CovarianceState


def check_gate_probability(value) -> float | None:
    """P_G in (0, 1), or None for no gate (every candidate is considered, P_G = 1)."""
    if value is None:
        return None
    value = float(value)
    if not (0.0 < value < 1.0):
        raise ValueError(f"gate_probability: expected P_G in (0, 1) (or None for no gate), got {value!r}")
    return value


def set_clutter_model(estimator, detection_probability, clutter_density, gate_probability) -> None:
    """The parametric clutter model on ``estimator``, checked: ``detection_probability`` P_D in (0, 1],
    ``clutter_density`` λ ≥ 0, ``gate_probability`` P_G (:func:`check_gate_probability`), and ``log_miss`` =
    ln(1 − P_D P_G) (−∞ when a miss is impossible: P_D = 1, no gate), ``log_detect`` = ln(P_D / λ) (ln P_D for λ = 0)."""
    P_D = estimator.detection_probability = check_detection_probability(detection_probability)
    lam = estimator.clutter_density = check_clutter_density(clutter_density)
    estimator.gate_probability = check_gate_probability(gate_probability)
    miss = 1.0 - P_D * (1.0 if estimator.gate_probability is None else estimator.gate_probability)
    estimator.log_miss = math.log(miss) if miss > 0 else -math.inf
    estimator.log_detect = math.log(P_D) - (math.log(lam) if lam > 0 else 0.0)


@functools.lru_cache(maxsize=64)
def gate_threshold(gate_probability: float | None, m: int) -> float:
    """γ with P(χ²_m ≤ γ) = P_G; ∞ without a gate."""
    if gate_probability is None:
        return float("inf")
    return float(2.0 * special.gammaincinv(m / 2.0, gate_probability))  # F⁻¹(P_G) = 2 P⁻¹(m/2, P_G), scipy.stats.chi2.ppf


def innovation_covariance(P: np.ndarray, H: np.ndarray, R: np.ndarray, selection=None) -> np.ndarray:
    """S = H P⁻ Hᵀ + R (M, m, m), symmetrised; with ``selection`` H P Hᵀ is indexing (as in ``_covariance.update``)."""
    if selection is not None:
        return symmetrize(P[:, :, list(selection)][:, list(selection), :] + R)
    return symmetrize(H @ P @ np.swapaxes(H, -1, -2) + R)


def distances(nu: np.ndarray, L: np.ndarray) -> np.ndarray:
    """d²_ji = ν_jiᵀ S_j⁻¹ ν_ji for ν (M, L, m) and S_j = L_j L_jᵀ (M, m, m) → (M, L)."""
    if nu.shape[1] == 0:
        return np.zeros(nu.shape[:2])
    w = forward_substitute(L[:, None, :, :], nu)
    return np.einsum("...i,...i->...", w, w)


def nearest_weights(d2: np.ndarray, gated: np.ndarray, chol: np.ndarray):
    """The nearest neighbour's association (β_i one-hot (M, L), β_0 (M,), selected i* (M,), ℓ (M,)): i* the gated
    candidate with the smallest d² (−1 where none is gated), ℓ = −½(m ln 2π + ln det S + d²_{i*}) (NaN for none)."""
    M, L = d2.shape
    selected = (np.where(gated.any(axis=1), np.argmin(np.where(gated, d2, np.inf), axis=1), -1) if L else np.full(M, -1)).astype(np.int64)
    rows = np.flatnonzero(selected >= 0)
    loglik = np.full(M, np.nan)
    loglik[rows] = -0.5 * d2[rows, selected[rows]] - log_half_det_2pi_s(chol)[rows]
    return (np.arange(L) == selected[:, None]).astype(float), (selected < 0).astype(float), selected, loglik


def pad_axis(a: np.ndarray, axis: int, size: int, value) -> np.ndarray:
    """``a`` padded with ``value`` to at least ``size`` entries along ``axis`` (as it is when it has them)."""
    if a.shape[axis] >= size:
        return a
    shape = list(a.shape)
    shape[axis] = size - a.shape[axis]
    return np.concatenate([a, np.full(shape, value, dtype=a.dtype)], axis=axis)


def log_half_det_2pi_s(L: np.ndarray) -> np.ndarray:
    """ln √|2π S| = ½(m ln 2π + ln det S) for S = L Lᵀ (M,)."""
    m = L.shape[-1]
    return 0.5 * (m * LOG_2PI + log_det_from_cholesky(L))


def pda_weights(
    d2: np.ndarray, gated: np.ndarray, L: np.ndarray, detection_probability: float, clutter_density: float, log_miss: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """β_i (M, L), β_0 (M,) and ln Λ (M,) of the parametric PDA (:mod:`.pda`; Λ in the module docstring).

    ln b = ln λ + ln √|2πS| + ln(1 − P_D P_G) − ln P_D (−∞ when λ = 0 or P_D P_G = 1; ``log_miss`` = ln(1 − P_D P_G)).
    """
    P_D, lam = detection_probability, clutter_density
    M = d2.shape[0]
    half = log_half_det_2pi_s(L)  # (M,)
    log_b = np.broadcast_to(np.log(lam) + half + log_miss - np.log(P_D) if lam > 0 else -np.inf, (M,))
    log_e = np.where(gated, -0.5 * d2, -np.inf)  # (M, L)
    terms = np.concatenate([log_b[:, None], log_e], axis=1)  # (M, 1 + L)
    total = logsumexp(terms, axis=1)
    informative = np.isfinite(total)
    weights = np.zeros_like(terms)
    weights[informative] = np.exp(terms[informative] - total[informative, None])
    weights[~informative, 0] = 1.0  # nothing gated and b = 0: no information, β_0 = 1
    beta0, beta = weights[:, 0], weights[:, 1:]
    if lam > 0:
        loglik = np.where(informative, np.log(P_D) - np.log(lam) - half + total, log_miss)
    else:
        log_sum = logsumexp(log_e, axis=1)
        loglik = np.where(np.isfinite(log_sum), np.log(P_D) - half + log_sum, log_miss)
    return beta, beta0, loglik


def combine(nu: np.ndarray, beta: np.ndarray, beta0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Combined innovation ν = Σ β_i ν_i (M, m) and the spread Σ β_i ν_i ν_iᵀ − ν νᵀ (M, m, m): the moment-matched
    mean and covariance of the point masses ν_0 = 0 (weight β_0, no candidate is the target's) and ν_i (weight β_i)."""
    M, L, m = nu.shape
    points = np.concatenate([np.zeros((M, 1, m)), nu], axis=1)
    return moment_match(np.concatenate([beta0[:, None], beta], axis=1), points, np.zeros((M, L + 1, m, m)))


class ScanEstimator(BankEstimator):
    """Covariance-form bank of one-target trackers in clutter, updated scan by scan (NN, PDA, MSDA, MHT, PMHT).

    ``update(state, z, sensors, layout)`` accepts, for ``z``:

    * the stacked z of :meth:`Estimator.update` (shape (Σ m_i,) or (M, Σ m_i),
      NaN: a missing component, or a sensor without measurement) — the present
      components' stacked vector is then the one candidate of the step;
    * a :class:`~hybridtrack.sdk.scans.Scan` — the candidates (L, m) of the
      sensor named ``scan.sensor`` (one of ``sensors``), L ≥ 0;
    * a sequence of Scans — processed one sensor after the other (sequential
      multisensor association); the :class:`ClutterInnovation` stacks their ν
      with S block-diagonal.

    Linear sensors with a measurement-independent R only.  A subclass gives
    :meth:`associate_scan` (the state and one scan's candidates → the new
    state, the ν used, S and the Association), and may change how the
    candidates are formed (:meth:`stacked_candidates`, :meth:`scan_candidates`)
    and the innovation (:meth:`finish`).
    """

    exact_kalman = False
    #: the pipeline may pass a list of Scans (candidates in clutter) as z
    accepts_scans = True
    #: RowScans (candidates per filter row) accepted
    row_scans = False

    def __init__(self, gate_probability: float | None = 0.99, form: str = "joseph"):
        super().__init__()
        if form not in cov_form.UPDATE_FORMS:
            raise ValueError(f"form: expected one of {cov_form.UPDATE_FORMS}, got {form!r}")
        self.gate_probability = check_gate_probability(gate_probability)
        self.form = form

    @guarded
    def predict(self, state, transitions):
        """x⁻ = F x + B, P⁻ = F P Fᵀ + Q (seed 000 eqs. 4–5) of every filter's x (M, n) or hypotheses x (M, H, n)."""
        M, n = state.x.shape[0], state.x.shape[-1]
        bank = self.check_transitions(transitions, M, n, state.mean)
        per_filter = state.x.size // (M * n)
        F, B, Q = (np.repeat(A, per_filter, axis=0) for A in (bank.F, bank.B, bank.Q))
        x, P = cov_form.predict(state.x.reshape(-1, n), state.P.reshape(-1, n, n), F, B, Q)
        self.check_finite("predict", predicted_mean=x, predicted_covariance=P)
        x, P = x.reshape(state.x.shape), P.reshape(state.P.shape)
        return attrs.evolve(state, x=x, P=P, x_predicted=x, P_predicted=P, innovation=None)

    @guarded
    def update(self, state, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        check_layout(layout, state.x.shape[-1])
        scans = as_scans(z, rows=self.row_scans)
        if scans is None:
            found = self.stacked_candidates(state, z, sensors, layout)
            if found is None:
                return self.unmeasured(state, state.x.shape[0])
            state, nu, S, record = self.associate_scan(state, *found)
            return self.finish(state, [nu], [S], [record])
        return self.finish(*scan_by_scan(self, state, scans, sensors, layout, self._scan_step))

    def _scan_step(self, state, scan, sensor, model):
        return self.associate_scan(state, *self.scan_candidates(state, scan, sensor, model))

    def stacked_candidates(self, state, z, sensors, layout):
        """The one candidate of a stacked z against every row of x (filters, or hypotheses), as :meth:`associate_scan`
        takes it, or None when nothing was measured: ν (rows, 1, m), H, R, the selection, the sensors' name, z, ẑ."""
        M, n = state.x.shape[0], state.x.shape[-1]
        step = self.measurement_step(z, sensors, layout, M, n, state)
        if step is None:
            return None
        per_filter = state.x.size // (M * n)  # rows of x per filter
        R = np.asarray(step.R)
        if per_filter > 1:
            step = step.with_z(np.repeat(step.z, per_filter, axis=0)) if step.z.shape[0] > 1 else step
            R = np.repeat(R, per_filter, axis=0) if R.ndim == 3 else R
        step, nu, H = self.linearize(state.x.reshape(-1, n), z, sensors, layout, step)
        z_pred = np.broadcast_to(step.z, nu.shape) - nu
        return nu[:, None, :], H, R, step.selection, "+".join(m.sensor.name for m in step.models), step.z, z_pred

    def scan_candidates(self, state, scan, sensor, model):
        """A scan's candidates as :meth:`associate_scan` takes them: ν_ji = z_i ⊖ H x_j (rows, L, m) of every row of
        x (filters, or hypotheses), H, R, the selection, the sensor's name, the candidates and ẑ."""
        z_pred = predict_measurement(state.x.reshape(-1, state.x.shape[-1]), model)
        nu = candidate_residuals(z_pred, scan.z, sensor, model)
        return nu, model.H, sensor.noise_cov, model.selection, sensor.name, scan.z, z_pred

    def gate(self, nu, P, H, R, selection=None):
        """S = H P Hᵀ + R, chol S, γ, d² (rows, L) and the gate mask d² ≤ γ of the candidates' ν (rows, L, m)."""
        S = innovation_covariance(P, H, R, selection)
        chol = cholesky(S, "innovation covariance S")
        gamma = gate_threshold(self.gate_probability, S.shape[-1])
        d2 = distances(nu, chol)
        # an inf d² would drop a candidate silently
        self.check_finite("update", innovation_covariance=S, innovation=nu, squared_distances_d2=d2)
        return S, chol, gamma, d2, d2 <= gamma

    @abstractmethod
    def associate_scan(self, state, *candidates):
        """(new state, ν used (M, m), S (M, m, m), Association) of one scan's candidates."""

    def finish(self, state, used, blocks, records):
        """The state with the step's :class:`ClutterInnovation` (:func:`stacked_innovation` of the scans used)."""
        innovation = ClutterInnovation(*stacked_innovation(state.x.shape[0], used, blocks), tuple(records))
        return attrs.evolve(state, innovation=innovation), innovation


class ClutterEstimator(ScanEstimator):
    """Covariance-form bank whose update associates candidates before correcting (NN, PDA).

    ``z`` as for :class:`ScanEstimator`, and also a :class:`~hybridtrack.sdk.scans.RowScan` (or a sequence mixing
    them with Scans), candidates per filter row (M, L, m): row j gated and weighed against its own candidates only,
    a row of padding only as a row with nothing gated, ν = 0 (docs/clutter.md, "Stacked runs").

    Subclasses give the weights: :meth:`associate` (d², gated, chol S) → (β_i, β_0, selected, ln Λ).
    """

    row_scans = True

    def initialize(self, mean, cov) -> CovarianceState:
        x, P = self.check_prior(mean, cov)
        return CovarianceState(x, P, x, P, None)

    def scan_candidates(self, state, scan, sensor, model):
        """As :meth:`ScanEstimator.scan_candidates`, plus the mask (M, L) of the real candidates (a Scan's are all,
        shared by the rows; a RowScan's ``present``)."""
        M = state.x.shape[0]
        if scan.z.ndim == 3 and scan.z.shape[0] != M:
            raise ValueError(f"z: RowScan of sensor {scan.sensor!r} has {scan.z.shape[0]} rows for a bank of {M} filters")
        present = scan.present if scan.z.ndim == 3 else np.ones((M, scan.size), dtype=bool)
        z_pred = predict_measurement(state.x, model)
        candidates = np.where(present[..., None], scan.z, z_pred[:, None, :])  # padding: ν = 0, never gated
        nu = candidate_residuals(z_pred, candidates, sensor, model)
        return nu, model.H, sensor.noise_cov, model.selection, sensor.name, scan.z, z_pred, present

    def associate_scan(self, state, nu, H, R, selection, sensor_name, candidates, z_pred, present=True):
        """Gate, weigh and update with one scan: ν (M, L, m) → the updated state, ν used (M, m), S, Association;
        ``present`` (M, L) marks the real candidates (padding gets d² = ∞, never gated)."""
        x, P = state.x, state.P
        S, L, gamma, d2, gated = self.gate(nu, P, H, R, selection)
        d2 = np.where(present, d2, np.inf)
        gated = d2 <= gamma
        beta, beta0, selected, loglik = self.associate(d2, gated, L)
        record = Association(sensor_name, np.asarray(candidates), z_pred, S, gamma, d2, gated, beta, beta0, selected, loglik)
        if nu.shape[1] == 0:
            return state, np.zeros(x.shape[:1] + S.shape[-1:]), S, record
        combined, spread = combine(nu, beta, beta0)
        x_new, P_correct, _, _, K = cov_form.update(x, P, combined, H, R, selection, self.form)
        self.check_finite("update", updated_mean=x_new)
        P_new = beta0[:, None, None] * P + (1.0 - beta0)[:, None, None] * P_correct + K @ spread @ np.swapaxes(K, -1, -2)
        return attrs.evolve(state, x=x_new, P=symmetrize(P_new)), combined, S, record

    @abstractmethod
    def associate(self, d2: np.ndarray, gated: np.ndarray, L: np.ndarray):
        """(β_i (M, L), β_0 (M,), selected (M,), ln Λ or ℓ (M,)) from d² (M, L), the gate mask and chol S."""


def scan_by_scan(estimator: BankEstimator, state, scans, sensors, layout, step, linear: bool = True):
    """``step(state, scan, sensor, model) → (state, ν used (M, m), S (M, m, m), Association)`` applied to the scans
    one sensor after the other (sequential multisensor association): the last state, the ν and S of the scans with
    candidates (for :func:`stacked_innovation`) and every scan's Association.

    Each scan's sensor (by name among ``sensors``, one Sensor or a sequence) and its cached SensorModel are
    checked: linear (unless ``linear`` is False), with a measurement-independent R, of the scan's dimension, and
    the candidates within the filter's arithmetic."""
    by_name = {s.name: s for s in ((sensors,) if isinstance(sensors, Sensor) else sensors)}
    used, blocks, records = [], [], []
    for scan in scans:
        sensor = by_name.get(scan.sensor)
        if sensor is None:
            raise ValueError(f"z: scan of sensor {scan.sensor!r}, which is not among the sensors {sorted(by_name)}")
        model = estimator.assembler.sensor_model(sensor, tuple(layout))
        if linear and model.H is None:
            raise ValueError(f"sensors: {estimator.name!r} takes linear sensors only; {sensor.name!r} is nonlinear")
        if type(sensor).measurement_noise is not Sensor.measurement_noise:
            raise ValueError(f"sensors: {estimator.name!r} needs a measurement-independent R; sensor {sensor.name!r} computes R from z")
        if scan.measurement_dim != model.dim:
            raise ValueError(f"z: scan of sensor {scan.sensor!r} has dimension {scan.measurement_dim}, the sensor measures {model.dim}")
        check_magnitude(scan.z, "z", f"measurement (scan of sensor {scan.sensor!r})")
        state, nu, S, record = step(state, scan, sensor, model)
        records.append(record)
        if scan.size:
            used.append(nu)
            blocks.append(S)
    return state, used, blocks, records


def summed_loglik(records: Sequence[Association], M: int) -> np.ndarray:
    """ℓ = Σ ln Λ (M,) over a step's Associations, a scan impossible under the model (ln Λ = −∞) counting as no
    measurement (0)."""
    return sum((np.where(np.isfinite(record.loglik), record.loglik, 0.0) for record in records), np.zeros(M))


def predict_measurement(x: np.ndarray, model) -> np.ndarray:
    """ẑ = H x (rows, m) of a linear scan model (the selected components when H is a selection)."""
    return x[:, list(model.selection)] if model.selection is not None else x @ model.H.T


def candidate_residuals(z_pred: np.ndarray, candidates: np.ndarray, sensor: Sensor, model) -> np.ndarray:
    """ν_ji = z_i ⊖ ẑ_j (rows, L, m) of every candidate against every row's prediction ẑ (rows, m); ``candidates``
    (L, m) shared by the rows or (rows, L, m); ⊖ the sensor's residual (angles wrapped) unless plain subtraction."""
    if candidates.ndim == 2:
        candidates = np.broadcast_to(candidates[None, :, :], z_pred.shape[:1] + candidates.shape)
    predicted = np.broadcast_to(z_pred[:, None, :], candidates.shape)
    return candidates - predicted if model.plain_residual else sensor.residual(candidates, predicted)


def stacked_innovation(M: int, used: Sequence[np.ndarray], blocks: Sequence[np.ndarray], *, factored: bool = False):
    """(ν, S, ℓ, NIS) of a step's clutter scans for M filters: ν the scans' combined residuals (M, m_j)
    concatenated, S = blkdiag(S_j) and ℓ = −½(m ln 2π + ln det S + νᵀS⁻¹ν), NIS = νᵀS⁻¹ν (SPEC §4); with no
    scan used, empty ν and S and ℓ = NIS = 0 (a prediction-only step).

    ``factored``: the scores through :class:`~hybridtrack.sdk.linalg.CholeskyFactor` (closed forms for m ≤ 2, as the
    Gaussian-sum and particle filters compute them) instead of :func:`~hybridtrack.sdk.linalg.gaussian_scores`.
    """
    if not used:
        return np.zeros((M, 0)), np.zeros((M, 0, 0)), np.zeros(M), np.zeros(M)
    nu = np.concatenate(used, axis=-1)
    S = block_diagonal(blocks)
    if factored:
        loglik, nis = CholeskyFactor(S, "innovation covariance S").scores(nu)
    else:
        loglik, nis = gaussian_scores(nu, cholesky(S, "innovation covariance S"))
    return nu, S, loglik, nis


def as_scans(z, rows: bool = False):
    """z as a list of Scans, or None for a stacked measurement array; with ``rows`` RowScans are accepted too
    (nearest neighbour and PDA), else a RowScan is a TypeError naming the estimators that take it."""
    items = [z] if isinstance(z, (Scan, RowScan)) else z
    if isinstance(items, (list, tuple)) and items and all(isinstance(s, (Scan, RowScan)) for s in items):
        if not rows and any(isinstance(s, RowScan) for s in items):
            raise TypeError("z: a RowScan (candidates per filter row) is taken by nearest_neighbour and pda only; pass each row's Scan")
        names = [s.sensor for s in items]
        if len(set(names)) != len(names):
            raise ValueError(f"z: one scan per sensor, got {names}")
        return list(items)
    return None
