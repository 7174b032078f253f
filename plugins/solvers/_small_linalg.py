"""Cholesky factor and solve for stacks of small SPD systems (..., k, k), row by row.

Unlike ``np.linalg.cholesky`` on a stack, which fails as a whole when one matrix
is not positive definite, :func:`masked_cholesky` reports which ones fail, so a
batch of Levenberg–Marquardt problems can raise λ on those alone (seed 002
§4.3, step 4) while the others go on.  Loops run over the k ≤ 4 columns; every
operation is vectorized over the stack.
"""

from __future__ import annotations

import numpy as np


def masked_cholesky(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower L with A = L Lᵀ for each positive definite A (..., k, k); ``ok`` (...,) marks them.

    L_jj = √(A_jj − Σ_{l<j} L_jl²), L_ij = (A_ij − Σ_{l<j} L_il L_jl)/L_jj (i > j),
    unrolled over the k² entries, each a vector over the stack.  Matrices that
    are not positive definite (or not finite) get ``ok`` False and an identity factor.
    """
    k = A.shape[-1]
    L = np.zeros_like(A)
    ok = np.ones(A.shape[:-2], dtype=bool)
    for j in range(k):
        d = A[..., j, j].copy()
        for t in range(j):
            d -= L[..., j, t] ** 2
        ok &= d > 0  # False for NaN too
        root = np.sqrt(np.where(ok, d, 1.0))
        L[..., j, j] = root
        for i in range(j + 1, k):
            v = A[..., i, j].copy()
            for t in range(j):
                v -= L[..., i, t] * L[..., j, t]
            L[..., i, j] = v / root
    bad = ~ok
    if bad.any():
        L[bad] = np.eye(k)
    return L, ok


def cholesky_solve(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve L Lᵀ x = b for lower L (..., k, k) and b (..., k): forward then backward substitution."""
    k = L.shape[-1]
    y = np.empty(np.broadcast_shapes(L.shape[:-1], b.shape))
    for i in range(k):
        v = b[..., i].copy()
        for t in range(i):
            v -= L[..., i, t] * y[..., t]
        y[..., i] = v / L[..., i, i]
    x = np.empty_like(y)
    for i in range(k - 1, -1, -1):
        v = y[..., i].copy()
        for t in range(i + 1, k):
            v -= L[..., t, i] * x[..., t]
        x[..., i] = v / L[..., i, i]
    return x
