"""Batched small-matrix linear algebra shared by the filter plugins (docs/estimators.md, "Linear algebra").

Everything works on stacks: a matrix argument has shape (..., m, m), a vector (..., m).  Solves go through a
Cholesky factor (for small m the recurrences written out, one vectorized operation per entry over the whole stack;
LAPACK for larger m); nothing calls ``inv``.  A matrix that should be positive definite and is not raises
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


def _cholesky_entries(S: np.ndarray) -> tuple[list[list[np.ndarray]], np.ndarray]:
    """The entries L_ij (i ≥ j) of chol(S) as stack-shaped arrays, by the recurrence, and where S is positive definite.

    L_jj = √(S_jj − Σ_{k<j} L_jk²), L_ij = (S_ij − Σ_{k<j} L_ik L_jk) / L_jj (i > j).
    """
    m = S.shape[-1]
    entries = [[None] * m for _ in range(m)]
    ok = None
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(m):
            d = S[..., j, j]
            for k in range(j):
                d = d - entries[j][k] * entries[j][k]
            good = d > 0
            ok = good if ok is None else ok & good
            ljj = entries[j][j] = np.sqrt(d)
            for i in range(j + 1, m):
                s = S[..., i, j]
                for k in range(j):
                    s = s - entries[i][k] * entries[j][k]
                entries[i][j] = s / ljj
    return entries, ok


def _assemble(entries, shape) -> np.ndarray:
    L = np.zeros(shape)
    for i in range(shape[-1]):
        for j in range(i + 1):
            L[..., i, j] = entries[i][j]
    return L


def masked_cholesky(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower L with A = L Lᵀ for each positive definite A (..., k, k), and ``ok`` (...,) marking them.

    Unlike :func:`cholesky`, a matrix that is not positive definite (or not
    finite) does not stop the stack: it gets ``ok`` False and an identity
    factor, so a batch of problems can treat those alone (e.g. raise the
    Levenberg–Marquardt λ, seed 002 §4.3 step 4) while the others go on.
    Same recurrence as :func:`cholesky`, at every size.
    """
    A = np.asarray(A, dtype=float)
    k = A.shape[-1]
    if k == 0:
        return np.zeros_like(A), np.ones(A.shape[:-2], dtype=bool)
    entries, ok = _cholesky_entries(A)
    L = _assemble(entries, A.shape)
    L[~ok] = np.eye(k)
    return L, ok


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
            L = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            raise np.linalg.LinAlgError(f"{what} is not positive definite") from None
        if not np.isfinite(np.diagonal(L, axis1=-2, axis2=-1)).all():  # LAPACK passes NaN through
            raise np.linalg.LinAlgError(f"{what} is not positive definite (NaN)")
        return L
    entries, ok = _cholesky_entries(S)
    if not ok.all():
        raise np.linalg.LinAlgError(f"{what} is not positive definite (stack index {tuple(int(i) for i in np.argwhere(~ok)[0])})")
    return _assemble(entries, S.shape)


class CholeskyFactor:
    """An SPD stack S (..., m, m) factored once for the three uses of an innovation
    covariance: the Cholesky factor L, the inverse S⁻¹ (for the gain
    K = P Hᵀ S⁻¹ as one stacked matmul) and the Gaussian scores of ν.

    Closed forms for m ≤ 2, with S = [[a, b], [b, c]], det S = a c − b²:

    * positive definite ⇔ a > 0 and det S > 0 (m = 1: a > 0);
    * S⁻¹ = [[c, −b], [−b, a]] / det S (adjugate; m = 1: 1/a);
    * L = [[l₀₀, 0], [l₁₀, l₁₁]], l₀₀ = √a, l₁₀ = b / l₀₀, l₁₁ = √(c − l₁₀²);
    * NIS = νᵀS⁻¹ν from S = U D Uᵀ, U = [[1, 0], [b/a, 1]], D = diag(a, det S / a):
      NIS = ν₀²/a + r² a / det S with r = ν₁ − (b/a) ν₀ (= |L⁻¹ν|², a sum of
      non-negative terms), ln det S = ln(a c − b²).

    For 2 < m ≤ ``SMALL_CHOLESKY`` the factor of :func:`cholesky` (its
    recurrence) and, entry by entry over the stack, (L⁻¹)_ii = 1 / L_ii,
    (L⁻¹)_ij = −(Σ_{j≤k<i} L_ik (L⁻¹)_kj) / L_ii (i > j),
    (S⁻¹)_ij = Σ_{k ≥ max(i, j)} (L⁻¹)_ki (L⁻¹)_kj (exactly symmetric).  Larger m:
    LAPACK's factor and :func:`cholesky_solve` on the identity.  For m > 2 the scores are
    :func:`gaussian_scores`.
    """

    def __init__(self, S: np.ndarray, what: str = "matrix"):
        self.S = S
        self.shape = S.shape
        m = S.shape[-1]
        self._L = None
        if m in (1, 2):
            a = S[..., 0, 0]
            if m == 1:
                self.det = a
            else:
                b, c = S[..., 1, 0], S[..., 1, 1]
                self.det = a * c - b * b
                a = np.minimum(a, self.det)
            if not a.min(initial=np.inf) > 0:  # also catches NaN
                bad = ~(a > 0)
                raise np.linalg.LinAlgError(f"{what} is not positive definite (stack index {tuple(int(i) for i in np.argwhere(bad)[0])})")
            self.kind = "closed"
        else:
            self._L = cholesky(S, what)
            self.kind = "entries" if m <= SMALL_CHOLESKY else "lapack"

    @property
    def L(self) -> np.ndarray:
        if self._L is None:
            self._L = _assemble(self._closed_entries(), self.shape)
        return self._L

    def _closed_entries(self):
        S = self.S
        l00 = np.sqrt(S[..., 0, 0])
        if self.shape[-1] == 1:
            return [[l00]]
        l10 = S[..., 1, 0] / l00
        return [[l00, None], [l10, np.sqrt(S[..., 1, 1] - l10 * l10)]]

    def inverse(self) -> np.ndarray:
        """S⁻¹ (..., m, m)."""
        m = self.shape[-1]
        if self.kind == "closed":
            S = self.S
            if m == 1:
                return 1.0 / S
            r = 1.0 / self.det
            S_inv = np.empty(self.shape)
            S_inv[..., 0, 0] = S[..., 1, 1] * r
            S_inv[..., 1, 1] = S[..., 0, 0] * r
            off = S[..., 1, 0] * r
            S_inv[..., 0, 1] = S_inv[..., 1, 0] = np.negative(off, out=off)
            return S_inv
        if self.kind == "lapack":
            return cholesky_solve(self._L, np.broadcast_to(np.eye(m), self.shape))
        L = self._L
        inv = [[None] * m for _ in range(m)]
        for i in range(m):
            inv[i][i] = 1.0 / L[..., i, i]
            for j in range(i - 1, -1, -1):
                acc = L[..., i, j] * inv[j][j]
                for k in range(j + 1, i):
                    acc = acc + L[..., i, k] * inv[k][j]
                inv[i][j] = -acc / L[..., i, i]
        S_inv = np.empty(self.shape)
        for i in range(m):
            for j in range(i, m):
                acc = inv[j][i] * inv[j][j]
                for k in range(j + 1, m):
                    acc = acc + inv[k][i] * inv[k][j]
                S_inv[..., i, j] = acc
                if i != j:
                    S_inv[..., j, i] = acc
        return S_inv

    def scores(self, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ℓ, NIS) of ν (..., m) as :func:`gaussian_scores`."""
        if self.kind != "closed":  # ν and L broadcast to one stack shape
            lead = np.broadcast_shapes(self.shape[:-2], nu.shape[:-1])
            return gaussian_scores(np.broadcast_to(nu, lead + nu.shape[-1:]), np.broadcast_to(self._L, lead + self.shape[-2:]))
        m = self.shape[-1]  # S = U D Uᵀ: NIS = ν₀²/a + r²/(det S / a), r = ν₁ − (b/a) ν₀
        S, nu0 = self.S, nu[..., 0]
        t = nu0 / S[..., 0, 0]
        nis = nu0 * t
        if m == 2:
            r = nu[..., 1] - S[..., 1, 0] * t
            nis += S[..., 0, 0] * (r * r) / self.det
        return -0.5 * (m * LOG_2PI + np.log(self.det) + nis), nis


def forward_substitute(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve L y = b for lower-triangular L (..., m, m) and b (..., m) or (..., m, k).

    y_i = (b_i − Σ_{j<i} L_ij y_j) / L_ii, row by row over the stack (m ≤ ``SMALL_SOLVE``).
    """
    m = L.shape[-1]
    vector = b.ndim == L.ndim - 1
    if m > SMALL_SOLVE:
        y = np.linalg.solve(L, b[..., None] if vector else b)
        return y[..., 0] if vector else y
    if vector:  # each step is a 1-D operation over the stack
        y = np.empty(np.broadcast_shapes(L.shape[:-2], b.shape[:-1]) + (m,))
        for i in range(m):
            s = b[..., i]
            for j in range(i):
                s = s - L[..., i, j] * y[..., j]
            y[..., i] = s / L[..., i, i]
        return y
    y = np.empty(np.broadcast_shapes(L.shape[:-2], b.shape[:-2]) + b.shape[-2:])
    for i in range(m):
        s = b[..., i, :]
        for j in range(i):
            s = s - L[..., i, j, None] * y[..., j, :]
        y[..., i, :] = s / L[..., i, i, None]
    return y


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
    if m == 0 or m > SMALL_SOLVE:
        nis = np.einsum("...i,...i->...", w, w)
        log_det = log_det_from_cholesky(L)
    else:  # Σ over the few components as 1-D operations over the stack
        nis = w[..., 0] * w[..., 0]
        log_det = np.log(L[..., 0, 0])
        for i in range(1, m):
            nis = nis + w[..., i] * w[..., i]
            log_det = log_det + np.log(L[..., i, i])
        log_det = 2.0 * log_det
    loglik = -0.5 * (m * LOG_2PI + log_det + nis)
    return loglik, nis


def wrap_angle(angle):
    """Angles (radians) wrapped to (−π, π]: a − 2π round(a / 2π), then −π ↦ π."""
    angle = np.asarray(angle, dtype=float)
    wrapped = np.asarray(angle - 2.0 * np.pi * np.round(angle / (2.0 * np.pi)))
    wrapped[wrapped <= -np.pi] += 2.0 * np.pi
    return wrapped


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
