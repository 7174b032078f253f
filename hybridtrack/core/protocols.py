"""The protocols the algorithms call on top of the five interfaces (:mod:`hybridtrack.core.interfaces`).

* :class:`ScoreDetector` — a detector reading only the per-filter scores ℓ and
  NIS (so it also runs on the scores a node of a decentralized filter computes);
* :class:`HypothesisTest` — the sequential test of Algorithm 1 (known switch
  times) over a fixed bank, and :class:`ChangeTimeTest`, the test of
  Algorithm 3 (unknown change time) over a growing bank;
* their batches (``batch_class``, built by :meth:`~hybridtrack.core.interfaces.Detector.batch`,
  the one batching protocol of every detector): R independent copies fed
  together, looped by default, vectorized where a class overrides ``batch``;
* :class:`Association` and :class:`ClutterInnovation` — what a clutter-aware
  update did with each scan.

:func:`~hybridtrack.core.components.require` checks that a component
implements one of these.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from hybridtrack.core.interfaces import Detector, DetectorBatch, DetectorStep, Innovation

# --------------------------------------------------------------------------- clutter associations


@attrs.frozen(eq=False)
class Association:
    """What one clutter-aware update of a bank did with one sensor's scan (SPEC §6).

    ``candidates`` (L, m); ``predicted`` ẑ (M, m); ``S`` (M, m, m); ``gate`` γ;
    ``distances`` d² (M, L); ``gated`` (M, L) bool; ``weights`` β_i (M, L)
    (nearest neighbour: 1 for the chosen candidate); ``missed`` β_0 (M,)
    (nearest neighbour: 1 when nothing was gated); ``selected`` (M,) the chosen
    (NN) or most probable (PDA) candidate, −1 for none; ``loglik`` (M,)
    ln Λ (PDA) or the Gaussian ℓ of the chosen candidate (NN, NaN when none).
    """

    sensor: str
    candidates: np.ndarray
    predicted: np.ndarray
    S: np.ndarray
    gate: float
    distances: np.ndarray
    gated: np.ndarray
    weights: np.ndarray
    missed: np.ndarray
    selected: np.ndarray
    loglik: np.ndarray

    #: the fields with one entry per filter of the bank (the others describe the scan)
    PER_FILTER: ClassVar[tuple[str, ...]] = ("predicted", "S", "distances", "gated", "weights", "missed", "selected", "loglik")

    def take(self, rows: np.ndarray) -> Association:
        """The association of the filters ``rows`` of the bank (the scan's fields kept)."""
        return attrs.evolve(self, **{name: np.asarray(getattr(self, name))[rows] for name in self.PER_FILTER})


@attrs.frozen(eq=False)
class ClutterInnovation(Innovation):
    """An :class:`Innovation` of a clutter-aware update plus its :class:`Association` per scan.

    ``nu`` is the innovation the update used: the combined ν = Σ β_i ν_i (PDA)
    or the chosen candidate's (NN; 0 for a filter with nothing gated); S, ℓ and
    NIS go with it as in every Innovation.  ``association_loglik`` (M,) sums
    ln Λ over the scans of the step (0 when no scan was processed).  The
    pipeline records gates and weights from ``associations``.
    """

    associations: tuple[Association, ...] = ()

    def take(self, rows: np.ndarray, bank_size: int) -> ClutterInnovation:
        """:meth:`Innovation.take`, with each association cut to the filters ``rows``."""
        return attrs.evolve(super().take(rows, bank_size), associations=tuple(a.take(rows) for a in self.associations))

    @property
    def association_loglik(self) -> np.ndarray:
        if not self.associations:
            return np.zeros(self.nu.shape[0])
        return np.sum([a.loglik for a in self.associations], axis=0)


# --------------------------------------------------------------------------- detectors the algorithms call


class ScoreDetectorBatch(DetectorBatch):
    """R copies of one :class:`ScoreDetector` fed their scores: ``observe(step, runs, loglik (U, M), nis (U, M), m)``
    (m shared: the runs of one call measured the same components) returns one DetectorStep per run, each equal to
    ``copies[r].observe(step, loglik[u], nis[u], m)``; :meth:`step` hands it the innovation's scores (when the
    class keeps ScoreDetector's ``step``; otherwise the copies are stepped one by one)."""

    def step(self, step: int, runs: Sequence[int], innovation: Innovation) -> list[DetectorStep]:
        if type(self.detector).step is not ScoreDetector.step:
            return super().step(step, runs, innovation)
        U = len(runs)
        loglik = np.asarray(innovation.loglik, dtype=float).reshape(U, -1)
        nis = np.asarray(innovation.nis, dtype=float).reshape(U, -1)
        return self.observe(step, runs, loglik, nis, innovation.measurement_dim)

    def observe(self, step: int, runs: Sequence[int], loglik: np.ndarray, nis: np.ndarray, m: int) -> list[DetectorStep]:
        return [self.copies[int(r)].observe(step, loglik[u], nis[u], m) for u, r in enumerate(runs)]


class ScoreDetector(Detector):
    """A detector that reads only per-filter scores: ℓ (M,), NIS (M,) and m.

    ``observe(step, loglik, nis, m)`` is the entry point; ``step`` calls it
    with the innovation's scores.  The same detector then runs on the scores
    a node of a decentralized filter computes locally
    (:meth:`Estimator.node_scores`), so the adaptive estimators run one copy
    per node.
    """

    batch_class = ScoreDetectorBatch

    def step(self, step: int, innovation: Innovation) -> DetectorStep:
        return self.observe(step, np.asarray(innovation.loglik, float), np.asarray(innovation.nis, float), innovation.measurement_dim)

    @abstractmethod
    def observe(self, step: int, loglik: np.ndarray, nis: np.ndarray, m: int) -> DetectorStep:
        """Consume one step's scores: ℓ (M,), NIS (M,), m (0 = no measurement this step)."""


@attrs.frozen(eq=False)
class BatchStep:
    """One step of a :class:`HypothesisTestBatch` for the U runs observed: ``log_ratio`` (U, H), ``active``
    (U, H) (1 for the hypotheses in play), ``decided`` (U,) the accepted hypothesis or −1, ``decisions`` (U,)
    the step's Decision of each run or None."""

    log_ratio: np.ndarray
    active: np.ndarray
    decided: np.ndarray
    decisions: tuple


class HypothesisTestBatch(DetectorBatch):
    """R independent copies of one :class:`HypothesisTest` over banks of H hypotheses (the batch contract).

    ``reset(hypotheses)`` starts every copy anew (a switching moment of all
    runs); ``observe(step, runs, loglik (U, H), nis (U, H), m (U,))`` feeds the
    runs ``runs`` (indices into 0 … R−1) and returns a :class:`BatchStep`; each
    copy sees exactly what ``observe(step, loglik[u], nis[u], m[u])`` of a
    single test would.  This default keeps deep copies and loops over them (the
    fallback for tests without a vectorized batch).
    """

    def __init__(self, detector: HypothesisTest, runs: int):
        super().__init__(detector, runs)
        self.upper, self.lower = detector.upper, detector.lower

    def reset(self, hypotheses: tuple[str, ...] | None) -> None:
        for c in self.copies:
            c.hypotheses = hypotheses
            c.reset()

    def observe(self, step: int, runs: np.ndarray, loglik: np.ndarray, nis: np.ndarray, m: np.ndarray) -> BatchStep:
        runs = np.asarray(runs, dtype=int)
        U, H = np.shape(loglik)
        ratio, active, decided, decisions = np.zeros((U, H)), np.zeros((U, H)), np.full(U, -1), []
        for u, r in enumerate(runs):
            out = self.copies[r].observe(step, loglik[u], nis[u], int(m[u]))
            ratio[u] = out.statistics["log_ratio"]
            active[u] = np.asarray(out.statistics.get("active", np.ones(H)), dtype=float)
            if out.decision is not None:
                decided[u] = int(self.copies[r].decided)
            decisions.append(out.decision)
        return BatchStep(ratio, active, decided, tuple(decisions))


class HypothesisTest(ScoreDetector):
    """A sequential test between the hypotheses of a fixed bank (seed 001 Algorithm 1 drives one).

    Declared attributes, read and set by the driver:

    * ``hypotheses`` (tuple of names, one per filter, or None) — set before
      :meth:`reset` at every switching moment;
    * ``decided`` — index of the accepted hypothesis once the test has
      decided (the step's ``DetectorStep.decision`` is set then), else None;
    * ``upper``, ``lower`` — the thresholds A and B (recorded beside ln λ).

    ``observe`` reports ``statistics["log_ratio"]`` (M,) and may report
    ``statistics["active"]`` (M,), 1 for the hypotheses still in play.
    """

    batch_class = HypothesisTestBatch
    declared_attributes: ClassVar[tuple[str, ...]] = ("hypotheses", "decided", "upper", "lower")
    hypotheses: tuple[str, ...] | None = None
    decided: int | None = None
    upper: float
    lower: float


@attrs.frozen(eq=False)
class ChangeTimeStep:
    """One step of a :class:`ChangeTimeTestBatch` for all R runs: ``log_ratio`` (R, P) ln λ_p; ``decided`` (R,)
    −1 (continue), 0 (no change: the run's test restarted) or the alternative p ≥ 1; ``chosen_entry`` (R,) the
    entry followed after a change (index among the run's entries, −1 otherwise) and ``chosen_start`` (R,) its
    change step; ``decisions`` (R,) the step's Decision or None."""

    log_ratio: np.ndarray
    decided: np.ndarray
    chosen_entry: np.ndarray
    chosen_start: np.ndarray
    decisions: tuple


class ChangeTimeTestBatch(DetectorBatch):
    """R independent copies of one :class:`ChangeTimeTest` (the batch contract of Algorithm 3's test).

    The entries of all runs form one flat sequence, run by run (the rows of the
    runs' stacked banks without each run's filter 0).  ``restart(runs,
    hypotheses)`` resets those runs' tests with new hypothesis names (one tuple
    per run); ``add(start)`` appends, in every run, one entry per alternative
    1 … P hypothesising the change at ``start``; ``observe(step, loglik0 (R,),
    loglik (E,), nis0 (R,), nis (E,), m (R,))`` feeds filter 0's and the
    entries' scores and returns a :class:`ChangeTimeStep`; ``prune(runs,
    caps)`` bounds the entries of ``runs`` (cap −1: the test's own
    ``bank_size``) by the pruning rule and returns the kept mask over the
    entries (E,); ``counts`` (R,) entries per run.  Each copy sees what a
    single test would.  This default keeps deep copies and loops over them.
    """

    def __init__(self, detector: ChangeTimeTest, runs: int):
        super().__init__(detector, runs)
        self.upper, self.lower, self.pruning = detector.upper, detector.lower, detector.pruning

    @property
    def counts(self) -> np.ndarray:
        return np.array([c.starts.size for c in self.copies], dtype=int)

    def restart(self, runs: Sequence[int], hypotheses: Sequence[tuple[str, ...]]) -> None:
        for r, names in zip(runs, hypotheses):
            self.copies[r].hypotheses = tuple(names)
            self.copies[r].reset()

    def add(self, start: int) -> None:
        for c in self.copies:
            c.add(np.arange(1, len(c.hypotheses)), start)

    def observe(self, step: int, loglik0, loglik, nis0, nis, m) -> ChangeTimeStep:
        counts = self.counts
        ends = np.cumsum(counts)
        ratios, decided, entry, start, decisions = [], np.full(self.runs, -1), np.full(self.runs, -1), np.full(self.runs, -1), []
        for r, c in enumerate(self.copies):
            block = slice(ends[r] - counts[r], ends[r])
            out = c.observe(step, np.concatenate([[loglik0[r]], loglik[block]]), np.concatenate([[nis0[r]], nis[block]]), int(m[r]))
            ratios.append(np.asarray(out.statistics["log_ratio"], dtype=float))
            decisions.append(out.decision)
            if out.decision is not None:
                decided[r] = int(c.decided or 0)
                if c.decided:
                    entry[r] = int(c.chosen_entry)
                    start[r] = int(c.starts[entry[r]])
        return ChangeTimeStep(np.stack(ratios), decided, entry, start, tuple(decisions))

    def prune(self, runs: Sequence[int], caps: Sequence[int]) -> np.ndarray:
        keep = [np.ones(c.starts.size, dtype=bool) for c in self.copies]
        for r, cap in zip(runs, caps):
            rows = self.copies[r].prune(None if cap < 0 else int(cap))
            keep[r] = np.zeros(keep[r].size, dtype=bool)
            keep[r][rows] = True
        return np.concatenate(keep) if keep else np.zeros(0, dtype=bool)


class ChangeTimeTest(HypothesisTest):
    """A test for a change at an unknown time over a growing bank (seed 000 Algorithm 3 drives one).

    Row 0 of the bank is the current mode; the driver starts one filter per
    alternative at every step and tells the test with :meth:`add`; rows
    1 … E of each innovation are those entries in the order added.

    Besides :class:`HypothesisTest`'s attributes (``hypotheses[0]`` is the
    current mode; ``decided`` is the alternative p ≥ 1 on a change, 0 on "no
    change"): ``alpha``, ``beta`` (error probabilities), ``pruning`` (one of
    :data:`PRUNING_RULES`), ``starts`` (E,) the change step of each entry,
    ``chosen_entry`` (the entry followed after a change).
    """

    batch_class = ChangeTimeTestBatch
    PRUNING_RULES: ClassVar[tuple[str, ...]] = ("oldest", "nearest_lower")
    declared_attributes: ClassVar[tuple[str, ...]] = HypothesisTest.declared_attributes + (
        "alpha",
        "beta",
        "pruning",
        "starts",
        "chosen_entry",
    )
    alpha: float
    beta: float
    pruning: str
    starts: np.ndarray
    chosen_entry: int | None = None

    @abstractmethod
    def add(self, modes: Sequence[int], start: int) -> None:
        """Append one entry per alternative in ``modes`` (1 … M−1) hypothesising the change at ``start``."""

    @abstractmethod
    def keep(self, rows: Sequence[int]) -> None:
        """Keep only the entries ``rows`` (indices into the entries, in order)."""

    @abstractmethod
    def prune(self, bank_size: int | None = None) -> np.ndarray:
        """Bound the entries to ``bank_size`` by the pruning rule; return the entry rows kept."""

    @abstractmethod
    def log_ratios(self) -> np.ndarray:
        """ln λ_p for each alternative p = 1 … M−1."""
