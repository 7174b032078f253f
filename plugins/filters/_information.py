"""Information-form maths over stacked arrays (SPEC §3, seed 000 eqs. 10–21).

I = P⁻¹ (the information matrix, written Y in code to keep I for identity),
s = I x.  Conversions go through Cholesky factors, never ``inv``.
"""

from __future__ import annotations

import numpy as np

from hybridtrack.linalg import cholesky, cholesky_solve, forward_substitute, log_det_from_cholesky, symmetrize


def spd_inverse(A: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """A⁻¹ by Cholesky solves against the identity, and the factor L (A = L Lᵀ)."""
    L = cholesky(A, what)
    eye = np.broadcast_to(np.eye(A.shape[-1]), A.shape)
    return symmetrize(cholesky_solve(L, eye)), L


def to_information(x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(I, s) = (P⁻¹, P⁻¹ x)."""
    Y, L = spd_inverse(P, "covariance P")
    return Y, cholesky_solve(L, x)


def to_covariance(Y: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, P) = (I⁻¹ s, I⁻¹)."""
    P, L = spd_inverse(Y, "information matrix I")
    return cholesky_solve(L, s), P


def measurement_information(H: np.ndarray, R: np.ndarray, z: np.ndarray):
    """One node's contribution (seed 000 eqs. 18–19) through the whitened model.

    With R = L_R L_Rᵀ, W = L_R⁻¹ H and w = L_R⁻¹ z:
    ΔI = Hᵀ R⁻¹ H = Wᵀ W,  Δs = Hᵀ R⁻¹ z = Wᵀ w,  plus zᵀR⁻¹z = wᵀw and ln det R
    (broadcast too, so that every node can compute NIS and ℓ locally, SPEC §4).
    H is (m, n) or (M, m, n), R (m, m) or (M, m, m), z (1 or M, m).
    """
    L_R = cholesky(R, "measurement noise R")
    if H.ndim < L_R.ndim:  # shared H with one R per filter: broadcast (a bare (m, n) would read as a stack of vectors)
        H = np.broadcast_to(H, L_R.shape[:-2] + H.shape[-2:])
    W = forward_substitute(L_R, H)
    w = forward_substitute(L_R, z[..., None])[..., 0]
    Wt = np.swapaxes(W, -1, -2)
    dY = Wt @ W
    ds = np.einsum("...ij,...j->...i", Wt, w)
    zRz = np.einsum("...i,...i->...", w, w)
    return dY, ds, zRz, log_det_from_cholesky(L_R)


def local_scores(x_prior, Y_prior, x_post, Y_post, zRz, log_det_R, m):
    """NIS and ℓ from information quantities only (seed 000 eq. 22; SPEC §4).

    NIS = x⁻ᵀI⁻x⁻ − x⁺ᵀI⁺x⁺ + Σ_j z_jᵀR_j⁻¹z_j, and by the determinant lemma
    det S = det R · det I⁺ / det I⁻, so ℓ = −½(m ln 2π + ln det R + ln det I⁺ − ln det I⁻ + NIS).
    """
    quad = lambda x, Y: np.einsum("...i,...ij,...j->...", x, Y, x)  # noqa: E731
    nis = quad(x_prior, Y_prior) - quad(x_post, Y_post) + zRz
    log_det_S = log_det_R + np.linalg.slogdet(Y_post)[1] - np.linalg.slogdet(Y_prior)[1]
    loglik = -0.5 * (m * np.log(2 * np.pi) + log_det_S + nis)
    return loglik, nis
