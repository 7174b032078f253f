"""Pairwise SPRT with elimination over a fixed bank (seed 001 §3, rule (5); SPEC §4 "SPRT, known switching moments").

Filters F_0 … F_{M−1} run on the same data from a known switching moment.
With ℓ_{k,i} the innovation log-likelihood of filter i at step k, the pairwise
log-likelihood ratio

    λ_{k,ij} = λ_{k−1,ij} + μ_{k,ij},
    2μ_{k,ij} = ln det S_j − ln det S_i + ν_jᵀS_j⁻¹ν_j − ν_iᵀS_i⁻¹ν_i   (seed 001 eq. 4)

is μ_{k,ij} = ℓ_{k,i} − ℓ_{k,j}, so λ_{k,ij} = L_i − L_j with L_i = Σ ℓ_i since
the start (λ_0 = 0).  Thresholds A = ln((1−β)/α) (``upper``), B = ln(β/(1−α))
(``lower``).  Rule (5), applied to the hypotheses still in play:

* λ_ij ≤ B for some j: H_i is dropped (vectorized: L_i − max_j L_j ≤ B);
* λ_ij ≥ A for every other j in play: H_i is accepted;
* one hypothesis left: it is accepted.

The leader is never dropped (its λ against everyone is ≥ 0 > B), so the test
always ends with exactly one hypothesis.  After the decision the detector
keeps reporting the final values and takes no further decision until
``reset()``.

Statistics: ``log_ratio`` (M,) = L_i − max_{j≠i in play} L_j (the leader's margin
over the runner-up, negative for the others; frozen when a hypothesis is
dropped) and ``active`` (M,) 1/0 (all 0 once decided; the accepted hypothesis keeps its
final margin over the best of the others).
"""

from __future__ import annotations

from collections.abc import Sequence
from types import SimpleNamespace

import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import DetectorStep
from hybridtrack.core.protocols import BatchStep, HypothesisTest, HypothesisTestBatch
from hybridtrack.core.types import Decision
from hybridtrack.sdk.thresholds import WaldThresholds


def batch_margins(L: np.ndarray, active: np.ndarray) -> np.ndarray:
    """L_i − max_{j ≠ i, j active} L_j for every i of every row of L (U, H) with its row of ``active`` (U, H)
    (all j when fewer than two are active).  The leader's margin is over the runner-up, the others' over the leader;
    ties give the same values whichever tied filter is taken as the leader.
    """
    U, H = L.shape
    if H < 2:
        return np.zeros_like(L)
    pool = np.where(active.sum(axis=1, keepdims=True) >= 2, active, True)
    masked = np.where(pool, L, -np.inf)
    lead = np.argmax(masked, axis=1)
    rows = np.arange(U)
    best = masked[rows, lead]
    masked[rows, lead] = -np.inf
    second = masked.max(axis=1)
    rival = np.where(np.arange(H) == lead[:, None], second[:, None], best[:, None])
    return L - rival


def observe_tests(step, test, state, runs, loglik, measured, label: str):
    """One step of rule (5) for the tests ``runs`` (U,) of ``state`` (the attributes L, active, frozen (R, H) and
    decided (R,), −1 while undecided; filled on first use) with ℓ (U, H) and ``measured`` (U,); ``test`` gives
    the hypotheses' names and the thresholds.  Returns the reported log_ratio (U, H) (the margins, frozen for
    the dropped and the decided), active (U, H), the hypothesis accepted this step (U,) (−1: none) and the
    Decisions."""
    U, H = loglik.shape
    if state.L is None:
        R = len(state.decided)
        state.L, state.active, state.frozen = np.zeros((R, H)), np.ones((R, H), dtype=bool), np.zeros((R, H))
    if state.L.shape[1] != H:
        raise ValueError(f"loglik: the bank changed from {state.L.shape[1]} to {H} filters; call reset() first")
    if test.hypotheses is not None and len(test.hypotheses) != H:
        raise ValueError(f"hypotheses: {len(test.hypotheses)} names for a bank of {H} filters")
    live, L, active, frozen = state.decided[runs] < 0, state.L[runs], state.active[runs], state.frozen[runs]
    L = np.where((live & measured)[:, None], L + loglik, L)
    ratio = batch_margins(L, active)
    dropped = live[:, None] & active & (ratio <= test.lower)
    frozen = np.where(dropped, ratio, frozen)
    active = active & ~dropped
    ratio = batch_margins(L, active)
    winners = live[:, None] & active & (ratio >= test.upper)
    count = active.sum(axis=1)
    deciding = live & ((count == 1) | winners.any(axis=1))
    chosen = np.where(count == 1, np.argmax(active, axis=1), np.argmax(np.where(winners, ratio, -np.inf), axis=1))
    chosen = np.where(deciding, chosen, -1)
    rows = np.flatnonzero(deciding)
    if rows.size:  # the accepted hypothesis keeps its margin over the best of all the others
        frozen[rows, chosen[rows]] = batch_margins(L[rows], np.ones((rows.size, H), dtype=bool))[np.arange(rows.size), chosen[rows]]
        active[rows] = False
    out = np.where(active, batch_margins(L, active), frozen)
    state.L[runs], state.active[runs], state.frozen[runs] = L, active, frozen
    decisions = [None] * U
    for u in np.flatnonzero(chosen >= 0):
        i = state.decided[runs[u]] = int(chosen[u])
        name = test.hypotheses[i] if test.hypotheses is not None and i < len(test.hypotheses) else f"H{i}"
        decisions[u] = Decision(
            step, label, name, float(ratio[u, i]), f"{name} accepted with margin {ratio[u, i]:.2f} (A = {test.upper:.2f})"
        )
    return out, active.astype(float), chosen, decisions


class PairwiseSPRTBatch(HypothesisTestBatch):
    """R copies of :class:`PairwiseSPRT` as arrays (U runs per step vectorized): L, in-play and frozen values (R, H)."""

    def __init__(self, detector: PairwiseSPRT, runs: int):
        self.detector = detector
        self.runs = int(runs)
        self.upper, self.lower = detector.upper, detector.lower
        self.reset(detector.hypotheses)

    def reset(self, hypotheses) -> None:
        self.hypotheses = hypotheses
        self.L = self.active = self.frozen = None
        self.decided = np.full(self.runs, -1)

    def observe(self, step, runs, loglik, nis, m) -> BatchStep:
        runs = np.asarray(runs, dtype=int)
        out = observe_tests(step, self, self, runs, np.asarray(loglik, dtype=float), np.asarray(m) > 0, self.detector.label)
        return BatchStep(out[0], out[1], out[2], tuple(out[3]))


class PairwiseSPRT(WaldThresholds, HypothesisTest):
    """SPRT with pairwise log-likelihood ratios and elimination over a fixed bank (seed 001, rule (5))."""

    name = "sprt_pairwise"

    def __init__(self, alpha: float = 0.01, beta: float = 0.01, hypotheses: Sequence[str] | None = None):
        self.set_error_probabilities(alpha, beta)
        self.hypotheses = None if hypotheses is None else tuple(str(h) for h in hypotheses)
        if self.hypotheses is not None and not self.hypotheses:
            raise ValueError("hypotheses: expected at least one hypothesis name")
        self.reset()

    def reset(self) -> None:
        self.decided: int | None = None
        self._state = SimpleNamespace(L=None, active=None, frozen=None, decided=np.full(1, -1))  # a batch of one

    def observe(self, step, loglik, nis, m) -> DetectorStep:
        loglik = np.atleast_1d(np.asarray(loglik, dtype=float))
        self._state.decided[0] = -1 if self.decided is None else self.decided
        ratio, active, chosen, decisions = observe_tests(
            step, self, self._state, np.zeros(1, dtype=int), loglik[None], np.array([m > 0]), self.label
        )
        if chosen[0] >= 0:
            self.decided = int(chosen[0])
        return DetectorStep({"log_ratio": ratio[0], "active": active[0]}, {"upper": self.upper, "lower": self.lower}, decisions[0])

    def batch(self, runs: int) -> PairwiseSPRTBatch:
        """``runs`` copies of this test vectorized over the runs (each equal to a copy of this test)."""
        return PairwiseSPRTBatch(self, runs)


@hookimpl
def register_detectors(registry):
    registry.add(PairwiseSPRT.name, PairwiseSPRT)
