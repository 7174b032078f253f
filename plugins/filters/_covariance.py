"""Covariance-form Kalman filter maths over stacked arrays (SPEC §3, seed 000 Algorithm 1).

x has shape (M, n), P (M, n, n); F (M, n, n), B (M, n), Q (M, n, n) = G Q_w Gᵀ.
"""

from __future__ import annotations

import numpy as np

from hybridtrack_plugins.filters._linalg import CholeskyFactor, gaussian_scores, symmetrize

UPDATE_FORMS = ("joseph", "symmetric", "conventional")


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, B: np.ndarray, Q: np.ndarray, Ft: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """x⁻ = F x⁺ + B u, P⁻ = F P⁺ Fᵀ + G Q Gᵀ (seed 000 eqs. 4–5), P⁻ symmetrised.

    ``Ft``: Fᵀ as a contiguous stack, if the caller keeps one (a stacked matmul
    with a transposed view is about twice as slow as with a contiguous operand).
    """
    x_pred = np.einsum("mij,mj->mi", F, x)
    x_pred += B
    if Ft is None:
        Ft = np.ascontiguousarray(np.swapaxes(F, -1, -2))
    P_pred = F @ P @ Ft
    P_pred += Q
    return x_pred, symmetrize(P_pred)


def as_index(selection) -> slice | list[int]:
    """The state indices a selection H picks, as a slice when they are evenly spaced (a view instead of a gather)."""
    idx = [int(i) for i in selection]
    if len(idx) == 1:
        return slice(idx[0], idx[0] + 1)
    step = idx[1] - idx[0]
    if step > 0 and all(b - a == step for a, b in zip(idx, idx[1:])):
        return slice(idx[0], idx[-1] + 1, step)
    return idx


def _times_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """A C for a stack A (M, p, q) and C (q, r) shared by the bank (one BLAS call) or (M, q, r)."""
    if C.ndim == 2:
        M, p, q = A.shape
        return (A.reshape(M * p, q) @ C).reshape(M, p, C.shape[-1])
    return A @ C


def update(x, P, nu, H, R, selection=None, form: str = "joseph"):
    """One measurement update (seed 000 eqs. 6–9 with the SPEC §3 correction P⁺ = (I − K H) P⁻).

    S = H P⁻ Hᵀ + R, K = P⁻ Hᵀ S⁻¹ (S⁻¹ from the Cholesky factor of S), x⁺ = x⁻ + K ν, and

    * ``joseph``: P⁺ = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ (PSD by construction),
      evaluated as T = (I − K H) P⁻ = P⁻ − K (H P⁻), then
      P⁺ = T (I − K H)ᵀ + K R Kᵀ = T + (K R − T Hᵀ) Kᵀ, symmetrised — the
      same two-sided product for any K, with the products by I − K H written
      as rank-m corrections (no n × n matrix I − K H is formed);
    * ``symmetric``: P⁺ = P⁻ − K S Kᵀ = P⁻ − K (P⁻ Hᵀ)ᵀ, symmetrised,
    * ``conventional``: P⁺ = (I − K H) P⁻ as printed, no symmetrisation (kept
      to show how it breaks on ill-conditioned problems, docs/estimators.md).

    H is (m, n) or (M, m, n), R (m, m) or (M, m, m); a shared H or R multiplies
    the whole bank in one BLAS call.  With ``selection`` (the state indices H
    picks) the products with H become indexing.  Returns x⁺, P⁺, S, L = chol(S), K.
    """
    x_new, P_new, S, factor, K = _update(x, P, nu, H, R, selection, form)
    return x_new, P_new, S, factor.L, K


def update_scored(x, P, nu, H, R, selection=None, form: str = "joseph"):
    """:func:`update` plus the innovation scores from the same factor of S.

    Returns x⁺, P⁺, S, ℓ, NIS with ℓ = −½(m ln 2π + ln det S + NIS), NIS = νᵀS⁻¹ν (SPEC §4).
    """
    x_new, P_new, S, factor, _ = _update(x, P, nu, H, R, selection, form)
    loglik, nis = factor.scores(nu)
    return x_new, P_new, S, loglik, nis


def _update(x, P, nu, H, R, selection, form):
    if form not in UPDATE_FORMS:
        raise ValueError(f"form: expected one of {UPDATE_FORMS}, got {form!r}")
    M, n = x.shape
    m = nu.shape[-1]
    if selection is not None:
        idx = as_index(selection)
        PHt = P[:, :, idx]  # P Hᵀ (M, n, m)
        S = PHt[:, idx, :] + R
    else:
        Ht = np.ascontiguousarray(np.swapaxes(H, -1, -2))
        PHt = _times_matrix(P, Ht)
        S = H @ PHt + R
    S = _symmetrize_small(S)
    factor = CholeskyFactor(S, "innovation covariance S")
    K = PHt @ factor.inverse()  # (M, n, m)
    if form == "joseph":
        # one stacked product gives K (H P⁻) and K ν
        Y = np.empty((M, m, n + 1))
        Y[:, :, :n] = P[:, idx, :] if selection is not None else H @ P
        Y[:, :, n] = nu
        KY = K @ Y
        x_new = x + KY[:, :, n]
        T = P - KY[:, :, :n]  # (I − K H) P⁻
        D = _times_matrix(K, R)
        D -= T[:, :, idx] if selection is not None else _times_matrix(T, Ht)  # K R − T Hᵀ
        T += D @ np.ascontiguousarray(np.swapaxes(K, -1, -2))
        return x_new, symmetrize(T), S, factor, K
    x_new = x + (K @ nu[:, :, None])[:, :, 0]
    KPHt_T = K @ np.ascontiguousarray(np.swapaxes(PHt, -1, -2))  # K S Kᵀ = K (P⁻ Hᵀ)ᵀ
    if form == "symmetric":
        P_new = symmetrize(P - KPHt_T)
    else:
        P_new = P - KPHt_T
    return x_new, P_new, S, factor, K


def _symmetrize_small(S: np.ndarray) -> np.ndarray:
    """½(S + Sᵀ) of a freshly computed (M, m, m) stack, in place pair by pair for m ≤ 3 (same values as :func:`symmetrize`)."""
    m = S.shape[-1]
    if m > 3:
        return symmetrize(S)
    for i in range(m):
        for j in range(i + 1, m):
            S[:, i, j] = S[:, j, i] = 0.5 * (S[:, i, j] + S[:, j, i])
    return S


def innovation_scores(nu: np.ndarray, L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ℓ, NIS) of ν with S = L Lᵀ (SPEC §4)."""
    return gaussian_scores(nu, L)
