"""Covariance-form Kalman filter maths over stacked arrays (SPEC §3, seed 000 Algorithm 1).

x has shape (M, n), P (M, n, n); F (M, n, n), B (M, n), Q (M, n, n) = G Q_w Gᵀ.

``engine`` of :func:`predict` and :func:`update_scored`: ``"numpy"`` (default;
stacked operations over the bank, the reference) or ``"numba"`` (the compiled
one-pass kernels of :mod:`._kalman_kernel`, same results to rounding);
:func:`resolve_engine` turns an estimator's ``"auto"`` into one of them.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from hybridtrack.sdk.linalg import CholeskyFactor, symmetrize
from hybridtrack.sdk.measurements import selection_index

UPDATE_FORMS = ("joseph", "symmetric", "conventional")
ENGINES = ("auto", "numba", "numpy")
#: numba is installed (the kernel module is imported on first compiled call only, so loading the plugins
#: does not import numba)
NUMBA_AVAILABLE = importlib.util.find_spec("numba") is not None
#: "auto" takes the compiled kernel up to these sizes (state n, measurement m): there one pass of scalar
#: loops per filter beats a dozen stacked numpy operations; larger systems are BLAS-sized products
AUTO_MAX_STATE, AUTO_MAX_MEASUREMENT = 6, 3


def check_engine(engine: str) -> str:
    """``engine`` one of :data:`ENGINES`; "numba" needs numba installed.  ValueError naming it otherwise."""
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    if engine == "numba" and not NUMBA_AVAILABLE:
        raise ValueError("engine: 'numba' asked for but numba is not installed (pip install numba); use 'auto' or 'numpy'")
    return engine


def resolve_engine(engine: str, n: int, m: int = 0) -> str:
    """ "numba" or "numpy" for a step of state size n and measurement size m.

    "auto": the compiled kernel when numba is installed and n ≤ 6, m ≤ 3
    (:data:`AUTO_MAX_STATE`, :data:`AUTO_MAX_MEASUREMENT`), else numpy;
    "numba" and "numpy" as given (the kernel's loops take any size).
    """
    if engine == "auto":
        return "numba" if NUMBA_AVAILABLE and n <= AUTO_MAX_STATE and m <= AUTO_MAX_MEASUREMENT else "numpy"
    return engine


def kernel_module():
    """The compiled kernels (:mod:`._kalman_kernel`), imported (and numba with them) on first use."""
    from hybridtrack_plugins.filters import _kalman_kernel

    return _kalman_kernel


def _flat(A: np.ndarray, shape: tuple) -> np.ndarray:
    """A as a C-contiguous float array of the given shape (a view when it already is one)."""
    return np.ascontiguousarray(A, dtype=float).reshape(shape)


def predict(
    x: np.ndarray,
    P: np.ndarray,
    F: np.ndarray,
    B: np.ndarray,
    Q: np.ndarray,
    Ft: np.ndarray | None = None,
    engine: str = "numpy",
) -> tuple[np.ndarray, np.ndarray]:
    """x⁻ = F x⁺ + B u, P⁻ = F P⁺ Fᵀ + G Q Gᵀ (seed 000 eqs. 4–5), P⁻ symmetrised.

    ``Ft``: Fᵀ as a contiguous stack, if the caller keeps one (a stacked matmul
    with a transposed view is about twice as slow as with a contiguous operand;
    unused by the compiled kernel).  ``engine``: "numpy" or "numba"
    (:func:`._kalman_kernel.predict_bank`).
    """
    if engine == "numba":
        M, n = x.shape
        x, P, F, Q = (_flat(A, (M, -1)) for A in (x, P, F, Q))
        x_pred, P_pred = np.empty((M, n)), np.empty((M, n, n))
        kernel_module().predict_bank(x, P, F, _flat(B, (M, n)), Q, x_pred, P_pred.reshape(M, n * n), (0,) * n)
        return x_pred, P_pred
    x_pred = np.einsum("mij,mj->mi", F, x)
    x_pred += B
    if Ft is None:
        Ft = np.ascontiguousarray(np.swapaxes(F, -1, -2))
    P_pred = F @ P @ Ft
    P_pred += Q
    return x_pred, symmetrize(P_pred)


def _times_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """A C for a stack A (M, p, q) and C (q, r) shared by the bank (one BLAS call) or (M, q, r)."""
    if C.ndim == 2:
        M, p, q = A.shape
        return (A.reshape(M * p, q) @ C).reshape(M, p, C.shape[-1])
    return A @ C


def update(x, P, nu, H, R, selection=None, form: str = "joseph"):
    """One measurement update (seed 000 eqs. 6–9 with the SPEC §3 correction P⁺ = (I − K H) P⁻).

    S = H P⁻ Hᵀ + R (symmetrised), K = P⁻ Hᵀ S⁻¹, x⁺ = x⁻ + K ν, and

    * ``joseph``: P⁺ = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ (PSD by construction),
      evaluated as T = (I − K H) P⁻ = P⁻ − K (H P⁻), then
      P⁺ = T (I − K H)ᵀ + K R Kᵀ = T + (K R − T Hᵀ) Kᵀ, symmetrised — the
      same two-sided product for any K, with the products by I − K H written
      as rank-m corrections (no n × n matrix I − K H is formed);
    * ``symmetric``: P⁺ = P⁻ − K S Kᵀ = P⁻ − K (P⁻ Hᵀ)ᵀ, symmetrised,
    * ``conventional``: P⁺ = (I − K H) P⁻ as printed, no symmetrisation (kept
      to show how it breaks on ill-conditioned problems, docs/estimators.md).

    S⁻¹ from :class:`~hybridtrack.sdk.linalg.CholeskyFactor` (its closed forms for m ≤ 2), so K is one stacked
    matmul.  H is (m, n) or (M, m, n), R (m, m) or (M, m, m); a shared H or R multiplies the whole bank in one BLAS
    call.  With ``selection`` (the state indices H picks) the products with H become indexing and S is built entry
    by entry.  Returns x⁺, P⁺, S, L = chol(S), K.
    """
    x_new, P_new, S, factor, K = _update(x, P, nu, H, R, selection, form)
    return x_new, P_new, S, factor.L, K


def update_scored(x, P, nu, H, R, selection=None, form: str = "joseph", engine: str = "numpy"):
    """:func:`update` plus the innovation scores from the same factor of S.

    Returns x⁺, P⁺, S, ℓ, NIS with ℓ = −½(m ln 2π + ln det S + NIS), NIS = νᵀS⁻¹ν (SPEC §4).
    ``engine``: "numpy" or "numba" (:func:`._kalman_kernel.update_bank`, one pass
    over the filters; H is used as given, so a selection H multiplies by its
    zeros and ones, which is exact).
    """
    if engine != "numba" or form not in UPDATE_FORMS:  # (the numpy path raises for an unknown form)
        x_new, P_new, S, factor, _ = _update(x, P, nu, H, R, selection, form)
        return x_new, P_new, S, *factor.scores(nu)
    (M, n), m = x.shape, nu.shape[-1]
    x_new, P_new, S = np.empty((M, n)), np.empty((M, n, n)), np.empty((M, m, m))
    loglik, nis = np.empty(M), np.empty(M)
    kernel = kernel_module()
    H, R = (_flat(A, (1 if A.ndim == 2 else M, -1)) for A in (H, R))  # shared (1, ·) or per filter (M, ·)
    inputs = (_flat(x, (M, n)), _flat(P, (M, n * n)), _flat(nu, (M, m)), H, R)
    outputs = (x_new, P_new.reshape(M, n * n), S.reshape(M, m * m), loglik, nis)
    bad = kernel.update_bank(*inputs, kernel.FORMS[form], *outputs, (0,) * n, (0,) * m)
    if bad >= 0:
        raise np.linalg.LinAlgError(f"innovation covariance S is not positive definite (stack index ({bad},))")
    return x_new, P_new, S, loglik, nis


def _update(x, P, nu, H, R, selection, form):
    if form not in UPDATE_FORMS:
        raise ValueError(f"form: expected one of {UPDATE_FORMS}, got {form!r}")
    if selection is not None:
        idx = selection_index(selection)
        PHt = P[:, :, idx]  # P Hᵀ (M, n, m)
        HPHt = PHt[:, idx, :]  # P[sel][:, sel]
    else:
        Ht = np.ascontiguousarray(np.swapaxes(H, -1, -2))
        PHt = _times_matrix(P, Ht)
        HPHt = H @ PHt
    S = _symmetrize_small(HPHt + R)
    factor = CholeskyFactor(S, "innovation covariance S")
    K = PHt @ factor.inverse()  # (M, n, m)
    x_new = x + np.einsum("mij,mj->mi", K, nu)
    if form == "joseph":
        T = P - K @ (P[:, idx, :] if selection is not None else H @ P)  # (I − K H) P⁻
        D = _times_matrix(K, R)
        D -= T[:, :, idx] if selection is not None else _times_matrix(T, Ht)  # K R − T Hᵀ
        T += D @ np.ascontiguousarray(np.swapaxes(K, -1, -2))
        return x_new, symmetrize(T), S, factor, K
    T = P - K @ np.ascontiguousarray(np.swapaxes(PHt, -1, -2))  # P⁻ − K S Kᵀ = P⁻ − K (P⁻ Hᵀ)ᵀ
    return x_new, T if form == "conventional" else symmetrize(T), S, factor, K


def _symmetrize_small(S: np.ndarray) -> np.ndarray:
    """½(S + Sᵀ) of a freshly computed (M, m, m) stack, in place pair by pair for m ≤ 3 (same values as :func:`symmetrize`)."""
    m = S.shape[-1]
    if m > 3:
        return symmetrize(S)
    for i in range(m):
        for j in range(i + 1, m):
            S[:, i, j] = S[:, j, i] = 0.5 * (S[:, i, j] + S[:, j, i])
    return S
