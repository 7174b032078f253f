"""Decentralized information Kalman filter over N fully connected nodes (SPEC §3, seed 000 Algorithm 2).

Every node i keeps its own copy (I_i, s_i) of every filter of the bank and:

1. predicts locally: x_i⁻ = F x_i⁺ + B, (P_i⁻)⁻¹ = (F P_i⁺ Fᵀ + G Q Gᵀ)⁻¹       (eqs. 16–17)
2. computes its contribution ΔI_i = H_iᵀR_i⁻¹H_i and, about the prediction
   (ν_i = z_i − H_i x⁻), g_i = H_iᵀR_i⁻¹ν_i (= Δs_i − ΔI_i x⁻), q_i = ν_iᵀR_i⁻¹ν_i
   and ln det R_i                                                        (eqs. 18–19)
3. broadcasts them; every node assimilates all of them:
   I_i⁺ = I_i⁻ + Σ_j ΔI_j,  x_i⁺ = x_i⁻ + (I_i⁺)⁻¹ Σ_j g_j
   (= (I_i⁺)⁻¹ (I_i⁻ x_i⁻ + Σ_j Δs_j))                                    (eqs. 20–21)

The nodes are the sensors passed to ``update`` (node j = ``sensors[j]``); a node
without a measurement at a step broadcasts nothing.  Each node also computes
NIS and ℓ locally (seed 000 eq. 22 rewritten about the prediction,
NIS = Σ_j q_j − gᵀ(I⁺)⁻¹g, and the determinant lemma; see
``_information.local_scores``), exact at any distance from the coordinate
origin (eq. 22 as printed loses accuracy with its square), kept as
``state.node_nis`` / ``state.node_loglik`` (N, M).  The returned
:class:`Innovation` is that of the stacked (centralized) model at node 0, for
comparison with the centralized filter (``kalman`` given all sensors), which
this filter equals exactly (Rao & Durrant-Whyte 1991).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack.sdk.estimation import BankEstimator, NodeMoments, bank_field, empty_innovation, guarded
from hybridtrack_plugins.filters import _information as info
from hybridtrack_plugins.filters.information import information_predict, stacked_innovation


@attrs.frozen(eq=False, slots=False)
class DecentralizedState(NodeMoments):
    """Per-node information states: I (N, M, n, n), s (N, M, n); x⁻, P⁻ (N, M, …)."""

    Y: np.ndarray = bank_field(1)
    s: np.ndarray = bank_field(1)
    x_predicted: np.ndarray = bank_field(1)
    P_predicted: np.ndarray = bank_field(1)
    innovation: Innovation | None = None
    node_nis: np.ndarray | None = None
    node_loglik: np.ndarray | None = None
    moments: tuple | None = bank_field(1, default=None)

    @property
    def nodes(self) -> int:
        return self.Y.shape[0]

    @cached_property
    def _moments(self):
        return self.moments if self.moments is not None else info.to_covariance(self.Y, self.s)

    @property
    def predicted_mean(self) -> np.ndarray:
        return self.x_predicted[0]

    @property
    def predicted_covariance(self) -> np.ndarray:
        return self.P_predicted[0]


class DecentralizedFilter(BankEstimator):
    """Decentralized information KF (Algorithm 2 of seed 000): N nodes = the sensors given to ``update``.

    ``nodes``: the number of nodes, if known at ``initialize``; otherwise the
    single initial copy is replicated to ``len(sensors)`` nodes at the first update.
    """

    name = "decentralized"

    def __init__(self, nodes: int | None = None):
        super().__init__()
        if nodes is not None and (int(nodes) != nodes or nodes < 1):
            raise ValueError(f"nodes: expected a positive integer, got {nodes!r}")
        self.nodes = None if nodes is None else int(nodes)

    def initialize(self, mean, cov) -> DecentralizedState:
        x, P = self.check_prior(mean, cov)
        Y, s = info.to_information(x, P)
        N = self.nodes or 1
        rep = lambda a: np.broadcast_to(a, (N,) + a.shape).copy()  # noqa: E731
        return DecentralizedState(rep(Y), rep(s), rep(x), rep(P), moments=(rep(x), rep(P)))

    def conform(self, states: list) -> list:
        """A bank started from one prior has one node copy until its first update: replicate it to the others' N."""
        N = max(s.nodes for s in states)
        return [s if s.nodes == N else self._replicate(s, N) for s in states]

    def node_scores(self, state: DecentralizedState):
        if state.node_loglik is None:
            return None
        return state.node_loglik, state.node_nis

    @guarded
    def predict(self, state: DecentralizedState, transitions: TransitionBank) -> DecentralizedState:
        N, M, n = state.s.shape
        bank = self.check_transitions(transitions, M, n)
        flat = lambda a: np.broadcast_to(a, (N,) + a.shape).reshape((N * M,) + a.shape[1:])  # noqa: E731
        x, P = state._moments
        Y, s, x, P = information_predict(
            state.Y.reshape(N * M, n, n),
            state.s.reshape(N * M, n),
            flat(bank.F),
            flat(bank.B),
            flat(bank.Q),
            (x.reshape(N * M, n), P.reshape(N * M, n, n)),
            self.check_finite,
        )
        shape = lambda a: a.reshape((N, M) + a.shape[1:])  # noqa: E731
        return DecentralizedState(shape(Y), shape(s), shape(x), shape(P), moments=(shape(x), shape(P)))

    def _replicate(self, state: DecentralizedState, N: int) -> DecentralizedState:
        rep = lambda a: np.broadcast_to(a[:1], (N,) + a.shape[1:]).copy()  # noqa: E731
        x, P = state._moments
        return DecentralizedState(rep(state.Y), rep(state.s), rep(state.x_predicted), rep(state.P_predicted), moments=(rep(x), rep(P)))

    @guarded
    def update(self, state: DecentralizedState, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        if isinstance(sensors, Sensor):
            sensors = (sensors,)
        N, M, n = state.s.shape
        if N != len(sensors):
            if N != 1:
                raise ValueError(f"sensors: expected {N} sensors (one per node of this decentralized filter), got {len(sensors)}")
            state = self._replicate(state, len(sensors))
            N = len(sensors)
        step = self.measurement_step(z, sensors, layout, M, n)
        if step is None:
            innovation = empty_innovation(M)
            return attrs.evolve(state, innovation=innovation, node_nis=None, node_loglik=None, moments=state._moments), innovation
        if step.H is None:
            raise ValueError(f"sensors: {self.name!r} takes linear sensors only")
        # Each node's contribution (eqs. 18–19), formed about the prediction: ν_j = z_j − H_j x⁻.
        # Every node holds the same x⁻ (Algorithm 2 keeps them in step), so node i evaluates the
        # broadcast (ΔI_j, g_j, q_j, ln det R_j) about its own x_i⁻ (N, M, n).
        x_prior, P_prior = state._moments
        dY = g = q = log_det_R = 0.0
        for model, block in zip(step.models, step.blocks):
            nu_j = step.z[:, block] - x_prior @ model.H.T  # (N, M, m_j)
            dY_j, g_j, q_j, ldr_j = info.innovation_information(model.H, step.R[..., block, block], nu_j)
            # Communication: every node receives every contribution and sums them.
            dY, g, q, log_det_R = dY + dY_j, g + g_j, q + q_j, log_det_R + ldr_j
        # Assimilation at every node (eqs. 20–21) and the node's own NIS and ℓ (eq. 22, innovation form).
        Y, s, x_post, P_post, delta = info.assimilate(x_prior, state.Y, dY, g)
        node_loglik, node_nis = info.local_scores(state.Y, Y, g, delta, q, log_det_R, step.dim)
        self.check_finite("update", updated_mean=x_post, node_NIS=node_nis, node_loglik=node_loglik)
        innovation = stacked_innovation(step, x_prior[0], P_prior[0], layout)
        new = DecentralizedState(Y, s, state.x_predicted, state.P_predicted, innovation, node_nis, node_loglik, (x_post, P_post))
        return new, innovation


@hookimpl
def register_estimators(registry):
    registry.add(DecentralizedFilter.name, DecentralizedFilter)
