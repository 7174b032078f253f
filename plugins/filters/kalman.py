"""Covariance-form Kalman filter bank (SPEC §3, seed 000 Algorithm 1).

Predict:  x⁻ = F x⁺ + B,  P⁻ = F P⁺ Fᵀ + G Q Gᵀ                       (eqs. 4–5)
Update:   S = H P⁻ Hᵀ + R,  K = P⁻ Hᵀ S⁻¹,  ν = z − H x⁻,  x⁺ = x⁻ + K ν,
          P⁺ = (I − K H) P⁻ (Joseph form by default)                 (eqs. 6–9)
Scores:   ℓ = −½(m ln 2π + ln det S + νᵀS⁻¹ν),  NIS = νᵀS⁻¹ν          (SPEC §4)

All of it over stacked arrays: M filters with their own F, B, Q are one call.
The centralized multisensor filter is this filter given all sensors at once
(H = [H_1; …; H_N], R = blockdiag(R_i), SPEC §2).
"""

from __future__ import annotations

from typing import Sequence

import attrs
import numpy as np

from hybridtrack.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters._base import BankEstimator, empty_innovation


@attrs.frozen(eq=False)
class CovarianceState:
    """A bank in covariance form: x (M, n), P (M, n, n), plus the last prediction and innovation."""

    x: np.ndarray
    P: np.ndarray
    x_predicted: np.ndarray
    P_predicted: np.ndarray
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

    @property
    def bank_size(self) -> int:
        return self.x.shape[0]


class KalmanFilter(BankEstimator):
    """Covariance-form Kalman filter bank (Joseph or symmetrised update, Cholesky solves).

    ``form``: ``"joseph"`` (default), ``"symmetric"`` (P⁻ − K S Kᵀ, symmetrised)
    or ``"conventional"`` ((I − K H) P⁻ unsymmetrised, for comparisons only).
    Linear sensors only; the ``ekf`` estimator takes nonlinear ones.
    """

    name = "kalman"

    def __init__(self, form: str = "joseph"):
        super().__init__()
        if form not in cov_form.UPDATE_FORMS:
            raise ValueError(f"form: expected one of {cov_form.UPDATE_FORMS}, got {form!r}")
        self.form = form

    def initialize(self, mean, cov) -> CovarianceState:
        x, P = self._check_prior(mean, cov)
        return CovarianceState(x, P, x, P, None)

    def predict(self, state: CovarianceState, transitions: TransitionBank) -> CovarianceState:
        M, n = state.x.shape
        bank = self._check_transitions(transitions, M, n, state.x)
        x, P = cov_form.predict(state.x, state.P, bank.F, bank.B, bank.Q)
        return CovarianceState(x, P, x, P, None)

    def update(self, state: CovarianceState, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        M, n = state.x.shape
        found = self._linearized(state.x, z, sensors, layout)
        if found is None:
            innovation = empty_innovation(M)
            return attrs.evolve(state, innovation=innovation), innovation
        step, nu, H = found
        x, P, S, L, _ = cov_form.update(state.x, state.P, nu, H, step.R, step.selection, self.form)
        loglik, nis = cov_form.innovation_scores(nu, L)
        innovation = Innovation(nu, S, loglik, nis)
        return CovarianceState(x, P, state.x_predicted, state.P_predicted, innovation), innovation


COMPONENTS = {"kalman": KalmanFilter}
