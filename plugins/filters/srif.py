"""Square-root information filter bank (SPEC §3; Bierman 1977; seed 000 ref. 16).

State R and ζ with I = P⁻¹ = Rᵀ R and ζ = R x.  Measurement update by QR of the stacked whitened rows
(:func:`._sqrt.srif_update`, ℓ by :func:`._sqrt.srif_scores`); time update Dyer–McReynolds, or through the
covariance square root when some F of the bank is singular (the stop mode) (:func:`._sqrt.srif_predict`).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor
from hybridtrack.sdk.estimation import BankEstimator, DerivedMoments, bank_field, guarded
from hybridtrack.sdk.linalg import symmetrize
from hybridtrack_plugins.filters import _sqrt


@attrs.frozen(eq=False, slots=False)
class SRIFState(DerivedMoments):
    """R (…, M, n, n), ζ (…, M, n) now and after the last prediction; leading node axis for the decentralized form.
    The moments x = R⁻¹ζ, P = R⁻¹R⁻ᵀ (by solves) are computed on first reading."""

    R: np.ndarray = bank_field(-3)
    zeta: np.ndarray = bank_field(-2)
    R_predicted: np.ndarray = bank_field(-3)
    zeta_predicted: np.ndarray = bank_field(-2)
    innovation: Innovation | None = None

    @cached_property
    def moments(self):
        return _sqrt.srif_moments(self.R, self.zeta)

    @cached_property
    def predicted_moments(self):
        return _sqrt.srif_moments(self.R_predicted, self.zeta_predicted)

    x_predicted = property(lambda self: self.predicted_moments[0])
    P_predicted = property(lambda self: self.predicted_moments[1])


def srif_innovation(nu, H, Rinfo, R_meas):
    """S = (H R⁻¹)(H R⁻¹)ᵀ + R_meas with H R⁻¹ from a solve with Rᵀ."""
    A = np.linalg.solve(np.swapaxes(Rinfo, -1, -2), np.swapaxes(np.broadcast_to(H, Rinfo.shape[:-2] + H.shape[-2:]), -1, -2))
    return symmetrize(np.swapaxes(A, -1, -2) @ A + R_meas)


class SquareRootInformationFilter(BankEstimator):
    """Square-root information filter bank (QR of stacked information rows)."""

    name = "srif"

    def initialize(self, mean, cov) -> SRIFState:
        x, P = self.check_prior(mean, cov)
        R, zeta = _sqrt.srif_from_moments(x, P)
        return SRIFState(R, zeta, R, zeta)

    @guarded
    def predict(self, state: SRIFState, transitions) -> SRIFState:
        bank = self.check_transitions(transitions, *state.zeta.shape, state.mean if callable(transitions) else None)
        R, zeta = _sqrt.srif_predict(state.R, state.zeta, bank.F, bank.B, _sqrt.noise_root(bank))
        self.check_finite("predict", predicted_information_factor=R, predicted_information_state=zeta)
        return SRIFState(R, zeta, R, zeta)

    def update_measured(self, state: SRIFState, step, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        x = state.mean
        step, nu, H = self.linearize(x, z, sensors, layout, step)
        # the whitened rows [H̃, z̃], z̃ = L_R⁻¹(ν + H x⁻): the linearized measurement z ≈ h(x⁻) + H (x − x⁻)
        Ht, nut, log_det_R = _sqrt.whiten(H, nu, step.R)
        zt = nut + np.einsum("...ij,...j->...i", Ht, x)
        R, zeta, e2 = _sqrt.srif_update(state.R, state.zeta, [(Ht, zt)])
        loglik = _sqrt.srif_scores(state.R, R, log_det_R, e2, step.dim)
        innovation = Innovation(nu, srif_innovation(nu, H, state.R, step.R), loglik, e2)
        self.check_finite("update", innovation_covariance=innovation.S, updated_information_state=zeta)
        return SRIFState(R, zeta, state.R_predicted, state.zeta_predicted, innovation), innovation


@hookimpl
def register_estimators(registry):
    registry.add(SquareRootInformationFilter.name, SquareRootInformationFilter)
