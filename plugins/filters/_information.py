"""Information-form maths over stacked arrays (SPEC §3, seed 000 eqs. 10–21).

I = P⁻¹ (the information matrix, written Y in code to keep I for identity),
s = I x.  Conversions go through Cholesky factors, never ``inv``.
"""

from __future__ import annotations

import numpy as np

from hybridtrack.sdk.linalg import cholesky, cholesky_solve, symmetrize
from hybridtrack_plugins.filters._sqrt import whiten


def spd_inverse(A: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """A⁻¹ by Cholesky solves against the identity, and the factor L (A = L Lᵀ)."""
    L = cholesky(A, what)
    eye = np.broadcast_to(np.eye(A.shape[-1]), A.shape)
    return symmetrize(cholesky_solve(L, eye)), L


def to_information(x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(I, s) = (P⁻¹, P⁻¹ x)."""
    Y, L = spd_inverse(P, "covariance P")
    return Y, cholesky_solve(L, x)


def innovation_information(H: np.ndarray, R: np.ndarray, nu: np.ndarray):
    """One node's contribution (seed 000 eqs. 18–19) formed about the prediction x⁻.

    With R = L_R L_Rᵀ, W = L_R⁻¹ H and the whitened innovation w = L_R⁻¹ ν,
    ν = z − H x⁻:  ΔI = Hᵀ R⁻¹ H = Wᵀ W,  g = Hᵀ R⁻¹ ν = Wᵀ w,  q = νᵀ R⁻¹ ν = wᵀ w,
    and ln det R.  (g, q) carry the same information as (Δs, zᵀR⁻¹z) of eq. 19,
    Δs = g + ΔI x⁻, but at the scale of the innovation instead of that of the
    coordinates, so nothing downstream subtracts large, nearly equal terms.
    H is (m, n) or (…, m, n), R (m, m) or (…, m, m), ν (…, m); the leading axes broadcast (:func:`._sqrt.whiten`).
    """
    W, w, log_det_R = whiten(H, nu, R)
    dY = np.swapaxes(W, -1, -2) @ W
    g = np.einsum("...ji,...j->...i", W, w)
    q = np.einsum("...i,...i->...", w, w)
    return dY, g, q, log_det_R


def assimilate(x_prior: np.ndarray, Y_prior: np.ndarray, dY: np.ndarray, g: np.ndarray):
    """Eqs. 20–21 about the prediction: I⁺ = I⁻ + ΣΔI_j, δ = (I⁺)⁻¹ Σg_j, x⁺ = x⁻ + δ, s⁺ = I⁺ x⁺.

    Algebraically the same as x⁺ = (I⁺)⁻¹(I⁻x⁻ + ΣΔs_j) (substitute Δs_j = g_j + ΔI_j x⁻),
    but the solve acts on the correction δ only.  Returns I⁺, s⁺, x⁺, P⁺ = (I⁺)⁻¹, δ.
    """
    Y = symmetrize(Y_prior + dY)
    P, L = spd_inverse(Y, "information matrix I")
    delta = cholesky_solve(L, g)
    x = x_prior + delta
    return Y, np.einsum("...ij,...j->...i", Y, x), x, P, delta


def local_scores(Y_prior, Y_post, g, delta, q, log_det_R, m):
    """NIS and ℓ of the stacked innovation from information quantities only (seed 000 eq. 22; SPEC §4).

    Seed 000 eq. 22 writes NIS = x⁻ᵀI⁻x⁻ − x⁺ᵀI⁺x⁺ + Σ_j z_jᵀR_j⁻¹z_j: three terms of
    the size of (|x|/σ)², whose difference loses accuracy with the square of
    the distance from the coordinate origin.  Substituting z_j = ν_j + H_j x⁻
    (ν_j = z_j − H_j x⁻ the innovation of node j about the prediction),
    s⁺ = I⁻x⁻ + ΣΔs_j = I⁺x⁻ + g with g = Σ_j H_jᵀR_j⁻¹ν_j, and x⁺ = x⁻ + δ,
    δ = (I⁺)⁻¹ g, the terms in x⁻ cancel exactly:

        NIS = Σ_j ν_jᵀR_j⁻¹ν_j − gᵀ(I⁺)⁻¹g = Σ_j q_j − gᵀδ

    (the information form of νᵀ(H P⁻ Hᵀ + R)⁻¹ν by the Woodbury identity), every
    term at the scale of the innovation.  By the determinant lemma
    det S = det R · det I⁺ / det I⁻, so ℓ = −½(m ln 2π + ln det R + ln det I⁺ − ln det I⁻ + NIS).
    ``g``, ``delta`` (…, n), ``q``, ``log_det_R`` (…) summed over the nodes; m the stacked dimension.
    """
    nis = q - np.einsum("...i,...i->...", g, delta)
    log_det_S = log_det_R + np.linalg.slogdet(Y_post)[1] - np.linalg.slogdet(Y_prior)[1]
    loglik = -0.5 * (m * np.log(2 * np.pi) + log_det_S + nis)
    return loglik, nis
