"""``info_kalman``: a small, readable Kalman filter bank for linear sensors.

Written only against hybridtrack's public API (``hybridtrack.core.interfaces``,
``hybridtrack.sdk.estimation``, ``hybridtrack.sdk.linalg``), as a third-party estimator
would be.  It is the covariance form of the Kalman filter (SPEC §3), every
solve going through the Cholesky factor of the innovation covariance S — the
"information" the detectors read (ν, S, ℓ, NIS):

    predict:  x⁻ = F x + B,           P⁻ = F P Fᵀ + G Q Gᵀ
    update:   ν = z − H x⁻,           S = H P⁻ Hᵀ + R = L Lᵀ
              K = P⁻ Hᵀ S⁻¹,          x⁺ = x⁻ + K ν
              P⁺ = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ          (Joseph form)
    scores:   NIS = νᵀ S⁻¹ ν,         ℓ = −½(m ln 2π + ln det S + NIS)

over stacked arrays (M filters at once).  The state is an attrs class whose
per-filter arrays are :func:`hybridtrack.sdk.estimation.bank_field` s, so the bank
operations ``take`` / ``concatenate`` come from
:class:`hybridtrack.sdk.estimation.BankEstimator`; so do the input checks and the
measurement assembly (NaN components dropped, R per sensor).
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack.core.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack.sdk.estimation import BankEstimator, bank_field
from hybridtrack.sdk.linalg import cholesky, cholesky_solve, gaussian_scores, symmetrize


@attrs.frozen(eq=False)
class InfoState:
    """A bank: x (M, n), P (M, n, n), the last prediction x⁻, P⁻ and the last innovation."""

    x: np.ndarray = bank_field()
    P: np.ndarray = bank_field()
    x_predicted: np.ndarray = bank_field()
    P_predicted: np.ndarray = bank_field()
    innovation: Innovation | None = None

    @property
    def mean(self) -> np.ndarray:
        return self.x

    @property
    def covariance(self) -> np.ndarray:
        return self.P

    @property
    def predicted_mean(self) -> np.ndarray:
        return self.x_predicted

    @property
    def predicted_covariance(self) -> np.ndarray:
        return self.P_predicted


class InfoKalman(BankEstimator):
    """Kalman filter bank, Joseph-form update, Cholesky solves; linear sensors and TransitionBanks only."""

    name = "info_kalman"

    def initialize(self, mean, cov) -> InfoState:
        x, P = self.check_prior(mean, cov)
        return InfoState(x, P, x, P)

    def predict(self, state: InfoState, transitions: TransitionBank) -> InfoState:
        M, n = state.x.shape
        bank = self.check_transitions(transitions, M, n)
        x = np.einsum("mij,mj->mi", bank.F, state.x) + bank.B
        P = symmetrize(bank.F @ state.P @ np.swapaxes(bank.F, -1, -2) + bank.Q)
        return InfoState(x, P, x, P)

    def update_measured(self, state: InfoState, step, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        """A measured step (the template ``update`` of BankEstimator handles the step without one)."""
        M, n = state.x.shape
        step, nu, H = self.linearize(state.x, z, sensors, layout, step)  # ν (M, m), H (m, n)
        R = np.broadcast_to(step.R, (M,) + step.R.shape[-2:])
        HP = H @ state.P  # (M, m, n)
        S = symmetrize(HP @ H.T + R)
        L = cholesky(S, "innovation covariance S")
        K = np.swapaxes(cholesky_solve(L, HP), -1, -2)  # P Hᵀ S⁻¹ (M, n, m)
        x = state.x + np.einsum("mij,mj->mi", K, nu)
        A = np.eye(n) - K @ H
        P = symmetrize(A @ state.P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2))
        loglik, nis = gaussian_scores(nu, L)
        innovation = Innovation(nu, S, loglik, nis)
        return InfoState(x, P, state.x_predicted, state.P_predicted, innovation), innovation
