"""Potter square-root filter bank (SPEC §3; seed 003, "Potter style"; Potter 1963, Bierman 1977).

State x and a square root S of P = S Sᵀ; time update by QR (``_sqrt.potter_predict``), measurement update by
whitening and one scalar Potter step per component (``_sqrt.potter_update``).  P is never formed in the filter;
``covariance`` assembles it for reading.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor
from hybridtrack.sdk.estimation import BankEstimator, CovarianceMoments, bank_field, guarded
from hybridtrack.sdk.linalg import cholesky, symmetrize
from hybridtrack_plugins.filters import _sqrt


@attrs.frozen(eq=False)
class SquareRootState(CovarianceMoments):
    """x (M, n), S (M, n, n) with P = S Sᵀ; the same for the last prediction."""

    x: np.ndarray = bank_field(0)
    S: np.ndarray = bank_field(0)
    x_predicted: np.ndarray = bank_field(0)
    S_predicted: np.ndarray = bank_field(0)
    innovation: Innovation | None = None

    P = property(lambda self: self.S @ np.swapaxes(self.S, -1, -2))
    P_predicted = property(lambda self: self.S_predicted @ np.swapaxes(self.S_predicted, -1, -2))


class PotterFilter(BankEstimator):
    """Potter square-root Kalman filter bank (scalar measurement processing after whitening)."""

    name = "potter"

    def initialize(self, mean, cov) -> SquareRootState:
        x, P = self.check_prior(mean, cov)
        S = cholesky(P, "cov")
        return SquareRootState(x, S, x, S)

    @guarded
    def predict(self, state: SquareRootState, transitions) -> SquareRootState:
        bank = self.check_transitions(transitions, *state.x.shape, state.x)
        x, S = _sqrt.potter_predict(state.x, state.S, bank.F, bank.B, _sqrt.noise_root(bank))
        self.check_finite("predict", predicted_mean=x, predicted_covariance_factor=S)
        return SquareRootState(x, S, x, S)

    def update_measured(self, state: SquareRootState, step, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        step, nu, H = self.linearize(state.x, z, sensors, layout, step)
        x, S, loglik, nis = _sqrt.potter_update(state.x, state.S, H, nu, step.R)
        HS = H @ state.S  # S = (H S⁻)(H S⁻)ᵀ + R from the factor; ℓ and NIS from the scalar steps
        innovation = Innovation(nu, symmetrize(HS @ np.swapaxes(HS, -1, -2) + step.R), loglik, nis)
        self.check_finite("update", innovation_covariance=innovation.S, updated_mean=x)
        return SquareRootState(x, S, state.x_predicted, state.S_predicted, innovation), innovation


@hookimpl
def register_estimators(registry):
    registry.add(PotterFilter.name, PotterFilter)
