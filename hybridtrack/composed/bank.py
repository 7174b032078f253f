"""A bank of filters that can grow, shrink and be re-created: the storage under the adaptive estimators.

Between steps the bank is held in covariance form — means (M, n), covariances
(M, n, n) and each filter's transition (F, B, Q = G Q_w Gᵀ), fixed when the
filter was started (SPEC §1: a turn's ω and centre come from the estimate at
the hypothesised switch).  A step hands the whole bank to any
:class:`~hybridtrack.interfaces.Estimator` (``initialize`` → ``predict`` →
``update``), so every estimator form (covariance, information, decentralized)
drives a bank whose membership changes from step to step; the estimator's
state after the update is kept for node-level quantities (the decentralized
filter's ``node_loglik``/``node_nis``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack.interfaces import Estimator, Innovation, MotionModel, Sensor, TransitionBank


class FilterBank:
    """Means, covariances and transitions of M filters, with labels (any per-filter payload)."""

    def __init__(self, n: int):
        self.n = int(n)
        self.means = np.zeros((0, n))
        self.covs = np.zeros((0, n, n))
        self.F = np.zeros((0, n, n))
        self.B = np.zeros((0, n))
        self.Q = np.zeros((0, n, n))
        self.labels: list = []
        self.state = None  # the estimator's state after the last update

    def __len__(self) -> int:
        return self.means.shape[0]

    def add(self, mean, cov, model: MotionModel, tau: float, switch_state, label=None) -> None:
        """Start a filter at (mean, cov) running ``model`` with its transition fixed at ``switch_state``."""
        t = model.transition(tau, np.asarray(switch_state, dtype=float))
        self.means = np.concatenate([self.means, np.asarray(mean, float)[None]])
        self.covs = np.concatenate([self.covs, np.asarray(cov, float)[None]])
        self.F = np.concatenate([self.F, t.F[None]])
        self.B = np.concatenate([self.B, t.B[None]])
        self.Q = np.concatenate([self.Q, t.process_noise[None]])
        self.labels.append(label)

    def keep(self, rows: Sequence[int]) -> None:
        """Keep only the filters ``rows`` (in that order)."""
        rows = np.asarray(rows, dtype=int)
        self.means, self.covs, self.F, self.B, self.Q = (a[rows] for a in (self.means, self.covs, self.F, self.B, self.Q))
        self.labels = [self.labels[i] for i in rows]

    def update_only(self, estimator: Estimator, z, sensors: Sequence[Sensor], layout: Sequence[str]) -> Innovation:
        """Measurement update without prediction (the first step, from the prior)."""
        state = estimator.initialize(self.means, self.covs)
        return self._update(estimator, state, z, sensors, layout)

    def step(self, estimator: Estimator, z, sensors: Sequence[Sensor], layout: Sequence[str]) -> Innovation:
        """Predict every filter with its own transition, then update with z (SPEC §3)."""
        state = estimator.initialize(self.means, self.covs)
        state = estimator.predict(state, TransitionBank(self.F, self.B, self.Q))
        return self._update(estimator, state, z, sensors, layout)

    def _update(self, estimator, state, z, sensors, layout) -> Innovation:
        state, innovation = estimator.update(state, z, sensors, layout)
        self.state = state
        self.means = np.array(estimator.mean(state), dtype=float)
        covs = np.array(estimator.covariance(state), dtype=float)
        self.covs = 0.5 * (covs + np.swapaxes(covs, -1, -2))
        return innovation

    def node_scores(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(ℓ, NIS) each node computed locally, shape (N, M), when the estimator is decentralized; else None."""
        loglik = getattr(self.state, "node_loglik", None)
        nis = getattr(self.state, "node_nis", None)
        if loglik is None or nis is None:
            return None
        return np.asarray(loglik, float), np.asarray(nis, float)
