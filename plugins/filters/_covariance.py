"""Covariance-form Kalman filter maths over stacked arrays (SPEC §3, seed 000 Algorithm 1).

x has shape (M, n), P (M, n, n); F (M, n, n), B (M, n), Q (M, n, n) = G Q_w Gᵀ.
"""

from __future__ import annotations

import numpy as np

from hybridtrack_plugins.filters._linalg import cholesky, cholesky_solve, gaussian_scores, symmetrize

UPDATE_FORMS = ("joseph", "symmetric", "conventional")


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, B: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x⁻ = F x⁺ + B u, P⁻ = F P⁺ Fᵀ + G Q Gᵀ (seed 000 eqs. 4–5), P⁻ symmetrised."""
    x_pred = np.einsum("mij,mj->mi", F, x) + B
    P_pred = F @ P @ np.swapaxes(F, -1, -2) + Q
    return x_pred, symmetrize(P_pred)


def update(x, P, nu, H, R, selection=None, form: str = "joseph"):
    """One measurement update (seed 000 eqs. 6–9 with the SPEC §3 correction P⁺ = (I − K H) P⁻).

    S = H P⁻ Hᵀ + R, K = P⁻ Hᵀ S⁻¹ (by Cholesky solves), x⁺ = x⁻ + K ν, and

    * ``joseph``: P⁺ = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ (PSD by construction),
    * ``symmetric``: P⁺ = P⁻ − K S Kᵀ, symmetrised,
    * ``conventional``: P⁺ = (I − K H) P⁻ as printed, no symmetrisation (kept
      to show how it breaks on ill-conditioned problems, docs/estimators.md).

    H is (m, n) or (M, m, n); with ``selection`` (the state indices H picks) the
    products with H become indexing.  Returns x⁺, P⁺, S, L = chol(S), K.
    """
    if selection is not None:
        idx = list(selection)
        PHt = P[:, :, idx]  # P Hᵀ (M, n, m)
        S = PHt[:, idx, :] + R
    else:
        PHt = P @ np.swapaxes(H, -1, -2)
        S = H @ PHt + R
    S = symmetrize(S)
    L = cholesky(S, "innovation covariance S")
    K = np.swapaxes(cholesky_solve(L, np.swapaxes(PHt, -1, -2)), -1, -2)  # (M, n, m)
    x_new = x + np.einsum("mij,mj->mi", K, nu)
    if form == "joseph":
        if selection is not None and len(set(idx)) == len(idx):
            A = np.broadcast_to(np.eye(P.shape[-1]), P.shape).copy()
            A[:, :, idx] -= K  # K H puts K's columns at the selected indices
        else:
            A = np.eye(P.shape[-1]) - K @ H
        P_new = A @ P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
        P_new = symmetrize(P_new)
    elif form == "symmetric":
        P_new = symmetrize(P - K @ np.swapaxes(PHt, -1, -2))
    elif form == "conventional":
        P_new = P - K @ np.swapaxes(PHt, -1, -2)
    else:
        raise ValueError(f"form: expected one of {UPDATE_FORMS}, got {form!r}")
    return x_new, P_new, S, L, K


def innovation_scores(nu: np.ndarray, L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ℓ, NIS) of ν with S = L Lᵀ (SPEC §4)."""
    return gaussian_scores(nu, L)
