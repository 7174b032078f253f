"""Compiled steps of the dense covariance Kalman filter (SPEC §3, seed 000 Algorithm 1), by numba.

The same arithmetic as :mod:`._covariance` (predict; update with the three
forms) and :class:`hybridtrack.sdk.linalg.CholeskyFactor` (S⁻¹ and the scores),
run filter by filter in compiled loops over the bank: each call is one pass
over the M filters, every intermediate (F P, P Hᵀ, S, S⁻¹, K, T, D) an n × n,
n × m or m × m scratch array reused from filter to filter, nothing stacked.
The sizes n and m are compile-time constants (each kernel takes tuples of
lengths n and m, whose types carry the lengths, so numba compiles one version
per (n, m) with unrolled, vectorizable loops, cached like the rest) and the
matrices come flattened row-major to (M, n²) etc.  Per filter i (H, R shared
or per filter):

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
whose S is not positive definite (or NaN) stops the pass and the caller raises
the same ``LinAlgError`` as the numpy path.  No ``fastmath``: IEEE semantics as in
numpy, so an overflow leaves inf/NaN for the estimator's finiteness checks.
``error_model="numpy"``: a division by zero gives inf/NaN, not an exception.
``cache=True``: the first call in a fresh checkout compiles (a few seconds)
and caches the machine code next to this file (``__pycache__``).

Imported only on first use by :mod:`._covariance` (loading the plugins does
not import numba).
"""

from __future__ import annotations

import functools
import math

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover - exercised only without numba
    numba = None

LOG_2PI = float(np.log(2.0 * np.pi))
FORMS = {"joseph": 0, "symmetric": 1, "conventional": 2}


def _njit(function, inline="never"):
    return numba.njit(cache=True, error_model="numpy", nogil=True, inline=inline)(function) if numba is not None else function


@functools.partial(_njit, inline="always")
def _inverse_and_scores(S, nu, Si, L, Li, w, m_tuple):  # pragma: no cover - compiled
    """S⁻¹ (into ``Si``), ln det S and NIS = νᵀS⁻¹ν of one filter by the closed forms for m ≤ 2 and the Cholesky
    recurrence for m ≥ 3 (the formulas in the module docstring); S (m²,) symmetric, ν (m,), L, Li (m², zeroed), w
    (m,) scratch, m = ``len(m_tuple)``.  Returns (True, ln det S, NIS), or (False, 0, 0) when S is not positive
    definite (or NaN).  Inlined into :func:`update_bank` and :func:`update_bank_blocked` (one copy of the code)."""
    Mm = len(m_tuple)
    if Mm <= 2:
        sa = S[0]
        if Mm == 1:
            det = sa
            if not sa > 0.0:  # also catches NaN
                return False, 0.0, 0.0
            Si[0] = 1.0 / sa
        else:
            sb, sc = S[2], S[3]
            det = sa * sc - sb * sb
            if not (sa > 0.0 and det > 0.0):  # also catches NaN
                return False, 0.0, 0.0
            rd = 1.0 / det
            Si[0] = sc * rd
            Si[3] = sa * rd
            Si[1] = Si[2] = -(sb * rd)
        t = nu[0] / sa
        s_nis = nu[0] * t
        if Mm == 2:
            res = nu[1] - S[2] * t
            s_nis += sa * (res * res) / det
        log_det = math.log(det)
    else:
        for j in range(Mm):
            d = S[j * Mm + j]
            for k in range(j):
                d = d - L[j * Mm + k] * L[j * Mm + k]
            if not d > 0.0:
                return False, 0.0, 0.0
            L[j * Mm + j] = math.sqrt(d)
            for a in range(j + 1, Mm):
                s = S[a * Mm + j]
                for k in range(j):
                    s = s - L[a * Mm + k] * L[j * Mm + k]
                L[a * Mm + j] = s / L[j * Mm + j]
        for a in range(Mm):  # L⁻¹, row by row
            Li[a * Mm + a] = 1.0 / L[a * Mm + a]
            for j in range(a - 1, -1, -1):
                acc = L[a * Mm + j] * Li[j * Mm + j]
                for k in range(j + 1, a):
                    acc = acc + L[a * Mm + k] * Li[k * Mm + j]
                Li[a * Mm + j] = -acc / L[a * Mm + a]
        for a in range(Mm):  # S⁻¹ = L⁻ᵀ L⁻¹
            for j in range(a, Mm):
                acc = Li[j * Mm + a] * Li[j * Mm + j]
                for k in range(j + 1, Mm):
                    acc = acc + Li[k * Mm + a] * Li[k * Mm + j]
                Si[a * Mm + j] = Si[j * Mm + a] = acc
        log_det = math.log(L[0])
        for a in range(1, Mm):
            log_det += math.log(L[a * Mm + a])
        log_det *= 2.0
        s_nis = 0.0
        for a in range(Mm):  # w = L⁻¹ ν
            acc = nu[a]
            for j in range(a):
                acc = acc - L[a * Mm + j] * w[j]
            w[a] = acc / L[a * Mm + a]
            s_nis = s_nis + w[a] * w[a]
    return True, log_det, s_nis


@functools.partial(_njit, inline="always")
def _predict_one(xi, Pi, Fi, Bi, Qi, xo, Po, FP, N):  # pragma: no cover - compiled
    """x⁻ = F x⁺ + B and P⁻ = ½(C + Cᵀ), C = (F P⁺) Fᵀ + Q, of one filter (matrices flattened row-major), into xo, Po;
    ``FP`` scratch of n²."""
    for j in range(N):
        acc = 0.0
        for k in range(N):
            acc += Fi[j * N + k] * xi[k]
        xo[j] = acc + Bi[j]
    for j in range(N):
        for k in range(N):
            acc = 0.0
            for q in range(N):
                acc += Fi[j * N + q] * Pi[q * N + k]
            FP[j * N + k] = acc
    for j in range(N):
        for k in range(j, N):
            c_jk = 0.0
            c_kj = 0.0
            for q in range(N):
                c_jk += FP[j * N + q] * Fi[k * N + q]
                c_kj += FP[k * N + q] * Fi[j * N + q]
            if j == k:
                Po[j * N + j] = c_jk + Qi[j * N + j]
            else:
                Po[j * N + k] = Po[k * N + j] = 0.5 * ((c_jk + Qi[j * N + k]) + (c_kj + Qi[k * N + j]))


@_njit
def predict_bank(x, P, F, B, Q, x_out, P_out, n_tuple):  # pragma: no cover - compiled
    """The prediction of each filter (module docstring; outputs written in place); ``n_tuple`` any tuple of length n."""
    N = len(n_tuple)
    FP = np.empty(N * N)
    for i in range(x.shape[0]):
        _predict_one(x[i], P[i], F[i], B[i], Q[i], x_out[i], P_out[i], FP, N)


@_njit
def update_bank(x, P, nu, H, R, form, x_out, P_out, S_out, loglik, nis, n_tuple, m_tuple):  # pragma: no cover - compiled
    """The measurement update and scores of each filter (outputs written in place); the first filter whose S is
    not positive definite, or −1.  Matrices flattened row-major: P (M, n²), H (1 or M, m n) shared or per filter,
    R (1 or M, m²), S_out (M, m²); ``n_tuple``, ``m_tuple`` any tuples of lengths n and m (compile-time sizes)."""
    N, Mm = len(n_tuple), len(m_tuple)
    M = x.shape[0]
    PHt = np.empty(N * Mm)
    HP = np.empty(Mm * N)
    S = np.empty(Mm * Mm)
    Si = np.empty(Mm * Mm)
    L = np.zeros(Mm * Mm)
    Li = np.zeros(Mm * Mm)
    w = np.empty(Mm)
    K = np.empty(N * Mm)
    T = np.empty(N * N)
    D = np.empty(N * Mm)
    per_h, per_r = H.shape[0] > 1, R.shape[0] > 1
    for i in range(M):
        Pi, Hi, Ri, nui = P[i], H[i if per_h else 0], R[i if per_r else 0], nu[i]
        # P Hᵀ, S = ½(C + Cᵀ), C = H (P Hᵀ) + R
        for a in range(N):
            for b in range(Mm):
                acc = 0.0
                for q in range(N):
                    acc += Pi[a * N + q] * Hi[b * N + q]
                PHt[a * Mm + b] = acc
        for a in range(Mm):
            for b in range(Mm):
                acc = 0.0
                for q in range(N):
                    acc += Hi[a * N + q] * PHt[q * Mm + b]
                S[a * Mm + b] = acc + Ri[a * Mm + b]
        for a in range(Mm):
            for b in range(a + 1, Mm):
                S[a * Mm + b] = S[b * Mm + a] = 0.5 * (S[a * Mm + b] + S[b * Mm + a])
        # S⁻¹ and the scores
        ok, log_det, s_nis = _inverse_and_scores(S, nui, Si, L, Li, w, m_tuple)
        if not ok:
            return i
        nis[i] = s_nis
        loglik[i] = -0.5 * (Mm * LOG_2PI + log_det + s_nis)
        So = S_out[i]
        for a in range(Mm * Mm):
            So[a] = S[a]
        # K = P Hᵀ S⁻¹, x⁺ = x⁻ + K ν
        for a in range(N):
            for b in range(Mm):
                acc = 0.0
                for q in range(Mm):
                    acc += PHt[a * Mm + q] * Si[q * Mm + b]
                K[a * Mm + b] = acc
        for a in range(N):
            acc = 0.0
            for b in range(Mm):
                acc += K[a * Mm + b] * nui[b]
            x_out[i, a] = x[i, a] + acc
        # T = P − K (H P) (Joseph) or P − K (P Hᵀ)ᵀ
        if form == 0:
            for a in range(Mm):
                for b in range(N):
                    acc = 0.0
                    for q in range(N):
                        acc += Hi[a * N + q] * Pi[q * N + b]
                    HP[a * N + b] = acc
        else:
            for a in range(Mm):
                for b in range(N):
                    HP[a * N + b] = PHt[b * Mm + a]
        for a in range(N):
            for b in range(N):
                acc = 0.0
                for q in range(Mm):
                    acc += K[a * Mm + q] * HP[q * N + b]
                T[a * N + b] = Pi[a * N + b] - acc
        if form == 0:  # D = K R − T Hᵀ, T += D Kᵀ
            for a in range(N):
                for b in range(Mm):
                    acc = 0.0
                    for q in range(Mm):
                        acc += K[a * Mm + q] * Ri[q * Mm + b]
                    acc2 = 0.0
                    for q in range(N):
                        acc2 += T[a * N + q] * Hi[b * N + q]
                    D[a * Mm + b] = acc - acc2
            for a in range(N):
                for b in range(N):
                    acc = 0.0
                    for q in range(Mm):
                        acc += D[a * Mm + q] * K[b * Mm + q]
                    T[a * N + b] += acc
        Po = P_out[i]
        if form == 2:
            for a in range(N * N):
                Po[a] = T[a]
        else:
            for a in range(N):
                Po[a * N + a] = T[a * N + a]
                for b in range(a + 1, N):
                    Po[a * N + b] = Po[b * N + a] = 0.5 * (T[a * N + b] + T[b * N + a])
    return -1


# ---------------------------------------------------------------------------------------------- the fast lanes
# Kernels of the estimator's compiled fast lanes (``KalmanFilter`` with a bank it has already checked and a
# measurement model it has already assembled): each computes one whole step from the raw inputs, checks what
# the numpy path checks (z finite and within the magnitude limit, S positive definite, every output finite) and
# returns a status instead of raising: 0 when the step is good, non-zero when the caller must run the reference
# path instead (which handles NaN components and raises the usual errors).


#: filters per block of the blocked lane kernels (:func:`predict_bank_checked`, :func:`update_bank_blocked`): the
#: filter index is the innermost (stride-1) index of their scratch, so LLVM vectorizes each block's arithmetic
#: across filters (8 doubles per AVX-512 register); 16 was the fastest of 8, 16, 32, 64, 128 at n = 4, m = 2
LANE_WIDTH = 16


def lane_blocks(A: np.ndarray, width: int = LANE_WIDTH) -> np.ndarray:
    """(M, k) → (⌈M/width⌉, k, width): filter i at block i // width, lane i % width, the last block padded with
    copies of the last filter (the operands F, B, Q of :func:`predict_bank_checked`, made once per bank)."""
    A = np.asarray(A, dtype=float)
    M = A.shape[0]
    blocks = -(-M // width)
    index = np.minimum(np.arange(blocks * width), M - 1)
    return np.ascontiguousarray(A.reshape(M, -1)[index].reshape(blocks, width, -1).transpose(0, 2, 1))


@_njit
def predict_bank_checked(x, P, F, B, Q, x_out, P_out, n_tuple, w_tuple):  # pragma: no cover - compiled
    """:func:`predict_bank` (x⁻ = F x⁺ + B, P⁻ = (F P⁺) Fᵀ + Q) computing the upper triangle of P⁻ only and mirroring it
    (P⁻ is symmetric: the lower triangle of (F P⁺) Fᵀ equals the upper to rounding, so no ½(C + Cᵀ) is needed);
    returns 0, or 1 when an output is not finite.

    Blocked across filters: F, B, Q come as :func:`lane_blocks` (⌈M/W⌉, n², W) etc., W = ``len(w_tuple)``
    (:data:`LANE_WIDTH`); each block of W filters is copied into a scratch with the filter index innermost, computed
    in one loop over its lanes whose body has compile-time offsets only (n = ``len(n_tuple)``), which LLVM vectorizes
    across filters, and copied out.  The same operations in the same order per filter as the filter-by-filter loop
    (x⁻_j = B_j + Σ_k F_jk x_k, (F P)_jk = Σ_q F_jq P_qk, P⁻_jk = Q_jk + Σ_q (F P)_jq F_kq, sums in index order): the
    results are bitwise those of that loop.  Non-finite outputs are found lane-wise by Σ (v − v) (0 for finite v,
    NaN otherwise)."""
    N = len(n_tuple)
    W = len(w_tuple)
    NN = N * N
    OX, OP, OXO, OFP, OPO, OCHK = 0, N, N + NN, 2 * N + NN, 2 * N + 2 * NN, 2 * N + 3 * NN
    M = x.shape[0]
    buf = np.zeros((OCHK + 1, W))
    bad = 0
    for blk in range(F.shape[0]):
        i0 = blk * W
        cnt = min(W, M - i0)
        for ln in range(cnt):
            for a in range(N):
                buf[OX + a, ln] = x[i0 + ln, a]
            for a in range(NN):
                buf[OP + a, ln] = P[i0 + ln, a]
        Fb, Bb, Qb = F[blk], B[blk], Q[blk]
        for ln in range(W):  # vectorized across the block's filters
            chk = 0.0
            for j in range(N):
                acc = Bb[j, ln]
                for k in range(N):
                    acc += Fb[j * N + k, ln] * buf[OX + k, ln]
                buf[OXO + j, ln] = acc
                chk += acc - acc
            for j in range(N):
                for k in range(N):
                    acc = 0.0
                    for q in range(N):
                        acc += Fb[j * N + q, ln] * buf[OP + q * N + k, ln]
                    buf[OFP + j * N + k, ln] = acc
            for j in range(N):
                for k in range(j, N):
                    acc = Qb[j * N + k, ln]
                    for q in range(N):
                        acc += buf[OFP + j * N + q, ln] * Fb[k * N + q, ln]
                    buf[OPO + j * N + k, ln] = acc
                    chk += acc - acc
            buf[OCHK, ln] = chk
        for ln in range(cnt):
            i = i0 + ln
            if buf[OCHK, ln] != 0.0:  # inf or NaN
                bad = 1
            xo, Po = x_out[i], P_out[i]
            for j in range(N):
                xo[j] = buf[OXO + j, ln]
                for k in range(j, N):
                    v = buf[OPO + j * N + k, ln]
                    Po[j * N + k] = v
                    Po[k * N + j] = v
    return bad


@_njit
def update_bank_blocked(
    x, P, z, sel, R, limit, x_out, P_out, nu_out, S_out, loglik, nis, n_tuple, m_tuple, f_tuple, w_tuple
):  # pragma: no cover
    """The update of each filter for a selection H (rows e_sel[b]ᵀ, the position sensors) with ν = z − x⁻[sel]
    computed here: P Hᵀ = P⁻[:, sel], H P = P⁻[sel, :], S = ½(C + Cᵀ), C = P⁻[sel][:, sel] + R, the Joseph
    T Hᵀ = T[:, sel] = P⁻[:, sel] − K P⁻[sel][:, sel]; otherwise the arithmetic of :func:`update_bank` (P⁺ by the
    form ``len(f_tuple) − 1``), except that the Joseph U = T + (K R − T Hᵀ) Kᵀ, symmetric in exact arithmetic, has
    its upper triangle formed and mirrored (the reference's ½(U + Uᵀ) differs by rounding only).  z (1 or M, m),
    R (m²,).

    Blocked across filters like :func:`predict_bank_checked`: per block of W = ``len(w_tuple)`` filters, x, ν,
    P⁻, P⁻[:, sel], P⁻[sel, :] and P⁻[sel][:, sel] are copied into a scratch with the filter index innermost; one
    loop over the lanes with compile-time offsets only takes the step (for m ≤ 2, S⁻¹ and NIS by the closed forms
    of the module docstring, vectorized by LLVM; for m ≥ 3 by the Cholesky recurrence, lane by lane); the copy out
    takes ℓ (the logarithm per filter: no vector logarithm without SVML).  The same operations in the same order
    per filter whatever W: 1-wide blocks are the filter-by-filter loop, bitwise.  Returns 0, or 1 when z has an
    entry that is NaN or beyond ``limit``, S is not positive definite or an output is not finite."""
    N, Mm, form, W = len(n_tuple), len(m_tuple), len(f_tuple) - 1, len(w_tuple)
    NN = N * N
    OX = 0
    OP = OX + N
    ONU = OP + NN
    OPH = ONU + Mm  # P[:, sel]  (N, m)
    OHP = OPH + N * Mm  # P[sel, :]  (m, N)
    OSS = OHP + Mm * N  # P[sel][:, sel]  (m, m)
    OS = OSS + Mm * Mm
    OSI = OS + Mm * Mm
    OK = OSI + Mm * Mm
    OXO = OK + N * Mm
    OT = OXO + N
    OD = OT + NN
    OPO = OD + N * Mm
    ODET = OPO + NN
    ONIS = ODET + 1
    OCHK = ONIS + 1
    M = x.shape[0]
    per_z = z.shape[0] > 1
    for b in range(z.shape[0]):
        for a in range(Mm):
            if not abs(z[b, a]) <= limit:
                return 1
    OL = OCHK + 1  # m ≥ 3: the Cholesky scratch L, L⁻¹ (zeroed) and w per lane
    buf = np.zeros((OL + (2 * Mm * Mm + Mm if Mm > 2 else 0), W))
    for blk in range(-(-M // W)):
        i0 = blk * W
        cnt = min(W, M - i0)
        for ln in range(cnt):
            i = i0 + ln
            Pi, xi, zi = P[i], x[i], z[i if per_z else 0]
            for a in range(N):
                buf[OX + a, ln] = xi[a]
            for a in range(NN):
                buf[OP + a, ln] = Pi[a]
            for a in range(Mm):
                buf[ONU + a, ln] = zi[a] - xi[sel[a]]
                for b in range(N):
                    buf[OPH + b * Mm + a, ln] = Pi[b * N + sel[a]]
                    buf[OHP + a * N + b, ln] = Pi[sel[a] * N + b]
                for b in range(Mm):
                    buf[OSS + a * Mm + b, ln] = Pi[sel[a] * N + sel[b]]
        for ln in range(W):  # vectorized across the block's filters
            for a in range(Mm):
                buf[OS + a * Mm + a, ln] = buf[OSS + a * Mm + a, ln] + R[a * Mm + a]
                for b in range(a + 1, Mm):
                    v = 0.5 * ((buf[OSS + a * Mm + b, ln] + R[a * Mm + b]) + (buf[OSS + b * Mm + a, ln] + R[b * Mm + a]))
                    buf[OS + a * Mm + b, ln] = v
                    buf[OS + b * Mm + a, ln] = v
            if Mm <= 2:  # the closed forms, vectorized (no logarithm: ln det S is taken in the copy out)
                sa = buf[OS, ln]
                nu0 = buf[ONU, ln]
                if Mm == 1:
                    det = sa
                    buf[OSI, ln] = 1.0 / sa
                else:
                    sb, sc = buf[OS + 2, ln], buf[OS + 3, ln]
                    det = sa * sc - sb * sb
                    rd = 1.0 / det
                    buf[OSI, ln] = sc * rd
                    buf[OSI + 3, ln] = sa * rd
                    buf[OSI + 1, ln] = -(sb * rd)
                    buf[OSI + 2, ln] = -(sb * rd)
                t = nu0 / sa
                s_nis = nu0 * t
                if Mm == 2:
                    res = buf[ONU + 1, ln] - buf[OS + 2, ln] * t
                    s_nis += sa * (res * res) / det
                # S positive definite: a > 0 and det S > 0 (False for NaN); else a NaN check sum
                chk = 0.0 if (sa > 0.0 and det > 0.0) else math.nan
            else:  # the Cholesky recurrence, lane by lane; ODET holds ln det S
                S, nu, Si = buf[OS : OS + Mm * Mm, ln], buf[ONU : ONU + Mm, ln], buf[OSI : OSI + Mm * Mm, ln]
                L, Li, w = buf[OL : OL + Mm * Mm, ln], buf[OL + Mm * Mm : OL + 2 * Mm * Mm, ln], buf[OL + 2 * Mm * Mm :, ln]
                ok, det, s_nis = _inverse_and_scores(S, nu, Si, L, Li, w, m_tuple)
                chk = 0.0 if ok else math.nan
            buf[ODET, ln] = det
            buf[ONIS, ln] = s_nis
            for a in range(N):
                acc2 = buf[OX + a, ln]
                for b in range(Mm):
                    acc = 0.0
                    for q in range(Mm):
                        acc += buf[OPH + a * Mm + q, ln] * buf[OSI + q * Mm + b, ln]
                    buf[OK + a * Mm + b, ln] = acc
                    acc2 += acc * buf[ONU + b, ln]
                buf[OXO + a, ln] = acc2
                chk += acc2 - acc2
            for a in range(N):
                for b in range(N):
                    acc = 0.0
                    for q in range(Mm):
                        if form == 0:
                            acc += buf[OK + a * Mm + q, ln] * buf[OHP + q * N + b, ln]
                        else:
                            acc += buf[OK + a * Mm + q, ln] * buf[OPH + b * Mm + q, ln]
                    buf[OT + a * N + b, ln] = buf[OP + a * N + b, ln] - acc
            if form == 0:  # D = K R − T[:, sel], T[:, sel] = P[:, sel] − K P[sel][:, sel]; U = T + D Kᵀ (upper)
                for a in range(N):
                    for b in range(Mm):
                        acc = 0.0
                        for q in range(Mm):
                            acc += buf[OK + a * Mm + q, ln] * R[q * Mm + b]
                        acc3 = 0.0
                        for q in range(Mm):
                            acc3 += buf[OK + a * Mm + q, ln] * buf[OSS + q * Mm + b, ln]
                        buf[OD + a * Mm + b, ln] = acc - (buf[OPH + a * Mm + b, ln] - acc3)
                for a in range(N):
                    for b in range(a, N):
                        v = buf[OT + a * N + b, ln]
                        for q in range(Mm):
                            v += buf[OD + a * Mm + q, ln] * buf[OK + b * Mm + q, ln]
                        buf[OPO + a * N + b, ln] = v
                        chk += v - v
            elif form == 1:
                for a in range(N):
                    buf[OPO + a * N + a, ln] = buf[OT + a * N + a, ln]
                    chk += buf[OT + a * N + a, ln] - buf[OT + a * N + a, ln]
                    for b in range(a + 1, N):
                        v = 0.5 * (buf[OT + a * N + b, ln] + buf[OT + b * N + a, ln])
                        buf[OPO + a * N + b, ln] = v
                        chk += v - v
            else:
                for a in range(NN):
                    buf[OPO + a, ln] = buf[OT + a, ln]
                    chk += buf[OT + a, ln] - buf[OT + a, ln]
            buf[OCHK, ln] = chk
        for ln in range(cnt):
            i = i0 + ln
            if buf[OCHK, ln] != 0.0:  # S not positive definite, or an output inf or NaN
                return 1
            s_nis = buf[ONIS, ln]
            ll = -0.5 * (Mm * LOG_2PI + (math.log(buf[ODET, ln]) if Mm <= 2 else buf[ODET, ln]) + s_nis)
            if ll - ll != 0.0:  # inf or NaN
                return 1
            nis[i] = s_nis
            loglik[i] = ll
            xo, Po, So, nuo = x_out[i], P_out[i], S_out[i], nu_out[i]
            for a in range(Mm):
                nuo[a] = buf[ONU + a, ln]
            for a in range(Mm * Mm):
                So[a] = buf[OS + a, ln]
            for a in range(N):
                xo[a] = buf[OXO + a, ln]
            if form == 2:
                for a in range(NN):
                    Po[a] = buf[OPO + a, ln]
            else:
                for a in range(N):
                    for b in range(a, N):
                        v = buf[OPO + a * N + b, ln]
                        Po[a * N + b] = v
                        Po[b * N + a] = v
    return 0


@_njit
def axis_predict(xa, Pa, F, B, Q, x_out, P_out, d_tuple):  # pragma: no cover - compiled
    """The axis-separable predict of :func:`._separable.predict` per axis a and filter i (x (d, A, M), P, F, Q
    (d, d, A, M), B (d, A, M)): x⁻ = F x + B, P⁻ = (F P) Fᵀ + Q, every entry formed (as the numpy path does);
    ``d_tuple`` any tuple of length d (compile-time block size).  Returns 0, or 1 when an output is not finite."""
    d = len(d_tuple)
    A, M = xa.shape[1], xa.shape[2]
    T = np.empty(d * d)
    bad = 0
    for a in range(A):
        for i in range(M):
            for j in range(d):
                acc = B[j, a, i]
                for k in range(d):
                    acc += F[j, k, a, i] * xa[k, a, i]
                x_out[j, a, i] = acc
                if acc - acc != 0.0:  # inf or NaN
                    bad = 1
            for j in range(d):
                for k in range(d):
                    acc = 0.0
                    for q in range(d):
                        acc += F[j, q, a, i] * Pa[q, k, a, i]
                    T[j * d + k] = acc
            for j in range(d):
                for k in range(d):
                    acc = 0.0
                    for q in range(d):
                        acc += T[j * d + q] * F[k, q, a, i]
                    acc += Q[j, k, a, i]
                    P_out[j, k, a, i] = acc
                    if acc - acc != 0.0:
                        bad = 1
    return bad


@_njit
def axis_update(xa, Pa, z, axis_row, c, r, form, limit, x_out, P_out, nu, S, loglik, nis, d_tuple):  # pragma: no cover
    """The scalar updates of :func:`._separable.update`: measurement row b (column b of z (1 or M, m)) measures
    component c of axis ``axis_row[b]`` with variance r[b]; per filter and measured axis the scalar update of
    :mod:`._separable`; ℓ = −½(m ln 2π + ln Π_rows s + Σ_rows ν²/s) (one logarithm per filter), NIS = Σ ν²/s; ν (M, m) and
    S = diag(s) (M, m, m, zero elsewhere) in the rows' order; the axes no row measures are copied.  ``d_tuple``
    any tuple of length d.  Returns 0, or 1 when z has an entry that is NaN or beyond ``limit``, some s ≤ 0 or an
    output is not finite (also when Π s over- or underflows: the reference then takes the step)."""
    d = len(d_tuple)
    A, M = xa.shape[1], xa.shape[2]
    m = axis_row.shape[0]
    per_z = z.shape[0] > 1
    for b in range(z.shape[0]):
        for a in range(m):
            if not abs(z[b, a]) <= limit:
                return 1
    if m < A:
        x_out[...] = xa
        P_out[...] = Pa
    kv = np.empty(d)
    bad = 0
    for i in range(M):
        prod = 1.0
        ni = 0.0
        zi = z[i if per_z else 0]
        for b in range(m):
            a = axis_row[b]
            s = Pa[c, c, a, i] + r[b]
            if not s > 0.0:
                return 1
            s_inv = 1.0 / s
            v = zi[b] - xa[c, a, i]
            for j in range(d):
                kv[j] = Pa[j, c, a, i] * s_inv
                xo = xa[j, a, i] + kv[j] * v
                x_out[j, a, i] = xo
                if xo - xo != 0.0:
                    bad = 1
            for j in range(d):
                for k in range(d):
                    kk = kv[j] * kv[k] * s
                    if form == 0:
                        val = Pa[j, k, a, i] - (kv[j] * Pa[c, k, a, i] + kv[k] * Pa[c, j, a, i]) + kk
                    else:
                        val = Pa[j, k, a, i] - kk
                    P_out[j, k, a, i] = val
                    if val - val != 0.0:
                        bad = 1
            nu[i, b] = v
            for q in range(m):
                S[i, b, q] = 0.0
            S[i, b, b] = s
            ni += v * v * s_inv
            prod *= s
        ll = -0.5 * (LOG_2PI * m + math.log(prod) + ni)
        nis[i] = ni
        loglik[i] = ll
        if ll - ll != 0.0 or not prod > 0.0:
            bad = 1
    return bad


# ---------------------------------------------------------------------------------------------- the restart lane
# Kernels of ``KalmanFilter.restart_step``: a bank started afresh at every step (the model-matched filters of the
# multiple-model estimators), predicted and updated with each filter's own row of z, whatever its missing
# components.  Statuses as for the fast lanes: 0 good, non-zero the caller must take the reference steps.

#: a Cholesky pivot at or below this fraction of its diagonal entry sends the step to the reference path (which
#: decides, with LAPACK's factorization, whether the matrix is positive definite: near singular, the two may differ)
PIVOT_MARGIN = 1e-12


@_njit
def restart_predict(x0, P0, F, B, Q, limit, rtol, x_out, P_out, n_tuple):  # pragma: no cover - compiled
    """Start each filter at N(x0, P0) and predict it: the prior checked as ``check_prior`` does (finite, every entry
    within ``limit``, each positive variance ≥ 1/``limit``, symmetric to ``rtol`` of the largest entry, positive
    definite by the Cholesky recurrence with the margin :data:`PIVOT_MARGIN`), F, B, Q finite, then
    :func:`predict_bank`'s x⁻ = F x⁺ + B, P⁻ = ½(C + Cᵀ), C = (F P⁺) Fᵀ + Q.  Matrices flattened row-major to
    (M, n²); ``n_tuple`` any tuple of length n.  Returns 0, or 1 when a check fails or an output is not finite."""
    N = len(n_tuple)
    M = x0.shape[0]
    FP = np.empty(N * N)
    L = np.empty(N * N)
    scale = 0.0
    skew = 0.0
    for i in range(M):
        xi, Pi, Fi, Qi, Po = x0[i], P0[i], F[i], Q[i], P_out[i]
        for a in range(N):
            if not abs(xi[a]) <= limit or not abs(B[i, a]) < math.inf:
                return 1
        for a in range(N * N):
            v = Pi[a]
            if not abs(v) <= limit or not abs(Fi[a]) < math.inf or not abs(Qi[a]) < math.inf:
                return 1
            scale = max(scale, abs(v))
        for a in range(N):
            d = Pi[a * N + a]
            if 0.0 < d < 1.0 / limit:
                return 1
            for b in range(a + 1, N):
                skew = max(skew, abs(Pi[a * N + b] - Pi[b * N + a]))
        for j in range(N):  # positive definite: the Cholesky recurrence on the lower triangle
            d = Pi[j * N + j]
            for k in range(j):
                d -= L[j * N + k] * L[j * N + k]
            if not d > PIVOT_MARGIN * Pi[j * N + j]:
                return 1
            L[j * N + j] = math.sqrt(d)
            for a in range(j + 1, N):
                s = Pi[a * N + j]
                for k in range(j):
                    s -= L[a * N + k] * L[j * N + k]
                L[a * N + j] = s / L[j * N + j]
        _predict_one(xi, Pi, Fi, B[i], Qi, x_out[i], Po, FP, N)
        for a in range(N):
            if x_out[i, a] - x_out[i, a] != 0.0:
                return 1
        for a in range(N * N):
            if Po[a] - Po[a] != 0.0:
                return 1
    if skew > rtol * max(scale, 2.2250738585072014e-308):
        return 1
    return 0


@functools.partial(_njit, inline="always")
def _update_present(i, p, xi, Pi, zi, Ei, xo, Po, loglik, nis, rows, cols, R, e, offset, form, N, Mm, scratch):  # pragma: no cover
    """The update of filter i on its p present rows (``rows``, their state components ``cols``): the body of
    :func:`update_rows` (its docstring), inlined twice there — with p = m, a compile-time constant (all rows present:
    fixed-length loops), and with the p of a row with missing components.  ℓ and NIS into ``loglik[i]``,
    ``nis[i]``; False when S is not positive definite or an output is not finite."""
    S, Rp, L, Li, Si, w, nu, PH, K, T, D = scratch
    for a in range(N):  # P Hᵀ
        for b in range(p):
            PH[a, b] = Pi[a * N + cols[b]]
    for a in range(p):
        nu[a] = zi[rows[a]] - xi[cols[a]]
        ra = rows[a] - offset
        for b in range(p):
            rb = rows[b] - offset
            if 0 <= ra < e and 0 <= rb < e:
                Rp[a, b] = R[rows[a] * Mm + rows[b]] + Ei[ra, rb]
            else:
                Rp[a, b] = R[rows[a] * Mm + rows[b]]
    for a in range(p):
        S[a, a] = PH[cols[a], a] + Rp[a, a]
        for b in range(a + 1, p):
            S[a, b] = S[b, a] = 0.5 * ((PH[cols[a], b] + Rp[a, b]) + (PH[cols[b], a] + Rp[b, a]))
    for j in range(p):  # L Lᵀ = S
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > PIVOT_MARGIN * S[j, j]:
            return False
        L[j, j] = math.sqrt(d)
        for a in range(j + 1, p):
            s = S[a, j]
            for k in range(j):
                s -= L[a, k] * L[j, k]
            L[a, j] = s / L[j, j]
    for a in range(p):  # L⁻¹, row by row
        Li[a, a] = 1.0 / L[a, a]
        for j in range(a - 1, -1, -1):
            acc = L[a, j] * Li[j, j]
            for k in range(j + 1, a):
                acc += L[a, k] * Li[k, j]
            Li[a, j] = -acc / L[a, a]
    for a in range(p):  # S⁻¹ = L⁻ᵀ L⁻¹
        for j in range(a, p):
            acc = Li[j, a] * Li[j, j]
            for k in range(j + 1, p):
                acc += Li[k, a] * Li[k, j]
            Si[a, j] = Si[j, a] = acc
    log_det = 0.0
    s_nis = 0.0
    for a in range(p):  # w = L⁻¹ ν
        log_det += math.log(L[a, a])
        acc = nu[a]
        for j in range(a):
            acc -= L[a, j] * w[j]
        w[a] = acc / L[a, a]
        s_nis += w[a] * w[a]
    ll = -0.5 * (p * LOG_2PI + 2.0 * log_det + s_nis)
    if ll - ll != 0.0 or s_nis - s_nis != 0.0:
        return False
    loglik[i] = ll
    nis[i] = s_nis
    for a in range(N):  # K = P Hᵀ S⁻¹, x⁺ = x⁻ + K ν
        acc2 = 0.0
        for b in range(p):
            acc = 0.0
            for q in range(p):
                acc += PH[a, q] * Si[q, b]
            K[a, b] = acc
            acc2 += acc * nu[b]
        v = xi[a] + acc2
        if v - v != 0.0:
            return False
        xo[a] = v
    for a in range(N):  # T = P − K (H P), H P = (P Hᵀ)ᵀ
        for b in range(N):
            acc = 0.0
            for q in range(p):
                acc += K[a, q] * PH[b, q]
            T[a, b] = Pi[a * N + b] - acc
    if form == 0:  # D = K R − T Hᵀ, T += D Kᵀ
        for a in range(N):
            for b in range(p):
                acc = 0.0
                for q in range(p):
                    acc += K[a, q] * Rp[q, b]
                D[a, b] = acc - T[a, cols[b]]
        for a in range(N):
            for b in range(N):
                acc = 0.0
                for q in range(p):
                    acc += D[a, q] * K[b, q]
                T[a, b] += acc
    for a in range(N):
        v = T[a, a]
        if v - v != 0.0:
            return False
        Po[a * N + a] = v
        for b in range(a + 1, N):
            v = 0.5 * (T[a, b] + T[b, a])
            if v - v != 0.0:
                return False
            Po[a * N + b] = Po[b * N + a] = v
    return True


@_njit
def update_rows(x, P, z, sel, R, extra, offset, form, limit, x_out, P_out, loglik, nis, dims, n_tuple, m_tuple):  # pragma: no cover
    """The update of each filter with its own row of z (M, m), NaN components not measured (any pattern per row):
    for the present rows p of filter i (H the selection of the state components ``sel[p]``, R_i = R + E_i restricted
    to p: R (m²,) the state-independent part, E_i = ``extra`` (M or 1, e, e) the state-dependent one on the rows
    ``offset`` … ``offset`` + e − 1 (e = 0: none)), S = ½(C + Cᵀ), C = P⁻[sel_p][:, sel_p] + R_pp, factored by the Cholesky recurrence (margin
    :data:`PIVOT_MARGIN`), S⁻¹ = L⁻ᵀ L⁻¹, ln det S = 2 Σ ln L_jj, NIS = |L⁻¹ν|², K = P⁻[:, sel_p] S⁻¹,
    x⁺ = x⁻ + K ν, P⁺ by ``form`` (0 Joseph: T = P⁻ − K P⁻[sel_p, :], U = T + (K R_pp − T[:, sel_p]) Kᵀ,
    P⁺ = ½(U + Uᵀ); 1 symmetric: P⁺ = ½(T + Tᵀ), T = P⁻ − K (P⁻[:, sel_p])ᵀ) and ℓ = −½(|p| ln 2π + ln det S +
    NIS) — :func:`update_bank`'s arithmetic on the present rows; a filter with none keeps its prediction (ℓ = NIS =
    0).  P⁻ must be exactly symmetric (as :func:`restart_predict` gives it): P⁻[sel_p, :] is read as P⁻[:, sel_p]ᵀ.
    ``dims`` gets |p|.  Returns 0, or 1 when a present entry of z is beyond ``limit`` (or ±inf), S is not positive
    definite or an output is not finite."""
    N, Mm = len(n_tuple), len(m_tuple)
    M = x.shape[0]
    e = extra.shape[1]
    per_e = extra.shape[0] > 1
    rows = np.empty(Mm, dtype=np.intp)
    cols = np.empty(Mm, dtype=np.intp)
    square = (np.empty((Mm, Mm)), np.empty((Mm, Mm)), np.zeros((Mm, Mm)), np.zeros((Mm, Mm)), np.empty((Mm, Mm)))
    scratch = square + (np.empty(Mm), np.empty(Mm), np.empty((N, Mm)), np.empty((N, Mm)), np.empty((N, N)), np.empty((N, Mm)))
    for i in range(M):
        xi, Pi, zi, Ei, xo, Po = x[i], P[i], z[i], extra[i if per_e else 0], x_out[i], P_out[i]
        p = 0
        for a in range(Mm):
            if zi[a] == zi[a]:  # not NaN
                if not abs(zi[a]) <= limit:
                    return 1
                rows[p] = a
                cols[p] = sel[a]
                p += 1
        dims[i] = p
        if p == 0:
            for a in range(N):
                xo[a] = xi[a]
            for a in range(N * N):
                Po[a] = Pi[a]
            loglik[i] = 0.0
            nis[i] = 0.0
            continue
        if p == Mm:  # every row present: the loops over m have a compile-time length
            ok = _update_present(i, Mm, xi, Pi, zi, Ei, xo, Po, loglik, nis, rows, cols, R, e, offset, form, N, Mm, scratch)
        else:
            ok = _update_present(i, p, xi, Pi, zi, Ei, xo, Po, loglik, nis, rows, cols, R, e, offset, form, N, Mm, scratch)
        if not ok:
            return 1
    return 0
