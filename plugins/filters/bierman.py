"""Bierman UD filter bank (SPEC §3; seed 003, "Bierman style"; Bierman 1977, Thornton 1976).

P = U D Uᵀ with U unit upper triangular and D = diag(d); time update by Thornton's modified weighted Gram–Schmidt
(``_sqrt.thornton_predict``), measurement update by Bierman's scalar algorithm after whitening
(``_sqrt.bierman_update``).
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor
from hybridtrack.sdk.estimation import BankEstimator, CovarianceMoments, bank_field, guarded
from hybridtrack.sdk.linalg import symmetrize
from hybridtrack_plugins.filters import _sqrt


@attrs.frozen(eq=False)
class UDState(CovarianceMoments):
    """x (M, n), U (M, n, n) unit upper triangular, d (M, n): P = U diag(d) Uᵀ; and the last prediction."""

    x: np.ndarray = bank_field(0)
    U: np.ndarray = bank_field(0)
    d: np.ndarray = bank_field(0)
    x_predicted: np.ndarray = bank_field(0)
    U_predicted: np.ndarray = bank_field(0)
    d_predicted: np.ndarray = bank_field(0)
    innovation: Innovation | None = None

    P = property(lambda self: _sqrt.ud_covariance(self.U, self.d))
    P_predicted = property(lambda self: _sqrt.ud_covariance(self.U_predicted, self.d_predicted))


class BiermanFilter(BankEstimator):
    """Bierman UD filter bank with Thornton's MWGS time update."""

    name = "bierman"

    def initialize(self, mean, cov) -> UDState:
        x, P = self.check_prior(mean, cov)
        U, d = _sqrt.ud_factor(P)
        return UDState(x, U, d, x, U, d)

    @guarded
    def predict(self, state: UDState, transitions) -> UDState:
        bank = self.check_transitions(transitions, *state.x.shape, state.x)
        x, U, d = _sqrt.thornton_predict(state.x, state.U, state.d, bank.F, bank.B, _sqrt.noise_root(bank))
        self.check_finite("predict", predicted_mean=x, predicted_variances_d=d, predicted_covariance_factor_U=U)
        return UDState(x, U, d, x, U, d)

    def update_measured(self, state: UDState, step, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        step, nu, H = self.linearize(state.x, z, sensors, layout, step)
        x, U, d, loglik, nis = _sqrt.bierman_update(state.x, state.U, state.d, H, nu, step.R)
        HU = H @ state.U
        S = symmetrize((HU * state.d[..., None, :]) @ np.swapaxes(HU, -1, -2) + step.R)
        innovation = Innovation(nu, S, loglik, nis)
        self.check_finite("update", innovation_covariance=S, updated_mean=x)
        return UDState(x, U, d, state.x_predicted, state.U_predicted, state.d_predicted, innovation), innovation


@hookimpl
def register_estimators(registry):
    registry.add(BiermanFilter.name, BiermanFilter)
