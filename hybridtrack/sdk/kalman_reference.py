"""The Kalman filter step written to be read: one formula per line (SPEC §3; Bar-Shalom, Li & Kirubarajan 2001, §5.2).

This is the reference the fast paths are tested against (the numpy covariance
form and the compiled numba lanes of the ``kalman`` estimator, and through the
contract kit every exact estimator).  It works on one filter — x (n,), P (n, n)
— or on a bank with leading axes — x (..., n), P (..., n, n), the matrices
broadcasting — and solves with the Cholesky factor of S, never an inverse.
"""

from __future__ import annotations

import numpy as np

from hybridtrack.sdk.linalg import cholesky, cholesky_solve, log_det_from_cholesky


def transpose(A: np.ndarray) -> np.ndarray:
    return np.swapaxes(A, -1, -2)


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, B: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x⁻ = F x + B,  P⁻ = F P Fᵀ + Q  (Q here is the state noise G Q Gᵀ, shape (n, n))."""
    x_pred = (F @ x[..., None])[..., 0] + B  # x⁻ = F x + B
    P_pred = F @ P @ transpose(F) + Q  # P⁻ = F P Fᵀ + Q
    return x_pred, 0.5 * (P_pred + transpose(P_pred))  # exactly symmetric


def update(x: np.ndarray, P: np.ndarray, z: np.ndarray, H: np.ndarray, R: np.ndarray):
    """Joseph-form update with its scores; returns (x⁺, P⁺, ν, S, ℓ, NIS).

    ν = z − H x⁻                      innovation
    S = H P⁻ Hᵀ + R                   innovation covariance
    K = P⁻ Hᵀ S⁻¹                     gain (S = L Lᵀ, solved with L)
    x⁺ = x⁻ + K ν
    P⁺ = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ   (Joseph: symmetric and PSD by construction)
    NIS = νᵀ S⁻¹ ν,  ℓ = −½ (m ln 2π + ln det S + NIS)   (SPEC §4)
    """
    n, m = x.shape[-1], z.shape[-1]
    nu = z - (H @ x[..., None])[..., 0]  # ν = z − H x⁻
    S = H @ P @ transpose(H) + R  # S = H P⁻ Hᵀ + R
    S = 0.5 * (S + transpose(S))
    L = cholesky(S, "S")  # S = L Lᵀ
    K = transpose(cholesky_solve(L, H @ P))  # K = P⁻ Hᵀ S⁻¹ = (S⁻¹ H P⁻)ᵀ
    x_post = x + (K @ nu[..., None])[..., 0]  # x⁺ = x⁻ + K ν
    A = np.eye(n) - K @ H  # I − K H
    P_post = A @ P @ transpose(A) + K @ R @ transpose(K)  # P⁺ (Joseph)
    nis = np.einsum("...i,...i->...", nu, cholesky_solve(L, nu))  # νᵀ S⁻¹ ν
    loglik = -0.5 * (m * np.log(2 * np.pi) + log_det_from_cholesky(L) + nis)  # ℓ
    return x_post, 0.5 * (P_post + transpose(P_post)), nu, S, loglik, nis
