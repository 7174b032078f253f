"""Unscented Kalman filter bank: the sigma-point prediction of a nonlinear motion (issue 22, the coordinated turn).

The prediction through f of a Gaussian N(x⁺, P⁺) by the scaled unscented
transform (Julier & Uhlmann 2004, Proc. IEEE 92(3); Wan & van der Merwe 2000,
eqs. 15–17): with λ = α²(n + κ) − n and L the Cholesky factor of P⁺,

    χ_0 = x⁺,   χ_i = x⁺ + √(n+λ) L_i,   χ_{n+i} = x⁺ − √(n+λ) L_i   (i = 1 … n)
    W_0^m = λ/(n+λ),  W_0^c = W_0^m + 1 − α² + β,  W_i^m = W_i^c = 1/(2(n+λ))
    x⁻ = Σ_s W_s^m f(χ_s),   P⁻ = Σ_s W_s^c (f(χ_s) − x⁻)(f(χ_s) − x⁻)ᵀ + Q

(defaults α = 1, β = 2, κ = 0: λ = 0, the central point carries no mean
weight).  ``transitions`` is the linearizing callable of the EKF contract
(``model.linearizer(Δt)``): called at each sigma point of every filter (2n + 1
calls of (M, n) rows), its F χ + B is f(χ) exactly and its Q, taken at the
central point, the process noise.  A :class:`TransitionBank` is linear: the
ordinary Kalman prediction (the transform is exact there).  The update is the
Kalman update of :class:`~hybridtrack_plugins.filters.kalman.KalmanFilter`
(exact for the linear position sensors; linearized at x⁻ for a nonlinear one).
"""

from __future__ import annotations

import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.sdk.estimation import guarded
from hybridtrack_plugins.filters.kalman import CovarianceState, KalmanFilter


class UnscentedKalmanFilter(KalmanFilter):
    """Kalman filter bank with the unscented (sigma-point) prediction of a nonlinear motion (module docstring)."""

    name = "ukf"
    accepts_nonlinear = True

    def __init__(self, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0, form: str = "joseph"):
        super().__init__(form, structure=False)
        for key, value, low in (("alpha", alpha, 0.0), ("beta", beta, None), ("kappa", kappa, None)):
            if not np.isfinite(value) or (low is not None and value <= low):
                raise ValueError(f"{key}: expected a finite number{' > 0' if low is not None else ''}, got {value!r}")
        self.alpha, self.beta, self.kappa = float(alpha), float(beta), float(kappa)

    def weights(self, n: int) -> tuple[float, np.ndarray, np.ndarray]:
        """(√(n+λ), W^m (2n+1,), W^c (2n+1,)) of the scaled unscented transform (module docstring)."""
        lam = self.alpha**2 * (n + self.kappa) - n
        if not n + lam > 0:
            raise ValueError(f"alpha, kappa: n + λ = α²(n + κ) must be > 0, got {n + lam!r} for n = {n}")
        wm = np.full(2 * n + 1, 1.0 / (2.0 * (n + lam)))
        wc = wm.copy()
        wm[0] = lam / (n + lam)
        wc[0] = wm[0] + 1.0 - self.alpha**2 + self.beta
        return float(np.sqrt(n + lam)), wm, wc

    def predict(self, state, transitions):
        if isinstance(transitions, TransitionBank) or not callable(transitions):
            return super().predict(state, transitions)
        return self._sigma_point_predict(state, transitions)

    @guarded
    def _sigma_point_predict(self, state, transitions) -> CovarianceState:
        x, P = self.mean(state), self.covariance(state)
        M, n = x.shape
        scale, wm, wc = self.weights(n)
        try:
            L = np.linalg.cholesky(P)
        except np.linalg.LinAlgError:
            raise np.linalg.LinAlgError(
                f"predict: the covariance of {self.name!r} is not positive definite (its sigma points need a factor)"
            ) from None
        offsets = scale * np.swapaxes(L, -1, -2)  # row i: √(n+λ) L_i (M, n, n)
        chi = np.concatenate([x[:, None], x[:, None] + offsets, x[:, None] - offsets], axis=1)  # (M, 2n+1, n)
        images, Q = np.empty_like(chi), None
        for s in range(2 * n + 1):
            bank = self.check_transitions(transitions, M, n, chi[:, s])
            images[:, s] = np.einsum("mij,mj->mi", bank.F, chi[:, s]) + bank.B
            if s == 0:
                Q = bank.Q
        mean = np.einsum("s,msi->mi", wm, images)
        d = images - mean[:, None]
        cov = np.einsum("s,msi,msj->mij", wc, d, d) + Q
        cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
        self.check_finite("predict", predicted_mean=mean, predicted_covariance=cov)
        return CovarianceState(mean, cov, mean, cov, None)


@hookimpl
def register_estimators(registry):
    registry.add(UnscentedKalmanFilter.name, UnscentedKalmanFilter)
