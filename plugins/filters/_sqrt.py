"""Square-root filter maths over stacked arrays (SPEC §3; seed 000 ref. 16; seed 003; Bierman 1977).

* Potter: P = S Sᵀ; time update by QR, scalar measurement update.
* Bierman: P = U D Uᵀ (U unit upper triangular); scalar update; Thornton's
  modified weighted Gram–Schmidt (MWGS) time update.
* SRIF: I = Rᵀ R, ζ = R x; measurement update by QR of stacked rows;
  Dyer–McReynolds time update (F⁻¹ by solves) or, when some F is singular
  (the stop mode), through the covariance square root.

Scalar processing needs uncorrelated components: the measurement is first
whitened by the Cholesky factor of R (R = L_R L_Rᵀ; H̃ = L_R⁻¹ H, ν̃ = L_R⁻¹ ν).
Each scalar step i then has innovation ν_i with variance a_i (R̃ = 1), and
ln det S = ln det R + Σ ln a_i, NIS = Σ ν_i² / a_i (chain rule of the
Gaussian density), which gives ℓ (SPEC §4) from the scalar steps.
"""

from __future__ import annotations

import numpy as np

from hybridtrack.sdk.linalg import LOG_2PI, cholesky, forward_substitute, log_det_from_cholesky, psd_square_root, triangular_r


def noise_root(bank) -> np.ndarray:
    """W (M, n, r) with W Wᵀ = G Q Gᵀ: the bank's own ``noise_root`` or an eigen square root of Q."""
    return bank.noise_root if bank.noise_root is not None else psd_square_root(bank.Q)


def whiten(H: np.ndarray, nu: np.ndarray, R: np.ndarray):
    """H̃ = L_R⁻¹ H, ν̃ = L_R⁻¹ ν and ln det R, with R = L_R L_Rᵀ.

    H is (m, n) shared or (M, m, n); R is (m, m) or (M, m, m) (one per filter, e.g.
    radar pseudo-measurements of stacked Monte Carlo runs).  A shared H with a
    stacked R is broadcast first: (m, n) has the shape of a stack of vectors and
    would otherwise be solved as one.
    """
    L_R = cholesky(R, "measurement noise R")
    if H.ndim < L_R.ndim:
        H = np.broadcast_to(H, L_R.shape[:-2] + H.shape[-2:])
    return forward_substitute(L_R, H), forward_substitute(L_R, nu[..., None])[..., 0], log_det_from_cholesky(L_R)


def potter_predict(x, S, F, B, W):
    """x⁻ = F x + B; S⁻ lower triangular with S⁻S⁻ᵀ = F S Sᵀ Fᵀ + W Wᵀ, from QR of [(F S)ᵀ; Wᵀ]."""
    x_pred = np.einsum("mij,mj->mi", F, x) + B
    stacked = np.concatenate([np.swapaxes(F @ S, -1, -2), np.swapaxes(np.broadcast_to(W, F.shape[:-2] + W.shape[-2:]), -1, -2)], axis=-2)
    return x_pred, np.swapaxes(triangular_r(stacked), -1, -2)


def potter_update(x, S, H, nu, R):
    """Potter's scalar update on the whitened measurement (seed 003, Potter style).

    For each whitened row h with innovation ν_i = ν̃_i − h (x − x⁻):
    φ = Sᵀ h, a = φᵀφ + 1, K = S φ / a, x ← x + K ν_i,
    S ← S − γ S φ φᵀ with γ = α / (1 + √α), α = 1/a
    (so that S⁺S⁺ᵀ = S (I − α φ φᵀ) Sᵀ = P − K h P).
    Returns x⁺, S⁺, ℓ, NIS.
    """
    Ht, nut, log_det_R = whiten(H, nu, R)
    x0 = x
    loglik = -0.5 * log_det_R
    nis = 0.0
    for i in range(Ht.shape[-2]):
        h = Ht[..., i, :]
        nu_i = nut[..., i] - np.einsum("...j,...j->...", h, x - x0)
        phi = np.einsum("...ji,...j->...i", S, h)
        a = np.einsum("...i,...i->...", phi, phi) + 1.0
        Sphi = np.einsum("...ij,...j->...i", S, phi)
        x = x + Sphi * (nu_i / a)[..., None]
        alpha = 1.0 / a
        gamma = alpha / (1.0 + np.sqrt(alpha))
        S = S - gamma[..., None, None] * Sphi[..., :, None] * phi[..., None, :]
        ni = nu_i * nu_i / a
        loglik = loglik - 0.5 * (LOG_2PI + np.log(a) + ni)
        nis = nis + ni
    return x, S, loglik, nis


def ud_factor(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """U (unit upper triangular) and d with P = U diag(d) Uᵀ (Bierman 1977, UD factorization)."""
    P = np.array(P, dtype=float, copy=True)
    n = P.shape[-1]
    U = np.zeros_like(P)
    d = np.zeros(P.shape[:-1])
    for j in range(n - 1, -1, -1):
        dj = P[..., j, j]
        if not (dj > 0).all():
            raise np.linalg.LinAlgError("covariance P is not positive definite (UD factorization)")
        d[..., j] = dj
        U[..., j, j] = 1.0
        u = P[..., :j, j] / dj[..., None]
        U[..., :j, j] = u
        P[..., :j, :j] -= dj[..., None, None] * u[..., :, None] * u[..., None, :]
    return U, d


def ud_covariance(U: np.ndarray, d: np.ndarray) -> np.ndarray:
    """P = U diag(d) Uᵀ."""
    return (U * d[..., None, :]) @ np.swapaxes(U, -1, -2)


def thornton_predict(x, U, d, F, B, W):
    """Thornton's MWGS time update: P⁻ = [F U, W] diag(d, 1) [F U, W]ᵀ = U⁻ D⁻ U⁻ᵀ.

    Rows y_k of Y = [F U, W] are orthogonalised from the last: d⁻_k = Σ_l D̃_l y_kl²,
    U⁻_ik = (Σ_l y_il D̃_l y_kl) / d⁻_k, y_i ← y_i − U⁻_ik y_k for i < k.
    """
    x_pred = np.einsum("mij,mj->mi", F, x) + B
    W = np.broadcast_to(W, F.shape[:-2] + W.shape[-2:])
    Y = np.concatenate([F @ U, W], axis=-1)
    Dt = np.concatenate([d, np.ones(W.shape[:-2] + (W.shape[-1],))], axis=-1)
    n = F.shape[-1]
    U_new = np.zeros_like(F)
    d_new = np.zeros(F.shape[:-1])
    for k in range(n - 1, -1, -1):
        yk = Y[..., k, :]
        Dyk = Dt * yk
        dk = np.einsum("...l,...l->...", yk, Dyk)
        d_new[..., k] = dk
        U_new[..., k, k] = 1.0
        if k:
            u = np.einsum("...il,...l->...i", Y[..., :k, :], Dyk) / dk[..., None]
            U_new[..., :k, k] = u
            Y[..., :k, :] -= u[..., :, None] * yk[..., None, :]
    return x_pred, U_new, d_new


def bierman_update(x, U, d, H, nu, R):
    """Bierman's scalar UD measurement update on the whitened measurement (r = 1).

    f = Uᵀ h, v = d ∘ f, α₀ = 1; for j = 0…n−1: α_j = α_{j−1} + v_j f_j,
    d⁺_j = d_j α_{j−1} / α_j, λ = −f_j / α_{j−1}, U⁺_{:j, j} = U_{:j, j} + λ b_{:j},
    b_{:j+1} += v_j U_{:j+1, j}; K = b / α_{n−1}, a = α_{n−1} the innovation variance.
    Returns x⁺, U⁺, d⁺, ℓ, NIS.
    """
    Ht, nut, log_det_R = whiten(H, nu, R)
    x0 = x
    U = U.copy()
    d = d.copy()
    n = d.shape[-1]
    loglik = -0.5 * log_det_R
    nis = 0.0
    for i in range(Ht.shape[-2]):
        h = np.broadcast_to(Ht[..., i, :], x.shape)
        nu_i = nut[..., i] - np.einsum("...j,...j->...", h, x - x0)
        f = np.einsum("...ji,...j->...i", U, h)
        v = d * f
        b = np.zeros_like(x)
        alpha = np.ones(x.shape[:-1])
        for j in range(n):
            alpha_prev = alpha
            alpha = alpha_prev + v[..., j] * f[..., j]
            d[..., j] = d[..., j] * alpha_prev / alpha
            if j:
                lam = -f[..., j] / alpha_prev
                col = U[..., :j, j].copy()
                U[..., :j, j] = col + lam[..., None] * b[..., :j]
                b[..., :j] += v[..., j, None] * col
            b[..., j] += v[..., j]
        x = x + b * (nu_i / alpha)[..., None]
        ni = nu_i * nu_i / alpha
        loglik = loglik - 0.5 * (LOG_2PI + np.log(alpha) + ni)
        nis = nis + ni
    return x, U, d, loglik, nis


def srif_from_moments(x, P):
    """R with RᵀR = P⁻¹ (R = L⁻¹ for P = L Lᵀ, lower triangular) and ζ = R x."""
    return _from_root(cholesky(P, "covariance P"), x)


def _from_root(L, x):
    """R = L⁻¹ and ζ = R x by forward substitution, L lower triangular."""
    return forward_substitute(L, np.broadcast_to(np.eye(L.shape[-1]), L.shape)), forward_substitute(L, x[..., None])[..., 0]


def _to_root(Rinfo, zeta):
    """S = R⁻¹ (P = S Sᵀ) and x = R⁻¹ζ by solves with R (no inverse)."""
    S = np.linalg.solve(Rinfo, np.broadcast_to(np.eye(Rinfo.shape[-1]), Rinfo.shape))
    return S, np.linalg.solve(Rinfo, zeta[..., None])[..., 0]


def srif_moments(Rinfo, zeta):
    """x = R⁻¹ζ and P = R⁻¹R⁻ᵀ by solves with R (no inverse)."""
    S, x = _to_root(Rinfo, zeta)
    return x, S @ np.swapaxes(S, -1, -2)


def srif_predict(Rinfo, zeta, F, B, W):
    """SRIF time update.

    Dyer–McReynolds (all F invertible): with R_d = R F⁻¹ (by a solve) and
    x⁻ = F x + B + W w̃, w̃ ~ N(0, I): QR of [[I, 0, 0], [−R_d W, R_d, ζ + R_d B]]
    gives [[·, ·, ·], [0, R⁻, ζ⁻]].  Otherwise through the covariance square
    root: S = R⁻¹, S⁻ from QR of [(F S)ᵀ; Wᵀ], R⁻ = (S⁻)⁻¹, ζ⁻ = R⁻ x⁻ (solves).
    """
    n = F.shape[-1]
    W = np.broadcast_to(W, F.shape[:-2] + W.shape[-2:])
    r = W.shape[-1]
    if (np.linalg.cond(F) < 1e10).all():
        Rd = np.swapaxes(np.linalg.solve(np.swapaxes(F, -1, -2), np.swapaxes(Rinfo, -1, -2)), -1, -2)
        lead = F.shape[:-2]
        top = np.concatenate([np.broadcast_to(np.eye(r), lead + (r, r)), np.zeros(lead + (r, n + 1))], axis=-1)
        bottom = np.concatenate([-Rd @ W, Rd, (zeta + np.einsum("...ij,...j->...i", Rd, B))[..., None]], axis=-1)
        T = triangular_r(np.concatenate([top, bottom], axis=-2))
        return T[..., r:, r : r + n], T[..., r:, r + n]
    S, x = _to_root(Rinfo, zeta)
    x_pred, S_pred = potter_predict(x, S, F, B, W)
    return _from_root(S_pred, x_pred)


def srif_update(Rinfo, zeta, rows):
    """QR of [[R⁻, ζ⁻], [H̃_1, z̃_1], …] = [[R⁺, ζ⁺], [0, e]] (SPEC §3); NIS = e².

    ``rows`` is a list of (H̃_j, z̃_j) blocks (one per node for the decentralized
    filter), each (…, m_j, n) and (…, m_j).  Returns R⁺, ζ⁺, e².
    """
    n = Rinfo.shape[-1]
    lead = Rinfo.shape[:-2]
    blocks = [np.concatenate([Rinfo, zeta[..., None]], axis=-1)]
    for Ht, zt in rows:
        Ht = np.broadcast_to(Ht, lead + Ht.shape[-2:])
        zt = np.broadcast_to(zt, lead + zt.shape[-1:])
        blocks.append(np.concatenate([Ht, zt[..., None]], axis=-1))
    T = triangular_r(np.concatenate(blocks, axis=-2))
    return T[..., :n, :n], T[..., :n, n], T[..., n, n] ** 2


def srif_scores(R_prior, R_post, log_det_R, e2, m):
    """ℓ with ln det S = ln det R + ln det I⁺ − ln det I⁻ = ln det R + 2 ln|det R⁺| − 2 ln|det R⁻|."""
    log_det_S = log_det_R + 2.0 * np.linalg.slogdet(R_post)[1] - 2.0 * np.linalg.slogdet(R_prior)[1]
    return -0.5 * (m * LOG_2PI + log_det_S + e2)
