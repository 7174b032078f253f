"""Shared pieces of the bank estimators: input checks, the empty innovation, the reading API.

Every estimator state object of this family exposes, per step and per filter
(issue 3 item 5):

* ``mean`` (M, n) and ``covariance`` (M, n, n): the current (updated, or just
  predicted) estimate, P assembled from the factors for factor forms;
* ``predicted_mean`` / ``predicted_covariance``: x⁻, P⁻ of the last prediction
  (equal to the current ones right after ``predict``);
* ``innovation``: the :class:`~hybridtrack.interfaces.Innovation` (ν, S, ℓ,
  NIS) of the last update, ``None`` right after ``predict`` or ``initialize``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from hybridtrack.interfaces import Estimator, Innovation, TransitionBank, check_prior
from hybridtrack.measurements import MeasurementAssembler
from hybridtrack.validation import as_float_array


class NodeMoments:
    """Mixin for decentralized states: ``_moments`` = (x (N, M, n), P (N, M, n, n)) over the N nodes;
    ``mean``/``covariance`` read node 0 (every node holds the same estimate up to rounding)."""

    @property
    def node_means(self) -> np.ndarray:
        """Every node's x (N, M, n)."""
        return self._moments[0]

    @property
    def node_covariances(self) -> np.ndarray:
        """Every node's P (N, M, n, n)."""
        return self._moments[1]

    @property
    def mean(self) -> np.ndarray:
        return self._moments[0][0]

    @property
    def covariance(self) -> np.ndarray:
        return self._moments[1][0]


def empty_innovation(bank_size: int) -> Innovation:
    """m = 0: no measurement at this step (prediction only)."""
    return Innovation(np.zeros((bank_size, 0)), np.zeros((bank_size, 0, 0)), np.zeros(bank_size), np.zeros(bank_size))


class BankEstimator(Estimator):
    """Common plumbing; subclasses implement the maths of one form."""

    def __init__(self):
        self._assembler = MeasurementAssembler()
        self._checked_transitions: tuple | None = None

    # ------------------------------------------------------------------ checks
    @staticmethod
    def _check_prior(mean, cov) -> tuple[np.ndarray, np.ndarray]:
        return check_prior(mean, cov)

    #: estimators that relinearize (EKF forms) accept nonlinear sensors and a callable for ``transitions``
    accepts_nonlinear = False

    def _check_transitions(self, transitions, bank_size: int, n: int, x: np.ndarray | None = None) -> TransitionBank:
        """F (M, n, n), B (M, n), Q (M, n, n) finite; a bank already checked (same object) is not re-checked.

        Extended filters also take a callable ``transitions(x) -> TransitionBank``
        that linearizes the motion at the current estimate x (M, n):
        F = ∂f/∂x(x), B = f(x) − F x, so that F x + B = f(x) (MotionModel contract).
        """
        if callable(transitions) and not isinstance(transitions, TransitionBank):
            if not self.accepts_nonlinear:
                raise ValueError(
                    f"transitions: {self.name!r} takes a TransitionBank; a linearizing callable needs an extended filter ('ekf', 'ekf_sqrt')"
                )
            transitions = transitions(x)
            self._checked_transitions = None
        if not isinstance(transitions, TransitionBank):
            raise ValueError(f"transitions: expected a TransitionBank, got {type(transitions).__name__}")
        checked = self._checked_transitions
        if checked is not None and checked[0] is transitions and checked[1] == (bank_size, n):
            return transitions
        as_float_array(transitions.F, "transitions.F", (bank_size, n, n))
        as_float_array(transitions.B, "transitions.B", (bank_size, n))
        as_float_array(transitions.Q, "transitions.Q", (bank_size, n, n))
        if getattr(transitions, "noise_root", None) is not None:
            as_float_array(transitions.noise_root, "transitions.noise_root", (bank_size, n, None))
        self._checked_transitions = (transitions, (bank_size, n))
        return transitions

    def _measurement(self, z, sensors: Sequence, layout: Sequence[str], bank_size: int, n: int):
        if len(layout) != n:
            raise ValueError(f"layout: expected {n} component names (the state dimension), got {len(layout)}")
        return self._assembler.assemble(z, sensors, layout, bank_size)

    def _linearized(self, x: np.ndarray, z, sensors: Sequence, layout: Sequence[str]):
        """(step, ν, H) at x (M, n), or None when nothing was measured (prediction only).

        ν = residual(z, h(x)) per sensor (angles wrapped), H = ∂h/∂x at x.
        """
        M, n = x.shape
        step = self._measurement(z, sensors, layout, M, n)
        if step is None:
            return None
        if step.H is None and not self.accepts_nonlinear:
            names = [m.sensor.name for m in step.models if m.H is None]
            raise ValueError(f"sensors: {self.name!r} takes linear sensors only; {names} are nonlinear (use an extended filter)")
        z_pred, H = step.predicted(x, layout)
        return step, step.residual(z_pred), H

    # ------------------------------------------------------------------ reading
    def mean(self, state: Any) -> np.ndarray:
        return state.mean

    def covariance(self, state: Any) -> np.ndarray:
        return state.covariance

    def predicted_mean(self, state: Any) -> np.ndarray:
        """x⁻ of the last prediction (M, n)."""
        return state.predicted_mean

    def predicted_covariance(self, state: Any) -> np.ndarray:
        """P⁻ of the last prediction (M, n, n)."""
        return state.predicted_covariance

    def innovation(self, state: Any) -> Innovation | None:
        """ν, S, ℓ, NIS of the last update (None after a prediction)."""
        return state.innovation
