"""Algorithm 4 of seed 000: expected SPRT decision times (Wald's average sample numbers) and the bank size.

For the main mode 0 and an alternative p (SPEC §4 "Bounding it"):

1. A = ln((1−β)/α), B = ln(β/(1−α)).
2. Steady-state innovation covariances Σ_0, Σ_p of each mode's own filter from
   the discrete algebraic Riccati equation
   P = F P Fᵀ − F P Hᵀ (H P Hᵀ + R)⁻¹ H P Fᵀ + G Q Gᵀ,  Σ = H P Hᵀ + R,  K = P Hᵀ Σ⁻¹
   (``scipy.linalg.solve_discrete_are``).
3. The actual innovation second moment of filter f run on data of mode t,
   Σ̄ = H E{x xᵀ} Hᵀ − H E{x x̂ᵀ} Hᵀ − H E{x̂ xᵀ} Hᵀ + H E{x̂ x̂ᵀ} Hᵀ + R
   (seed 000 Algorithm 4 steps 4–5), from the second moment M of the joint
   vector ζ = [x; x̂⁺; 1] (the 1 carries the affine terms B of the turns):
   M⁻ = A_p M⁺ A_pᵀ + diag(Q_t, 0, 0), A_p = [[F_t, 0, B_t], [0, F_f, B_f], [0, 0, 1]],
   Σ̄ = C M⁻ Cᵀ + R, C = [H, −H, 0],
   M⁺ = U M⁻ Uᵀ + diag(0, K R Kᵀ, 0), U = [[I, 0, 0], [K H, I − K H, 0], [0, 0, 1]]
   — a discrete Lyapunov recursion started at the switching moment with the
   true state x_s and the shared estimate x̂ = x_s + e, e ~ N(0, P⁺_0).
4. Expected log-LR increments (seed 000 Algorithm 4 step 6):
   μ_0p = ½ ln|Σ_0| − ½ ln|Σ_p| + ½(m − tr(Σ_p⁻¹ Σ̄_{p|0}))   (data of mode 0, < 0)
   μ_p0 = ½ ln|Σ_0| − ½ ln|Σ_p| + ½(tr(Σ_0⁻¹ Σ̄_{0|p}) − m)   (data of mode p, > 0)
   (written for a general time k: the filters' own Σ_f(k) and Σ̄_{f|t}(k)).
5. N_0p = (αA + (1−α)B)/μ_0p, N_p0 = ((1−β)A + βB)/μ_p0; bank size
   max_p max(⌈N_0p⌉, ⌈N_p0⌉) (steps 7–9).

The seed takes μ from the limits k → ∞.  For the neutrally stable modes here
(constant velocity, turns about a centre fixed at the switch) a mismatched
filter's bias grows without bound, so the limit often does not exist;
:func:`wald_pair` then reports ``steady=None`` and the transient prediction
(the smallest N whose cumulative expected drift Σ_{k≤N} μ(k) reaches Wald's
boundary term) is used instead.  ``gains="steady"`` runs step 3 with the
steady gains of step 2 (the seed); ``"transient"`` with each filter's own
Riccati recursion from P⁺_0, as the real bank does.
"""

from __future__ import annotations

import math

import attrs
import numpy as np
import scipy.linalg

from hybridtrack.sdk.linalg import log_det_from_cholesky
from hybridtrack.sdk.thresholds import check_error_probabilities, sprt_thresholds


@attrs.frozen(eq=False)
class SteadyFilter:
    """Steady-state predicted covariance P⁻, innovation covariance Σ, gain K = P⁻HᵀΣ⁻¹, posterior P⁺."""

    P_predicted: np.ndarray
    S: np.ndarray
    K: np.ndarray
    P_posterior: np.ndarray


def steady_state_filter(F, H, Q, R) -> SteadyFilter:
    """The Kalman filter's steady state from the DARE (``scipy.linalg.solve_discrete_are``); Q = G Q_w Gᵀ."""
    F, H, Q, R = (np.asarray(a, dtype=float) for a in (F, H, Q, R))
    P = scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)
    P = 0.5 * (P + P.T)
    S = H @ P @ H.T + R
    K = scipy.linalg.cho_solve(scipy.linalg.cho_factor(S), H @ P).T
    I_KH = np.eye(F.shape[0]) - K @ H
    P_post = I_KH @ P @ I_KH.T + K @ R @ K.T
    return SteadyFilter(P, S, K, 0.5 * (P_post + P_post.T))


def steady_error_covariance(F, H, Q, R, K) -> np.ndarray:
    """Stationary predicted-error covariance of a matched filter with fixed gain K (discrete Lyapunov equation):
    E = F(I−KH) E (F(I−KH))ᵀ + F K R Kᵀ Fᵀ + Q; equals the DARE solution when K is the steady Kalman gain."""
    A = F @ (np.eye(F.shape[0]) - K @ H)
    return scipy.linalg.solve_discrete_lyapunov(A, F @ K @ R @ K.T @ F.T + Q)


def innovation_moments(true, filters, H, R, switch_state, P0, steps: int, gains: str = "steady"):
    """Own Σ_f(k) and actual Σ̄_{f|t}(k), k = 1 … steps, of each filter in ``filters`` on data of ``true``.

    ``true`` and each filter are (F, B, Q) with Q = G Q_w Gᵀ; the filters start
    at the switching moment from the same estimate x̂ = x_s + e, e ~ N(0, P0).
    Returns arrays own (F, steps, m, m) and actual (F, steps, m, m).
    """
    if gains not in ("steady", "transient"):
        raise ValueError(f"gains: expected 'steady' or 'transient', got {gains!r}")
    H, R, x_s, P0 = (np.asarray(a, dtype=float) for a in (H, R, switch_state, P0))
    n, m = x_s.shape[0], H.shape[0]
    F_t, B_t, Q_t = (np.asarray(a, dtype=float) for a in true)
    own = np.zeros((len(filters), steps, m, m))
    actual = np.zeros((len(filters), steps, m, m))
    C = np.hstack([H, -H, np.zeros((m, 1))])
    for i, (F_f, B_f, Q_f) in enumerate(filters):
        F_f, B_f, Q_f = (np.asarray(a, dtype=float) for a in (F_f, B_f, Q_f))
        steady = steady_state_filter(F_f, H, Q_f, R) if gains == "steady" else None
        A_p = np.zeros((2 * n + 1, 2 * n + 1))
        A_p[:n, :n], A_p[:n, -1] = F_t, B_t
        A_p[n : 2 * n, n : 2 * n], A_p[n : 2 * n, -1] = F_f, B_f
        A_p[-1, -1] = 1.0
        zeta = np.concatenate([x_s, x_s, [1.0]])
        M = np.outer(zeta, zeta)
        M[n : 2 * n, n : 2 * n] += P0
        P = P0.copy()
        for k in range(steps):
            M = A_p @ M @ A_p.T
            M[:n, :n] += Q_t
            if steady is None:
                P = F_f @ P @ F_f.T + Q_f
                S = H @ P @ H.T + R
                K = scipy.linalg.cho_solve(scipy.linalg.cho_factor(S), H @ P).T
                P = (np.eye(n) - K @ H) @ P @ (np.eye(n) - K @ H).T + K @ R @ K.T
            else:
                S, K = steady.S, steady.K
            own[i, k] = S
            actual[i, k] = C @ M @ C.T + R
            U = np.eye(2 * n + 1)
            U[n : 2 * n, :n] = K @ H
            U[n : 2 * n, n : 2 * n] = np.eye(n) - K @ H
            M = U @ M @ U.T
            M[n : 2 * n, n : 2 * n] += K @ R @ K.T
            M = 0.5 * (M + M.T)
    return own, actual


def expected_increments(own_0, own_p, actual_0, actual_p) -> np.ndarray:
    """μ(k) = E[ℓ_p − ℓ_0] = ½ ln|Σ_0| − ½ ln|Σ_p| + ½ tr(Σ_0⁻¹ Σ̄_0) − ½ tr(Σ_p⁻¹ Σ̄_p) per step (step 6)."""
    t0 = np.trace(np.linalg.solve(own_0, actual_0), axis1=-2, axis2=-1)
    tp = np.trace(np.linalg.solve(own_p, actual_p), axis1=-2, axis2=-1)
    log_det_0, log_det_p = (log_det_from_cholesky(np.linalg.cholesky(S)) for S in (own_0, own_p))
    return 0.5 * (log_det_0 - log_det_p + t0 - tp)


def wald_boundary_terms(alpha, beta) -> tuple[float, float]:
    """(αA + (1−α)B, (1−β)A + βB): E[λ_N] under H_0 and under H_p (Wald's approximations)."""
    alpha, beta = check_error_probabilities(alpha, beta)
    A, B = sprt_thresholds(alpha, beta)
    return alpha * A + (1 - alpha) * B, (1 - beta) * A + beta * B


def _limit(series: np.ndarray, rtol: float = 1e-3) -> float | None:
    """The last value when the series has settled (relative change over the last tenth below rtol)."""
    tail = series[-max(2, series.size // 10) :]
    scale = max(abs(float(series[-1])), 1e-12)
    return float(series[-1]) if np.ptp(tail) <= rtol * scale else None


def _transient_n(mu: np.ndarray, target: float) -> float:
    """Smallest N with Σ_{k≤N} μ(k) beyond ``target`` (same sign), ∞ if not within the horizon."""
    cumulative = np.cumsum(mu)
    hit = np.flatnonzero(cumulative >= target) if target > 0 else np.flatnonzero(cumulative <= target)
    return float(hit[0] + 1) if hit.size else math.inf


@attrs.frozen
class WaldPair:
    """Algorithm 4 for one pair (mode 0, mode p): μ series, steady μ (None without a limit), N predictions."""

    mu_0p: np.ndarray = attrs.field(eq=False)
    mu_p0: np.ndarray = attrs.field(eq=False)
    steady_mu_0p: float | None
    steady_mu_p0: float | None
    n_0p_steady: float | None
    n_p0_steady: float | None
    n_0p_transient: float
    n_p0_transient: float

    @property
    def n_0p(self) -> float:
        return self.n_0p_steady if self.n_0p_steady is not None else self.n_0p_transient

    @property
    def n_p0(self) -> float:
        return self.n_p0_steady if self.n_p0_steady is not None else self.n_p0_transient

    @property
    def bank_size(self) -> int:
        """M_p = max(⌈N_0p⌉, ⌈N_p0⌉) (step 8)."""
        return int(max(math.ceil(self.n_0p), math.ceil(self.n_p0)))


def wald_pair(model_0, model_p, H, R, switch_state, alpha, beta, P0=None, horizon: int = 400, gains: str = "steady") -> WaldPair:
    """Algorithm 4 for one pair; ``model_0`` and ``model_p`` are (F, B, Q = G Q_w Gᵀ) fixed at ``switch_state``.

    P0 (the estimate's error covariance at the switch) defaults to the steady
    posterior covariance of mode 0's filter (it has been running before).
    """
    low, high = wald_boundary_terms(alpha, beta)
    if P0 is None:
        P0 = steady_state_filter(model_0[0], H, model_0[2], R).P_posterior
    own_h0, act_h0 = innovation_moments(model_0, [model_0, model_p], H, R, switch_state, P0, horizon, gains)
    own_hp, act_hp = innovation_moments(model_p, [model_0, model_p], H, R, switch_state, P0, horizon, gains)
    mu_0p = expected_increments(own_h0[0], own_h0[1], act_h0[0], act_h0[1])
    mu_p0 = expected_increments(own_hp[0], own_hp[1], act_hp[0], act_hp[1])
    s0p, sp0 = _limit(mu_0p), _limit(mu_p0)
    n0 = low / s0p if s0p is not None and s0p < 0 else None
    n1 = high / sp0 if sp0 is not None and sp0 > 0 else None
    return WaldPair(mu_0p, mu_p0, s0p, sp0, n0, n1, _transient_n(mu_0p, low), _transient_n(mu_p0, high))


def algorithm4_bank_size(pairs) -> int:
    """max over the alternatives p of M_p (step 9)."""
    pairs = list(pairs)
    if not pairs:
        raise ValueError("pairs: Algorithm 4 needs at least one alternative mode")
    return max(pair.bank_size for pair in pairs)
