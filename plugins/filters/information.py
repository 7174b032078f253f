"""Information filter bank (SPEC §3, seed 000 eqs. 10–13).

State I = P⁻¹, s = I x (and x, P).  Predict in covariance form (F may be singular, e.g.
the stop mode): P⁺ = (I⁺)⁻¹, P⁻ = F P⁺ Fᵀ + G Q Gᵀ, I⁻ = (P⁻)⁻¹, s⁻ = I⁻ x⁻
(seed 000 eq. 17), all by Cholesky solves.  Update:
I⁺ = I⁻ + Hᵀ R⁻¹ H,  s⁺ = s⁻ + Hᵀ R⁻¹ z  (eqs. 10–13), evaluated about the
prediction: x⁺ = x⁻ + (I⁺)⁻¹ Hᵀ R⁻¹ ν, s⁺ = I⁺ x⁺ (the same, exact far from the origin).
ν = z − H x⁻ and S = H P⁻ Hᵀ + R are reported as in the covariance form; the
NIS is also computed from information quantities alone (seed 000 eq. 22, in
the innovation form of ``_information.local_scores``) and
kept as ``state.nis_information``.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack.sdk.estimation import BankEstimator, DerivedMoments, bank_field, guarded
from hybridtrack.sdk.linalg import cholesky, gaussian_scores, symmetrize
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters import _information as info


@attrs.frozen(eq=False)
class InformationState(DerivedMoments):
    """I (M, n, n) and s (M, n), with x⁻, P⁻ of the last prediction and the moments (x, P) of I and s."""

    Y: np.ndarray = bank_field(0)
    s: np.ndarray = bank_field(0)
    x_predicted: np.ndarray = bank_field(0)
    P_predicted: np.ndarray = bank_field(0)
    moments: tuple = bank_field(0)
    innovation: Innovation | None = None
    nis_information: np.ndarray | None = None


def information_predict(x, P, F, B, Q, check):
    """(I⁻, s⁻, x⁻, P⁻) from the moments (x⁺, P⁺) of (I⁺, s⁺) through the covariance prediction (seed 000 eqs. 16–17).

    The state holds x⁺ (never recovered from s⁺ = I⁺x⁺ by a solve, whose error
    grows with |x|).  ``check`` is called as ``check("predict", predicted_mean=x⁻,
    predicted_covariance=P⁻)`` before P⁻ is inverted (:meth:`BankEstimator.check_finite`).
    """
    x_pred, P_pred = cov_form.predict(x, P, F, B, Q)
    check("predict", predicted_mean=x_pred, predicted_covariance=P_pred)
    return (*info.to_information(x_pred, P_pred), x_pred, P_pred)


def stacked_innovation(step, x_pred, P_pred, layout):
    """ν = z − H x⁻, S = H P⁻ Hᵀ + R and their scores for the stacked (centralized) model."""
    z_pred, H = step.predicted(x_pred, layout)
    nu = step.residual(z_pred)
    S = symmetrize(H @ P_pred @ np.swapaxes(H, -1, -2) + step.R)
    loglik, nis = gaussian_scores(nu, cholesky(S, "innovation covariance S"))
    return Innovation(nu, S, loglik, nis)


class InformationFilter(BankEstimator):
    """Information-form Kalman filter bank (I = P⁻¹, s = I x)."""

    name = "information"

    def initialize(self, mean, cov) -> InformationState:
        x, P = self.check_prior(mean, cov)
        Y, s = info.to_information(x, P)
        return InformationState(Y, s, x, P, (x, P))

    @guarded
    def predict(self, state: InformationState, transitions: TransitionBank) -> InformationState:
        bank = self.check_transitions(transitions, *state.s.shape)
        Y, s, x, P = information_predict(*state.moments, bank.F, bank.B, bank.Q, self.check_finite)
        return InformationState(Y, s, x, P, (x, P))

    update_results = ("nis_information",)

    def update_measured(self, state: InformationState, step, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        if step.H is None:
            raise ValueError(f"sensors: {self.name!r} takes linear sensors only")
        x_prior, P_prior = state.mean, state.covariance  # the prior of this update
        innovation = stacked_innovation(step, x_prior, P_prior, layout)
        dY, g, q, log_det_R = info.innovation_information(step.H, step.R, innovation.nu)  # about x⁻ (eq. 22 rewritten)
        Y, s, x_post, P_post, delta = info.assimilate(x_prior, state.Y, dY, g)
        self.check_finite("update", updated_mean=x_post)
        _, nis_local = info.local_scores(state.Y, Y, g, delta, q, log_det_R, step.dim)
        return InformationState(Y, s, state.x_predicted, state.P_predicted, (x_post, P_post), innovation, nis_local), innovation


@hookimpl
def register_estimators(registry):
    registry.add(InformationFilter.name, InformationFilter)
