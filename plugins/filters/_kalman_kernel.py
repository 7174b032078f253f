"""Compiled steps of the dense covariance Kalman filter (SPEC §3, seed 000 Algorithm 1), by numba.

The same arithmetic as :mod:`._covariance` (predict; update with the three
forms) and :class:`hybridtrack.linalg.CholeskyFactor` (S⁻¹ and the scores),
run filter by filter in compiled loops over the bank: each call is one pass
over the M filters, every intermediate (F P, P Hᵀ, S, S⁻¹, K, T, D) an n × n,
n × m or m × m scratch array reused from filter to filter, nothing stacked.
Per filter i (H, R shared or per filter):

* :func:`predict_bank`: x⁻ = F x⁺ + B, C = (F P⁺) Fᵀ + Q, P⁻ = ½(C + Cᵀ)
  (seed 000 eqs. 4–5);
* :func:`update_bank`: S = ½(C + Cᵀ), C = H P⁻ Hᵀ + R; S⁻¹ and the scores by
  the closed forms for m ≤ 2 (S = [[a, b], [b, c]], det S = a c − b²,
  S⁻¹ = [[c, −b], [−b, a]] / det S, NIS = ν₀²/a + a r² / det S with
  r = ν₁ − (b/a) ν₀) and by the Cholesky recurrence for m ≥ 3
  (L_jj = √(S_jj − Σ_{k<j} L_jk²), L_ij = (S_ij − Σ_{k<j} L_ik L_jk) / L_jj,
  S⁻¹ = L⁻ᵀ L⁻¹, NIS = |L⁻¹ν|², ln det S = 2 Σ ln L_jj);
  K = P⁻ Hᵀ S⁻¹, x⁺ = x⁻ + K ν, and P⁺ by ``form``: 0 Joseph,
  T = P⁻ − K (H P⁻), P⁺ = ½(U + Uᵀ), U = T + (K R − T Hᵀ) Kᵀ (the
  (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ of seed 000 eq. 9 as corrected by SPEC §3,
  in the evaluation order of :func:`._covariance.update`); 1 symmetric,
  P⁺ = ½(T + Tᵀ), T = P⁻ − K (P⁻ Hᵀ)ᵀ; 2 conventional, P⁺ = T unsymmetrised.
  ℓ = −½(m ln 2π + ln det S + NIS) (SPEC §4).

The results equal the numpy path to rounding (tests/plugins/test_kalman_kernel.py:
≤ 1e-12 relative over random SPD systems, n = 2 … 6, m = 1 … 3).  A filter
whose S is not positive definite (or NaN) stops the pass: :func:`update_bank`
returns its index (−1 when all are) and the caller raises the same
``LinAlgError`` as the numpy path.  No ``fastmath``: IEEE semantics as in
numpy, so an overflow leaves inf/NaN for the estimator's finiteness checks.
``error_model="numpy"``: a division by zero gives inf/NaN, not an exception.
``cache=True``: the first call in a fresh checkout compiles (a few seconds)
and caches the machine code next to this file (``__pycache__``).

Imported only on first use by :mod:`._covariance` (loading the plugins does
not import numba); ``AVAILABLE`` is False without numba.
"""

from __future__ import annotations

import math

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover - exercised only without numba
    numba = None

AVAILABLE = numba is not None
LOG_2PI = float(np.log(2.0 * np.pi))
FORMS = {"joseph": 0, "symmetric": 1, "conventional": 2}


def _njit(function):
    return numba.njit(cache=True, error_model="numpy", nogil=True)(function) if AVAILABLE else function


@_njit
def predict_bank(x, P, F, B, Q, x_out, P_out):  # pragma: no cover - compiled
    """x⁻ = F x⁺ + B, P⁻ = ½(C + Cᵀ), C = (F P⁺) Fᵀ + Q, for each filter of the bank (outputs written in place)."""
    M, n = x.shape
    FP = np.empty((n, n))
    C = np.empty((n, n))
    for i in range(M):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += F[i, j, k] * x[i, k]
            x_out[i, j] = acc + B[i, j]
        for j in range(n):
            for k in range(n):
                acc = 0.0
                for q in range(n):
                    acc += F[i, j, q] * P[i, q, k]
                FP[j, k] = acc
        for j in range(n):
            for k in range(n):
                acc = 0.0
                for q in range(n):
                    acc += FP[j, q] * F[i, k, q]
                C[j, k] = acc + Q[i, j, k]
        for j in range(n):
            P_out[i, j, j] = C[j, j]
            for k in range(j + 1, n):
                P_out[i, j, k] = P_out[i, k, j] = 0.5 * (C[j, k] + C[k, j])


@_njit
def update_bank(x, P, nu, H, R, form, x_out, P_out, S_out, loglik, nis):  # pragma: no cover - compiled
    """The measurement update and scores of each filter (outputs written in place); the first filter whose S is
    not positive definite, or −1.  H (1 or M, m, n), R (1 or M, m, m): one shared or one per filter."""
    M, n = x.shape
    m = nu.shape[1]
    PHt = np.empty((n, m))
    HP = np.empty((m, n))
    S = np.empty((m, m))
    Si = np.empty((m, m))
    L = np.zeros((m, m))
    Li = np.zeros((m, m))
    w = np.empty(m)
    K = np.empty((n, m))
    T = np.empty((n, n))
    D = np.empty((n, m))
    per_h, per_r = H.shape[0] > 1, R.shape[0] > 1
    for i in range(M):
        h = i if per_h else 0
        r = i if per_r else 0
        # P Hᵀ, S = ½(C + Cᵀ), C = H (P Hᵀ) + R
        for a in range(n):
            for b in range(m):
                acc = 0.0
                for q in range(n):
                    acc += P[i, a, q] * H[h, b, q]
                PHt[a, b] = acc
        for a in range(m):
            for b in range(m):
                acc = 0.0
                for q in range(n):
                    acc += H[h, a, q] * PHt[q, b]
                S[a, b] = acc + R[r, a, b]
        for a in range(m):
            for b in range(a + 1, m):
                S[a, b] = S[b, a] = 0.5 * (S[a, b] + S[b, a])
        # S⁻¹ and the scores
        if m <= 2:
            sa = S[0, 0]
            if m == 1:
                det = sa
                if not sa > 0.0:
                    return i
                Si[0, 0] = 1.0 / sa
            else:
                sb, sc = S[1, 0], S[1, 1]
                det = sa * sc - sb * sb
                if not (sa > 0.0 and det > 0.0):  # also catches NaN
                    return i
                rd = 1.0 / det
                Si[0, 0] = sc * rd
                Si[1, 1] = sa * rd
                Si[0, 1] = Si[1, 0] = -(sb * rd)
            t = nu[i, 0] / sa
            s_nis = nu[i, 0] * t
            if m == 2:
                res = nu[i, 1] - S[1, 0] * t
                s_nis += sa * (res * res) / det
            log_det = math.log(det)
        else:
            for j in range(m):
                d = S[j, j]
                for k in range(j):
                    d = d - L[j, k] * L[j, k]
                if not d > 0.0:
                    return i
                L[j, j] = math.sqrt(d)
                for a in range(j + 1, m):
                    s = S[a, j]
                    for k in range(j):
                        s = s - L[a, k] * L[j, k]
                    L[a, j] = s / L[j, j]
            for a in range(m):  # L⁻¹, row by row
                Li[a, a] = 1.0 / L[a, a]
                for j in range(a - 1, -1, -1):
                    acc = L[a, j] * Li[j, j]
                    for k in range(j + 1, a):
                        acc = acc + L[a, k] * Li[k, j]
                    Li[a, j] = -acc / L[a, a]
            for a in range(m):  # S⁻¹ = L⁻ᵀ L⁻¹
                for j in range(a, m):
                    acc = Li[j, a] * Li[j, j]
                    for k in range(j + 1, m):
                        acc = acc + Li[k, a] * Li[k, j]
                    Si[a, j] = Si[j, a] = acc
            log_det = math.log(L[0, 0])
            for a in range(1, m):
                log_det += math.log(L[a, a])
            log_det *= 2.0
            s_nis = 0.0
            for a in range(m):  # w = L⁻¹ ν
                acc = nu[i, a]
                for j in range(a):
                    acc = acc - L[a, j] * w[j]
                w[a] = acc / L[a, a]
                s_nis = s_nis + w[a] * w[a]
        nis[i] = s_nis
        loglik[i] = -0.5 * (m * LOG_2PI + log_det + s_nis)
        for a in range(m):
            for b in range(m):
                S_out[i, a, b] = S[a, b]
        # K = P Hᵀ S⁻¹, x⁺ = x⁻ + K ν
        for a in range(n):
            for b in range(m):
                acc = 0.0
                for q in range(m):
                    acc += PHt[a, q] * Si[q, b]
                K[a, b] = acc
        for a in range(n):
            acc = 0.0
            for b in range(m):
                acc += K[a, b] * nu[i, b]
            x_out[i, a] = x[i, a] + acc
        # T = P − K (H P) (Joseph) or P − K (P Hᵀ)ᵀ
        if form == 0:
            for a in range(m):
                for b in range(n):
                    acc = 0.0
                    for q in range(n):
                        acc += H[h, a, q] * P[i, q, b]
                    HP[a, b] = acc
        else:
            for a in range(m):
                for b in range(n):
                    HP[a, b] = PHt[b, a]
        for a in range(n):
            for b in range(n):
                acc = 0.0
                for q in range(m):
                    acc += K[a, q] * HP[q, b]
                T[a, b] = P[i, a, b] - acc
        if form == 0:  # D = K R − T Hᵀ, T += D Kᵀ
            for a in range(n):
                for b in range(m):
                    acc = 0.0
                    for q in range(m):
                        acc += K[a, q] * R[r, q, b]
                    acc2 = 0.0
                    for q in range(n):
                        acc2 += T[a, q] * H[h, b, q]
                    D[a, b] = acc - acc2
            for a in range(n):
                for b in range(n):
                    acc = 0.0
                    for q in range(m):
                        acc += D[a, q] * K[b, q]
                    T[a, b] += acc
        if form == 2:
            for a in range(n):
                for b in range(n):
                    P_out[i, a, b] = T[a, b]
        else:
            for a in range(n):
                P_out[i, a, a] = T[a, a]
                for b in range(a + 1, n):
                    P_out[i, a, b] = P_out[i, b, a] = 0.5 * (T[a, b] + T[b, a])
    return -1
