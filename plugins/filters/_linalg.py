"""Batched small-matrix linear algebra shared by the filter plugins.

Everything works on stacks: a matrix argument has shape (..., m, m), a vector
(..., m).  Solves go through a Cholesky factor (closed forms for m = 1 and
m = 2, LAPACK for larger m); nothing calls ``inv`` (ARCHITECTURE.md, "The hot
path").  A matrix that should be positive definite and is not raises
:class:`numpy.linalg.LinAlgError` naming which one.
"""

from __future__ import annotations

import numpy as np

LOG_2PI = float(np.log(2.0 * np.pi))


def symmetrize(A: np.ndarray) -> np.ndarray:
    """½(A + Aᵀ) over the last two axes."""
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def cholesky(S: np.ndarray, what: str = "matrix") -> np.ndarray:
    """Lower Cholesky factor L of S = L Lᵀ for a stack S (..., m, m).

    m = 1 and m = 2 use closed forms: L = [[a, 0], [b, c]] with a = √S₀₀,
    b = S₁₀ / a, c = √(S₁₁ − b²).
    """
    m = S.shape[-1]
    if m == 0:
        return np.zeros_like(S)
    with np.errstate(invalid="ignore", divide="ignore"):
        if m == 1:
            L = np.sqrt(S)
            bad = ~(S[..., 0, 0] > 0)
        elif m == 2:
            a = np.sqrt(S[..., 0, 0])
            b = S[..., 1, 0] / a
            c2 = S[..., 1, 1] - b * b
            L = np.zeros_like(S)
            L[..., 0, 0] = a
            L[..., 1, 0] = b
            L[..., 1, 1] = np.sqrt(c2)
            bad = ~((S[..., 0, 0] > 0) & (c2 > 0))
        else:
            try:
                return np.linalg.cholesky(S)
            except np.linalg.LinAlgError:
                raise np.linalg.LinAlgError(f"{what} is not positive definite") from None
    if bad.any():
        raise np.linalg.LinAlgError(f"{what} is not positive definite (stack index {tuple(int(i) for i in np.argwhere(bad)[0])})")
    return L


def forward_substitute(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve L y = b for lower-triangular L (..., m, m) and b (..., m) or (..., m, k)."""
    vector = b.ndim == L.ndim - 1
    if vector:
        b = b[..., None]
    m = L.shape[-1]
    if m == 1:
        y = b / L[..., :1, :1]
    elif m == 2:
        y = np.empty(np.broadcast_shapes(L.shape[:-2], b.shape[:-2]) + b.shape[-2:])
        y[..., 0, :] = b[..., 0, :] / L[..., 0, 0, None]
        y[..., 1, :] = (b[..., 1, :] - L[..., 1, 0, None] * y[..., 0, :]) / L[..., 1, 1, None]
    else:
        y = np.linalg.solve(L, b)
    return y[..., 0] if vector else y


def cholesky_solve(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve (L Lᵀ) y = b given the lower Cholesky factor L; b (..., m) or (..., m, k)."""
    vector = b.ndim == L.ndim - 1
    if vector:
        b = b[..., None]
    w = forward_substitute(L, b)
    y = backward_substitute_transposed(L, w)
    return y[..., 0] if vector else y


def backward_substitute_transposed(L: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Solve Lᵀ y = w for lower-triangular L (..., m, m) and w (..., m, k)."""
    m = L.shape[-1]
    if m == 1:
        return w / L[..., :1, :1]
    if m == 2:
        y = np.empty(np.broadcast_shapes(L.shape[:-2], w.shape[:-2]) + w.shape[-2:])
        y[..., 1, :] = w[..., 1, :] / L[..., 1, 1, None]
        y[..., 0, :] = (w[..., 0, :] - L[..., 1, 0, None] * y[..., 1, :]) / L[..., 0, 0, None]
        return y
    return np.linalg.solve(np.swapaxes(L, -1, -2), w)


def log_det_from_cholesky(L: np.ndarray) -> np.ndarray:
    """ln det(L Lᵀ) = 2 Σ ln L_ii."""
    return 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(axis=-1)


def gaussian_scores(nu: np.ndarray, L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """NIS νᵀS⁻¹ν and log-likelihood ℓ = −½(m ln 2π + ln det S + NIS) (SPEC §4), S = L Lᵀ."""
    m = nu.shape[-1]
    w = forward_substitute(L, nu)
    nis = np.einsum("...i,...i->...", w, w)
    loglik = -0.5 * (m * LOG_2PI + log_det_from_cholesky(L) + nis)
    return loglik, nis


def psd_square_root(Q: np.ndarray) -> np.ndarray:
    """A square root W (..., n, n) with W Wᵀ = Q for a symmetric PSD stack Q (possibly singular).

    From the eigendecomposition Q = V Λ Vᵀ: W = V √max(Λ, 0).  Used only when a
    transition bank does not carry its own noise root G chol(Q_w).
    """
    eigenvalues, V = np.linalg.eigh(symmetrize(Q))
    return V * np.sqrt(np.clip(eigenvalues, 0.0, None))[..., None, :]


def triangular_r(A: np.ndarray) -> np.ndarray:
    """The upper-triangular factor of A = Q R (..., k, n), k ≥ n, rows signed so diag(R) ≥ 0."""
    R = np.linalg.qr(A, mode="r")
    n = A.shape[-1]
    R = R[..., :n, :]
    signs = np.where(np.diagonal(R, axis1=-2, axis2=-1) < 0, -1.0, 1.0)
    return R * signs[..., :, None]
