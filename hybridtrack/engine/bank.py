"""A bank of filters whose membership changes between steps: the storage under the adaptive estimators.

The bank holds the estimator's own state object (covariance, information,
square-root factors, per-node copies) from step to step and changes its
membership only through the estimator's bank operations
(:meth:`~hybridtrack.core.interfaces.Estimator.take` and
:meth:`~hybridtrack.core.interfaces.Estimator.concatenate`), so a square-root
filter's factors are propagated, never rebuilt from P, and a decentralized
filter's nodes keep their own states.  ``initialize`` is called once per
:meth:`FilterBank.start` (a bank created from a given estimate); filters added
by :meth:`FilterBank.branch` are copies of an existing filter's state.

Each filter runs its own motion model with its transition fixed at a switch
state (SPEC §1: a turn's ω and centre come from the estimate at the
hypothesised switch).  Transitions are built for the step's Δt and kept until
Δt changes, so regular sampling builds each filter's transition once.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from hybridtrack.core.interfaces import Estimator, Innovation, MotionModel, Sensor, TransitionBank


class BankMoments:
    """The moments of a bank's filters read from its ``estimator`` and ``state`` (``_moments`` caches them until
    the state changes): shared by :class:`FilterBank` and :class:`~hybridtrack.engine.run_bank.RunBank`."""

    def _read(self) -> tuple[np.ndarray, np.ndarray]:
        if self._moments is None:
            covs = np.asarray(self.estimator.covariance(self.state), dtype=float)
            self._moments = (np.asarray(self.estimator.mean(self.state), dtype=float), 0.5 * (covs + np.swapaxes(covs, -1, -2)))
        return self._moments

    @property
    def means(self) -> np.ndarray:
        """x (rows, n) of every filter."""
        return self._read()[0]

    @property
    def covs(self) -> np.ndarray:
        """P (rows, n, n) of every filter, symmetrized ½(P + Pᵀ)."""
        return self._read()[1]


class FilterBank(BankMoments):
    """M filters of one estimator: its state, each filter's model and switch state, and labels (any payload)."""

    def __init__(self, estimator: Estimator, layout: Sequence[str]):
        self.estimator = estimator
        self.layout = tuple(layout)
        self.state: Any = None
        self.models: list[MotionModel] = []
        self.switch_states = np.zeros((0, len(self.layout)))
        self.labels: list = []
        self._dt: float | None = None
        self._transitions: TransitionBank | None = None
        self._moments: tuple | None = None

    def __len__(self) -> int:
        return len(self.models)

    # ------------------------------------------------------------------ membership
    def start(self, mean, cov, models: Sequence[MotionModel], switch_state, labels: Sequence | None = None) -> None:
        """Replace the bank by one filter per model, each starting at (mean, cov) with its transition fixed at ``switch_state``."""
        M = len(models)
        mean, cov = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
        self.state = self.estimator.initialize(np.broadcast_to(mean, (M,) + mean.shape), np.broadcast_to(cov, (M,) + cov.shape))
        self._reset_members(models, switch_state, labels)

    def restart(self, row: int, models: Sequence[MotionModel], switch_state, labels: Sequence | None = None) -> None:
        """Replace the bank by copies of filter ``row`` (its own state form, no re-initialization), one per model."""
        self.state = self.estimator.take(self.state, [row] * len(models))
        self._reset_members(models, switch_state, labels)

    def branch(self, row: int, models: Sequence[MotionModel], switch_state, labels: Sequence | None = None) -> None:
        """Append copies of filter ``row``, one per model, hypothesising a switch at ``switch_state``."""
        if not models:
            return
        copies = self.estimator.take(self.state, [row] * len(models))
        self.state = self.estimator.concatenate([self.state, copies])
        self._append_members(models, switch_state, labels)
        self._moments = None

    def keep(self, rows: Sequence[int]) -> None:
        """Keep only the filters ``rows`` (in that order)."""
        rows = np.asarray(rows, dtype=int).reshape(-1)
        self.state = self.estimator.take(self.state, rows)
        self.models = [self.models[i] for i in rows]
        self.switch_states = self.switch_states[rows]
        self.labels = [self.labels[i] for i in rows]
        if self._transitions is not None:
            t = self._transitions
            self._transitions = TransitionBank(t.F[rows], t.B[rows], t.Q[rows], None if t.noise_root is None else t.noise_root[rows])
        if self._moments is not None:
            self._moments = (self._moments[0][rows], self._moments[1][rows])

    def replace_models(self, models: Sequence[MotionModel]) -> None:
        """Run the filters on ``models`` from now on (one per filter), keeping their states and switch states."""
        if len(models) != len(self.models):
            raise ValueError(f"models: expected {len(self.models)} models (one per filter), got {len(models)}")
        self.models = list(models)
        self._transitions = None

    def _reset_members(self, models, switch_state, labels) -> None:
        self.models, self.labels = [], []
        self.switch_states = np.zeros((0, len(self.layout)))
        self._transitions = None
        self._append_members(models, switch_state, labels)
        self._moments = None

    def _append_members(self, models, switch_state, labels) -> None:
        models = list(models)
        labels = [None] * len(models) if labels is None else list(labels)
        if len(labels) != len(models):
            raise ValueError(f"labels: expected {len(models)} labels, got {len(labels)}")
        x_s = np.broadcast_to(np.asarray(switch_state, dtype=float), (len(models), len(self.layout)))
        self.models += models
        self.switch_states = np.concatenate([self.switch_states, x_s])
        self.labels += labels
        if self._transitions is not None:
            new = TransitionBank.stack([m.transition(self._dt, x) for m, x in zip(models, x_s)])
            old = self._transitions
            root = (
                None
                if old.noise_root is None or new.noise_root is None or old.noise_root.shape[-1] != new.noise_root.shape[-1]
                else (np.concatenate([old.noise_root, new.noise_root]))
            )
            self._transitions = TransitionBank(
                np.concatenate([old.F, new.F]), np.concatenate([old.B, new.B]), np.concatenate([old.Q, new.Q]), root
            )

    # ------------------------------------------------------------------ steps
    def transitions(self, dt: float) -> TransitionBank:
        """Every filter's transition over ``dt`` seconds.

        Linear models: fixed at each filter's switch state, rebuilt only when
        Δt changes.  A bank with a nonlinear model is relinearized at every
        filter's current mean each step (EKF; MotionModel contract:
        F x̂ + B = f(x̂)).
        """
        if not all(m.linear for m in self.models):
            self._transitions = None
            return TransitionBank.stack([m.transition(dt, x) for m, x in zip(self.models, self.means)])
        if self._transitions is None or dt != self._dt:
            self._dt = dt
            self._transitions = TransitionBank.stack([m.transition(dt, x) for m, x in zip(self.models, self.switch_states)])
        return self._transitions

    def update_only(self, z, sensors: Sequence[Sensor]) -> Innovation:
        """Measurement update without prediction (the first step, from the prior)."""
        return self._update(self.state, z, sensors)

    def step(self, dt: float, z, sensors: Sequence[Sensor]) -> Innovation:
        """Predict every filter over ``dt`` with its own transition, then update with z (SPEC §3)."""
        return self._update(self.estimator.predict(self.state, self.transitions(dt)), z, sensors)

    def _update(self, state, z, sensors) -> Innovation:
        self.state, innovation = self.estimator.update(state, z, sensors, self.layout)
        self._moments = None
        return innovation

    # ------------------------------------------------------------------ reading
    def node_scores(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(ℓ, NIS) each node computed locally, shape (N, M), for a decentralized estimator; else None."""
        scores = self.estimator.node_scores(self.state)
        return None if scores is None else (np.asarray(scores[0], float), np.asarray(scores[1], float))
