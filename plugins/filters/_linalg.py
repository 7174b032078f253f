"""Batched small-matrix linear algebra shared by the filter plugins.

Everything works on stacks: a matrix argument has shape (..., m, m), a vector
(..., m).  Solves go through a Cholesky factor (for small m the recurrences
written out, one vectorized operation per entry over the whole stack; LAPACK
for larger m); nothing calls ``inv`` (ARCHITECTURE.md, "The hot path").  A matrix that should be positive definite and is not raises
:class:`numpy.linalg.LinAlgError` naming which one.
"""

from __future__ import annotations

import numpy as np

LOG_2PI = float(np.log(2.0 * np.pi))


def symmetrize(A: np.ndarray) -> np.ndarray:
    """½(A + Aᵀ) over the last two axes."""
    out = A + np.swapaxes(A, -1, -2)
    out *= 0.5
    return out


#: up to this size, Cholesky factors are computed entry by entry (each entry one
#: vectorized operation over the whole stack); LAPACK's batched call costs more
#: per matrix than these few operations for small m.
SMALL_CHOLESKY = 4
#: up to this size, triangular solves are substitution loops over the rows
#: (``np.linalg.solve`` would factor the triangular matrix again by LU).
SMALL_SOLVE = 8


def cholesky(S: np.ndarray, what: str = "matrix") -> np.ndarray:
    """Lower Cholesky factor L of S = L Lᵀ for a stack S (..., m, m).

    For m ≤ ``SMALL_CHOLESKY`` the textbook recurrence, one entry at a time
    over the whole stack: L_jj = √(S_jj − Σ_{k<j} L_jk²),
    L_ij = (S_ij − Σ_{k<j} L_ik L_jk) / L_jj (i > j); for m = 2 this is the
    closed form L = [[a, 0], [b, c]], a = √S₀₀, b = S₁₀ / a, c = √(S₁₁ − b²).
    LAPACK for larger m.
    """
    m = S.shape[-1]
    if m == 0:
        return np.zeros_like(S)
    if m > SMALL_CHOLESKY:
        try:
            return np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            raise np.linalg.LinAlgError(f"{what} is not positive definite") from None
    L = np.zeros(S.shape)
    ok = None
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(m):
            d = S[..., j, j]
            for k in range(j):
                d = d - L[..., j, k] * L[..., j, k]
            good = d > 0
            ok = good if ok is None else ok & good
            ljj = np.sqrt(d)
            L[..., j, j] = ljj
            for i in range(j + 1, m):
                s = S[..., i, j]
                for k in range(j):
                    s = s - L[..., i, k] * L[..., j, k]
                L[..., i, j] = s / ljj
    if not ok.all():
        bad = ~ok
        raise np.linalg.LinAlgError(f"{what} is not positive definite (stack index {tuple(int(i) for i in np.argwhere(bad)[0])})")
    return L


def forward_substitute(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve L y = b for lower-triangular L (..., m, m) and b (..., m) or (..., m, k).

    y_i = (b_i − Σ_{j<i} L_ij y_j) / L_ii, row by row over the stack (m ≤ ``SMALL_SOLVE``).
    """
    vector = b.ndim == L.ndim - 1
    if vector:
        b = b[..., None]
    m = L.shape[-1]
    if m > SMALL_SOLVE:
        y = np.linalg.solve(L, b)
        return y[..., 0] if vector else y
    y = np.empty(np.broadcast_shapes(L.shape[:-2], b.shape[:-2]) + b.shape[-2:])
    for i in range(m):
        s = b[..., i, :]
        for j in range(i):
            s = s - L[..., i, j, None] * y[..., j, :]
        y[..., i, :] = s / L[..., i, i, None]
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
    """Solve Lᵀ y = w for lower-triangular L (..., m, m) and w (..., m, k).

    y_i = (w_i − Σ_{j>i} L_ji y_j) / L_ii from the last row up (m ≤ ``SMALL_SOLVE``).
    """
    m = L.shape[-1]
    if m > SMALL_SOLVE:
        return np.linalg.solve(np.swapaxes(L, -1, -2), w)
    y = np.empty(np.broadcast_shapes(L.shape[:-2], w.shape[:-2]) + w.shape[-2:])
    for i in range(m - 1, -1, -1):
        s = w[..., i, :]
        for j in range(m - 1, i, -1):
            s = s - L[..., j, i, None] * y[..., j, :]
        y[..., i, :] = s / L[..., i, i, None]
    return y


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
