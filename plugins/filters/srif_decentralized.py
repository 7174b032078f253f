"""Decentralized square-root information filter over N fully connected nodes (SPEC §3).

The square-root form of Algorithm 2 (seed 000): every node i keeps (R_i, ζ_i)
of every filter of the bank, predicts locally (SRIF time update), whitens its
own measurement into the rows [L_Ri⁻¹H_i, L_Ri⁻¹z_i] (the square-root form of
ΔI_i, Δs_i: ΔI_i = H̃_iᵀH̃_i, Δs_i = H̃_iᵀz̃_i), broadcasts them, and
assimilates everything by one QR of [[R_i⁻, ζ_i⁻], rows_1, …, rows_N].
The residual e_i of that QR gives each node its NIS (e_i²) and ℓ locally.
Nodes are the sensors passed to ``update``; it equals the centralized KF.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor
from hybridtrack.sdk.estimation import guarded
from hybridtrack_plugins.filters import _sqrt
from hybridtrack_plugins.filters.decentralized import NodeBank, NodeCopies, node_rows, replicate
from hybridtrack_plugins.filters.srif import SRIFState, srif_innovation


@attrs.frozen(eq=False, slots=False)
class DecentralizedSRIFState(NodeCopies, SRIFState):
    """Node arrays R (N, M, n, n), ζ (N, M, n); ``mean``/``covariance`` read node 0."""

    node_nis: np.ndarray | None = None
    node_loglik: np.ndarray | None = None
    node_fields = ("R", "zeta", "R_predicted", "zeta_predicted")


class DecentralizedSRIF(NodeBank):
    """Decentralized SRIF: nodes exchange whitened measurement rows (N nodes = the sensors given to ``update``)."""

    name = "srif_decentralized"

    def initialize(self, mean, cov) -> DecentralizedSRIFState:
        x, P = self.check_prior(mean, cov)
        R, zeta = _sqrt.srif_from_moments(x, P)
        return replicate(DecentralizedSRIFState(R[None], zeta[None], R[None], zeta[None]), self.nodes or 1)

    @guarded
    def predict(self, state: DecentralizedSRIFState, transitions) -> DecentralizedSRIFState:
        N, M, n = state.zeta.shape
        bank = self.check_transitions(transitions, M, n)
        F, B, W = (node_rows(a, N) for a in (bank.F, bank.B, _sqrt.noise_root(bank)))
        R, zeta = _sqrt.srif_predict(state.R.reshape(N * M, n, n), state.zeta.reshape(N * M, n), F, B, W)
        self.check_finite("predict", predicted_information_factor=R, predicted_information_state=zeta)
        R, zeta = R.reshape(N, M, n, n), zeta.reshape(N, M, n)
        return DecentralizedSRIFState(R, zeta, R, zeta)

    def update_measured(self, state: DecentralizedSRIFState, step, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        # each measuring node whitens its own data into rows and broadcasts them
        rows, log_det_R = [], 0.0
        for model, block in zip(step.models, step.blocks):
            Ht, zt, ldr = _sqrt.whiten(model.H, step.z[:, block], step.R[..., block, block])
            rows.append((Ht, zt))
            log_det_R = log_det_R + ldr
        # every node assimilates all rows by one QR
        R, zeta, e2 = _sqrt.srif_update(state.R, state.zeta, rows)
        node_loglik = _sqrt.srif_scores(state.R, R, log_det_R, e2, step.dim)
        _, nu, H = self.linearize(state.node_means[0], z, sensors, layout, step)
        innovation = Innovation(nu, srif_innovation(nu, H, state.R[0], step.R), node_loglik[0], e2[0])
        self.check_finite(
            "update", innovation_covariance=innovation.S, updated_information_state=zeta, node_NIS=e2, node_loglik=node_loglik
        )
        new = DecentralizedSRIFState(R, zeta, state.R_predicted, state.zeta_predicted, innovation, e2, node_loglik)
        return new, innovation


@hookimpl
def register_estimators(registry):
    registry.add(DecentralizedSRIF.name, DecentralizedSRIF)
