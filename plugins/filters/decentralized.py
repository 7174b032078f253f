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

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack.sdk.estimation import BankEstimator, NodeMoments, bank_field, guarded
from hybridtrack_plugins.filters import _information as info
from hybridtrack_plugins.filters.information import information_predict, stacked_innovation


class NodeCopies(NodeMoments):
    """Mixin of the per-node states: ``node_fields`` the fields with a copy per node (axis 0; the first
    (N, M, n, n)), ``nodes`` N, the last prediction read at node 0."""

    nodes = property(lambda self: getattr(self, self.node_fields[0]).shape[0])
    predicted_mean = property(lambda self: self.x_predicted[0])
    predicted_covariance = property(lambda self: self.P_predicted[0])


@attrs.frozen(eq=False)
class DecentralizedState(NodeCopies):
    """Per-node information states: I (N, M, n, n), s (N, M, n); x⁻, P⁻ and the moments (x, P) (N, M, …)."""

    Y: np.ndarray = bank_field(1)
    s: np.ndarray = bank_field(1)
    x_predicted: np.ndarray = bank_field(1)
    P_predicted: np.ndarray = bank_field(1)
    moments: tuple = bank_field(1)
    innovation: Innovation | None = None
    node_nis: np.ndarray | None = None
    node_loglik: np.ndarray | None = None
    node_fields = ("Y", "s", "x_predicted", "P_predicted", "moments")


def replicate(state, N: int):
    """The state with node 0's copy of every field of ``state.node_fields`` repeated to N nodes (axis 0)."""

    def rep(a):
        return tuple(rep(v) for v in a) if isinstance(a, tuple) else np.repeat(a[:1], N, axis=0)

    return attrs.evolve(state, **{name: rep(getattr(state, name)) for name in state.node_fields})


def node_rows(a: np.ndarray, N: int) -> np.ndarray:
    """A per-filter array (M, …) repeated for the N nodes as rows (N M, …)."""
    return np.broadcast_to(a, (N,) + a.shape).reshape((N * a.shape[0],) + a.shape[1:])


class NodeBank(BankEstimator):
    """A bank holding a copy of every filter per node; the nodes are the sensors given to ``update``.

    ``nodes``: the number of nodes, if known at ``initialize``; otherwise the
    single initial copy is replicated to ``len(sensors)`` nodes at the first update.
    """

    update_results = ("node_nis", "node_loglik")

    def __init__(self, nodes: int | None = None):
        super().__init__()
        if nodes is not None and (int(nodes) != nodes or nodes < 1):
            raise ValueError(f"nodes: expected a positive integer, got {nodes!r}")
        self.nodes = None if nodes is None else int(nodes)

    def conform(self, states: list) -> list:
        """A bank started from one prior has one node copy until its first update: replicate it to the others' N."""
        N = max(s.nodes for s in states)
        return [s if s.nodes == N else replicate(s, N) for s in states]

    def node_scores(self, state):
        return None if state.node_loglik is None else (state.node_loglik, state.node_nis)

    @guarded
    def update(self, state, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        """Template: one node per sensor (a single node copy is replicated, another count is a ValueError), then
        :meth:`update_measured` with the step's linear model, or :meth:`unmeasured` when nothing was measured."""
        if isinstance(sensors, Sensor):
            sensors = (sensors,)
        if state.nodes != len(sensors):
            if state.nodes != 1:
                raise ValueError(f"sensors: expected {state.nodes} sensors (one per node of this decentralized filter), got {len(sensors)}")
            state = replicate(state, len(sensors))
        M, n = getattr(state, state.node_fields[0]).shape[1:3]
        step = self.measurement_step(z, sensors, layout, M, n, state)
        if step is None:
            return self.unmeasured(state, M)
        if step.H is None:
            raise ValueError(f"sensors: {self.name!r} takes linear sensors only")
        return self.update_measured(state, step, z, sensors, layout)


class DecentralizedFilter(NodeBank):
    """Decentralized information KF (Algorithm 2 of seed 000): N nodes = the sensors given to ``update``."""

    name = "decentralized"

    def initialize(self, mean, cov) -> DecentralizedState:
        x, P = self.check_prior(mean, cov)
        Y, s = info.to_information(x, P)
        return replicate(DecentralizedState(Y[None], s[None], x[None], P[None], (x[None], P[None])), self.nodes or 1)

    @guarded
    def predict(self, state: DecentralizedState, transitions: TransitionBank) -> DecentralizedState:
        N, M, n = state.s.shape
        bank = self.check_transitions(transitions, M, n)
        x, P = state.moments
        F, B, Q = (node_rows(a, N) for a in (bank.F, bank.B, bank.Q))
        Y, s, x, P = information_predict(x.reshape(N * M, n), P.reshape(N * M, n, n), F, B, Q, self.check_finite)
        Y, s, x, P = (a.reshape((N, M) + a.shape[1:]) for a in (Y, s, x, P))
        return DecentralizedState(Y, s, x, P, (x, P))

    def update_measured(self, state: DecentralizedState, step, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        # Each node's contribution (eqs. 18–19), formed about the prediction: ν_j = z_j − H_j x⁻.
        # Every node holds the same x⁻ (Algorithm 2 keeps them in step), so node i evaluates the
        # broadcast (ΔI_j, g_j, q_j, ln det R_j) about its own x_i⁻ (N, M, n).
        x_prior, P_prior = state.moments
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
        new = DecentralizedState(Y, s, state.x_predicted, state.P_predicted, (x_post, P_post), innovation, node_nis, node_loglik)
        return new, innovation


@hookimpl
def register_estimators(registry):
    registry.add(DecentralizedFilter.name, DecentralizedFilter)
