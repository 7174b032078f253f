"""Seed 001 Algorithm 1: an SPRT on a bank of 2n+1 filters re-created at each known switching moment (SPEC §4, §7).

At every known switching moment (the start of every schedule segment, the
first included) a bank of 2n+1 filters (straight, n left and n right turns
with radii r_min … r_max) is re-created from the current estimate (x̂, P),
each turn's ω and centre fixed from x̂ (SPEC §7); the detector (default
``sprt_pairwise``, rule (5)) eliminates hypotheses; until it decides the
estimate follows the ``follow`` rule; after the decision only the chosen
filter runs to the end of the segment (lines 14–16).

One implementation over R runs on one :class:`~hybridtrack.engine.bank.FilterBank`;
:meth:`KnownSwitchAdaptive.run` is the batch of one (step convention and recording: :mod:`.bank_runs`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import partial
from typing import Any

import attrs
import numpy as np

from hybridtrack.algorithms.bank_runs import run_alone, run_banks
from hybridtrack.algorithms.mode_sets import resolve_modes, turn_bank
from hybridtrack.algorithms.switch_state import SwitchAugmented, augmented_layout, augmented_prior
from hybridtrack.core.components import require
from hybridtrack.core.interfaces import Estimator, Sensor
from hybridtrack.core.plugins import resolve
from hybridtrack.core.protocols import HypothesisTest, HypothesisTestBatch
from hybridtrack.core.registry import Registry, registry_or_default
from hybridtrack.core.validation import check_positive
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.pipeline import mode_labels
from hybridtrack.engine.results import RunResult
from hybridtrack.engine.schedule import Schedule
from hybridtrack.sdk.mixtures import mixture
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import check_tau

__all__ = ["KnownSwitchAdaptive", "KnownSwitchRun", "SegmentOutcome", "turn_bank"]


@attrs.frozen
class SegmentOutcome:
    """One segment of Algorithm 1: the hypothesis followed at its end, its radius, when it was decided."""

    start: int
    steps: int
    mode: str
    index: int
    radius: float | None
    decision_step: int | None

    @property
    def delay(self) -> int | None:
        """Steps from the switching moment to the decision (None: undecided in the segment)."""
        return None if self.decision_step is None else self.decision_step - self.start


@attrs.frozen(eq=False, kw_only=True)
class KnownSwitchRun(RunResult):
    """Algorithm 1's output: ``modes`` the hypotheses, ``mode`` (K+1,) the hypothesis followed per step, the
    log-likelihood ratios per hypothesis (K+1, H; NaN when not in play), the per-segment outcomes and the
    thresholds A (``upper``), B (``lower``); ``hypothesis_positions`` (K+1, H, 2), kept only when the run is
    recorded: each hypothesis's filtered position from the switch (where every hypothesis starts at the
    followed estimate) until it is eliminated or decided, NaN elsewhere."""

    log_ratios: np.ndarray
    segments: tuple[SegmentOutcome, ...]
    upper: float
    lower: float
    hypothesis_positions: np.ndarray | None = None


def segment_lengths(segments: Schedule | Sequence[int]) -> list[int]:
    """The step counts of ``segments`` (a Schedule or step counts), each positive."""
    lengths = [s.steps for s in segments.segments] if isinstance(segments, Schedule) else [int(t) for t in segments]
    if not lengths or min(lengths) < 1:
        raise ValueError(f"segments: expected positive segment lengths, got {lengths}")
    return lengths


class KnownSwitchAdaptive:
    """Seed 001 Algorithm 1: SPRT on a re-created bank of 2n+1 filters at each known switching moment.

    ``modes`` overrides the bank (default :func:`turn_bank` (r_min, r_max, n,
    noise_cov)); ``detector`` is a fixed-bank detector exposing ``decided``
    and ``hypotheses`` (default ``sprt_pairwise`` with ``alpha``, ``beta``).

    The first bank is built from the given initial state (the prior mean x0),
    as Algorithm 1 does (x̂ := x0) and as the filter told the modes does: its
    turns' ω and centres come from x0, not from x0 updated with z_0.

    ``follow`` chooses the estimate before the decision in a segment:

    * ``"mixture"`` (default): the moment-matched mixture of the filters in
      play, weighted by their likelihood since the switch,
      w_i ∝ exp(L_{k,i}), L_{k,i} = Σ_{j=s+1}^{k} ℓ_{j,i} (ℓ the innovation
      log-likelihood, SPEC §4; equal prior probabilities):
      x̄ = Σ w_i x_i, P̄ = Σ w_i (P_i + (x_i − x̄)(x_i − x̄)ᵀ)
      (Bar-Shalom, Li & Kirubarajan 2001, §11.6, the mixture of a bank of
      model-matched filters).  A segment left undecided ends on the mixture,
      and the next segment's bank starts from it;
    * ``"most_likely"``: the filter î_k = argmax_{i in play} L_{k,i}, the
      maximum-likelihood hypothesis among those the SPRT has not dropped; an
      undecided segment ends on that filter;
    * ``"previous"`` (seed 001 Algorithm 1 line 9, kept to reproduce the
      seed): the filter of the hypothesis followed at the end of the previous
      segment (straight, index 0, in the first segment).

    ``switch_estimate`` chooses what fixes each hypothesis's transition:

    * ``"filtered"`` (default, the seed's): the transition is fixed from x̂_{s|s};
    * ``"joint"``: besides the hypothesis test's bank, an estimating bank whose
      filters carry the switch state in their state
      (:class:`~hybridtrack.algorithms.switch_state.SwitchAugmented`), so the
      turn's centre is refined by the segment's data (the smoothed switch state
      x̂_{s|k}) instead of staying at x̂_{s|s}; after the decision the chosen
      hypothesis also refines ω (EKF), mixed with the filter of fixed ω by
      their likelihoods since the decision.  The estimate comes from that bank.

    ``switch_inflation`` κ (default 4): the hypothesis test's bank starts from
    (x̂_s, κ P_s).  After a turn the estimate carries model error that P does
    not hold (ω and the centre came from an estimated switch state): its NEES
    at the next switch was measured at 2–6 times the expected 4 at R = 0.01,
    and an overconfident bank decides for a wrong hypothesis (a large-radius
    turn instead of a straight segment).  Inflating the covariance of a new
    mode's filters is the usual remedy at a manoeuvre onset (Bar-Shalom, Li &
    Kirubarajan 2001, §11.2, covariance reset at a detected manoeuvre); κ = 1
    is the seed's rule.

    The SPRT and its decisions are the same under every ``follow`` rule within
    a segment; the rule changes the estimate until the decision, and so the
    state the next segment's bank is created from.
    """

    FOLLOW = ("mixture", "most_likely", "previous")
    SWITCH_ESTIMATES = ("joint", "filtered")

    def __init__(
        self,
        *,
        sensors: SensorNetwork | Sequence[Sensor],
        tau: float | None = None,
        modes: Sequence[Any] | None = None,
        r_min: float = 1.0,
        r_max: float = 10.0,
        n: int = 10,
        noise_cov=None,
        estimator: Any = "kalman",
        detector: Any = None,
        alpha: float = 0.01,
        beta: float = 0.01,
        follow: str = "mixture",
        switch_estimate: str = "filtered",
        switch_inflation: float = 4.0,
        name: str = "known_switch",
        registry: Registry | None = None,
    ):
        if follow not in self.FOLLOW:
            raise ValueError(f"follow: expected one of {self.FOLLOW}, got {follow!r}")
        if switch_estimate not in self.SWITCH_ESTIMATES:
            raise ValueError(f"switch_estimate: expected one of {self.SWITCH_ESTIMATES}, got {switch_estimate!r}")
        self.follow = follow
        self.switch_estimate = switch_estimate
        self.switch_inflation = check_positive(switch_inflation, "switch_inflation")
        registry = registry_or_default(registry)
        self.models = resolve_modes(modes if modes is not None else turn_bank(r_min, r_max, n, noise_cov), registry)
        self.hypotheses = mode_labels(self.models)
        self.layout = self.models[0].layout
        joint = switch_estimate == "joint"
        self.bank_models = [SwitchAugmented(m) for m in self.models] if joint else self.models
        self.bank_layout = augmented_layout(self.layout) if joint else self.layout
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.tau = None if tau is None else check_tau(tau)
        self.estimator: Estimator = resolve("estimator", estimator, registry)
        spec = detector if detector is not None else ("sprt_pairwise", {"alpha": alpha, "beta": beta})
        needs = "detector (Algorithm 1 needs a test over a fixed bank, e.g. 'sprt_pairwise')"
        self.detector = require(resolve("detector", spec, registry), HypothesisTest, needs)
        self.name = name

    def run(
        self,
        measurements: Mapping[str, np.ndarray],
        prior,
        segments: Schedule | Sequence[int],
        *,
        times=None,
        recorder=None,
        truth=None,
    ) -> KnownSwitchRun:
        """Algorithm 1 over ``segments`` (step counts, or a Schedule) on measurements of steps 0 … K: the
        :meth:`run_batch` of one run.  ``times``: the K+1 measurement times in seconds (default 0, τ, 2τ, …)."""
        return run_alone(self, measurements, prior, segments, times=times, recorder=recorder, truth=truth)

    def run_batch(
        self,
        measurements: Mapping[str, np.ndarray],
        prior,
        segments: Schedule | Sequence[int],
        *,
        times=None,
        truth=None,
        recorders=None,
    ) -> list[KnownSwitchRun]:
        """Algorithm 1 on R runs at once, ``segments`` shared by the runs (the inputs and the recording as
        :func:`~hybridtrack.algorithms.bank_runs.run_banks` takes them).

        The R banks are one :class:`~hybridtrack.engine.bank.FilterBank`: the
        switch re-creates every run's bank, a run's decision keeps its chosen
        filter (index arrays through the estimator's ``take``), the detector
        runs as ``detector.batch(R)`` (vectorized for ``sprt_pairwise``).
        """
        return run_banks(self, partial(self._runs, segment_lengths(segments)), measurements, prior, times, truth, recorders)

    def _runs(self, lengths: list[int], z, t, dt, x0, P0, recorded: list[int]) -> list[KnownSwitchRun]:
        """Algorithm 1 over segments of ``lengths`` steps on the R runs of one bank (the rest as ``runs_of`` of
        :func:`~hybridtrack.algorithms.bank_runs.run_banks`)."""
        R, K = z.shape[0], sum(lengths)
        if z.shape[1] != K + 1:
            raise ValueError(f"measurements: expected {K + 1} steps (0 … {K}) for segments totalling {K}, got {z.shape[1]}")
        H, n = len(self.models), len(self.layout)
        joint = self.switch_estimate == "joint"
        means, covs = np.zeros((R, K + 1, n)), np.zeros((R, K + 1, n, n))
        followed = np.zeros((R, K + 1), dtype=int)
        ratios = np.full((R, K + 1, H), np.nan)
        # the SPRT's bank (transitions fixed at x̂_{s|s}) and, with the joint switch estimate, the estimating bank
        test = FilterBank(self.estimator, self.layout, self.network.sensors)
        estimate = FilterBank(self.estimator, self.bank_layout, self.network.sensors) if joint else test
        # Algorithm 1: x̂ := x0; the first bank's transitions come from the given initial state
        self._start(test, estimate, x0, P0, np.full(R, -1), inflation=1.0)
        test.step(None, z[:, 0])
        if joint:
            estimate.step(None, z[:, 0])
        first = test.offsets
        x, P = estimate.means[first, :n], estimate.covs[first, :n, :n]
        means[:, 0], covs[:, 0] = x, P
        position = [self.layout.index("x"), self.layout.index("y")]
        fans = {r: np.full((K + 1, H, 2), np.nan) for r in recorded}  # only the recorded runs keep them
        q, row = np.zeros(R, dtype=int), np.zeros(R, dtype=int)  # row −1: the estimate is not a filter of the bank
        outcomes, decisions = [[] for _ in range(R)], [[] for _ in range(R)]
        batch = self.detector.batch(R)
        if not isinstance(batch, HypothesisTestBatch):  # e.g. a change-time test on the fixed bank: its copies looped
            batch = HypothesisTestBatch(self.detector, R)
        k = 0
        for number, T in enumerate(lengths):
            if number:  # new banks at the switch, from the estimate followed at the end of the last segment
                self._start(test, estimate, x, P, row, inflation=self.switch_inflation)
            for r, fan in fans.items():  # every hypothesis starts at the followed estimate of the switch
                fan[k] = means[r, k, position]
            batch.reset(self.hypotheses)
            decision_step = np.full(R, -1)
            accumulated = np.zeros((R, H))  # L_i: log-likelihood since the switch (of the estimating bank)
            since = np.zeros((R, 2))  # after a decision: log-likelihood of the refined and the fixed filter
            for step in range(k + 1, k + T + 1):
                offsets = test.offsets
                scores = test.step(dt[:, step - 1], z[:, step])
                estimated = estimate.step(dt[:, step - 1], z[:, step]) if joint else scores
                row = np.zeros(R, dtype=int)
                open_ = np.flatnonzero(decision_step < 0)
                newly, mix = np.zeros(0, dtype=int), np.zeros(0, dtype=int)
                if open_.size:
                    idx = offsets[open_, None] + np.arange(H)
                    out = batch.observe(step, open_, scores.loglik[idx], scores.nis[idx], scores.m[offsets[open_]])
                    active = out.active > 0
                    ratios[open_, step] = np.where(active, out.log_ratio, np.nan)
                    accumulated[open_] += estimated.loglik[idx]
                    chosen = q[open_]
                    if self.follow != "previous":
                        best = np.argmax(np.where(active, accumulated[open_], -np.inf), axis=1)
                        chosen = np.where(active.any(axis=1), best, chosen)
                    done = out.decided >= 0
                    chosen = np.where(done, out.decided, chosen)
                    q[open_], row[open_] = chosen, chosen
                    newly = open_[done]
                    decision_step[newly] = step
                    ratios[newly, step, q[newly]] = out.log_ratio[done, q[newly]]
                    for u in np.flatnonzero(done):
                        decisions[open_[u]].append(attrs.evolve(out.decisions[u], time=float(t[open_[u], step])))
                    for u in np.flatnonzero(np.isin(open_, recorded)):  # the hypotheses in play (and the one just decided)
                        shown = active[u].copy()
                        shown[q[open_[u]]] |= bool(done[u])
                        fans[open_[u]][step] = np.where(shown[:, None], estimate.means[idx[u]][:, position], np.nan)
                    if self.follow == "mixture":  # w_i ∝ exp(L_i) over the hypotheses in play
                        pick = ~done & active.any(axis=1)
                        mix = open_[pick]
                        if mix.size:
                            sub = idx[pick]
                            weights = np.where(active[pick], accumulated[mix], -np.inf)
                            x_mix, P_mix = mixture(weights, estimate.means[sub][..., :n], estimate.covs[sub][..., :n, :n])
                chosen_rows = offsets + row
                x, P = estimate.means[chosen_rows, :n].copy(), estimate.covs[chosen_rows, :n, :n].copy()
                if mix.size:
                    x[mix], P[mix] = x_mix, P_mix
                    row[mix] = -1  # the next bank (if the segment ends undecided) starts from the mixture
                if joint:
                    # after the decision: the chosen hypothesis with its switch state refined (EKF) and with it fixed
                    # at x̂_{s|s}, weighted by their likelihood since the decision (the refinement is kept while the
                    # data support it)
                    after = np.flatnonzero((decision_step >= 0) & (decision_step < step))
                    if after.size:
                        rows = offsets[after]
                        since[after] += np.stack([estimated.loglik[rows], scores.loglik[rows]], axis=1)
                        x[after], P[after] = mixture(
                            since[after],
                            np.stack([estimate.means[rows, :n], test.means[rows]], axis=1),
                            np.stack([estimate.covs[rows, :n, :n], test.covs[rows]], axis=1),
                        )
                        row[after] = -1
                if newly.size:  # the decided runs keep only the chosen filter
                    keep = np.ones(len(test), dtype=bool)
                    keep[(offsets[newly, None] + np.arange(H)).reshape(-1)] = False
                    keep[offsets[newly] + q[newly]] = True
                    test.take(np.flatnonzero(keep))
                    if joint:  # the chosen hypothesis refines ω and the centre with the switch estimate (EKF)
                        estimate.take(np.flatnonzero(keep))
                        rows = estimate.offsets[newly]
                        refined = [SwitchAugmented(self.models[i], relinearize=True) for i in q[newly]]
                        estimate.assign(rows, refined, estimate.switch_states[rows])
                        since[newly] = 0.0
                    row[newly] = 0
                means[:, step], covs[:, step], followed[:, step] = x, P, q
            for r in range(R):
                decided_at = None if decision_step[r] < 0 else int(decision_step[r])
                outcomes[r].append(SegmentOutcome(k, T, self.hypotheses[q[r]], int(q[r]), self.models[q[r]].radius, decided_at))
            k += T
        return [
            KnownSwitchRun(
                layout=self.layout,
                modes=self.hypotheses,
                times=t[r],
                means=means[r],
                covs=covs[r],
                mode=followed[r],
                decisions=tuple(decisions[r]),
                log_ratios=ratios[r],
                segments=tuple(outcomes[r]),
                upper=float(batch.upper),
                lower=float(batch.lower),
                hypothesis_positions=fans.get(r),
            )
            for r in range(R)
        ]

    def _start(self, test: FilterBank, estimate: FilterBank, x: np.ndarray, P: np.ndarray, row: np.ndarray, inflation: float) -> None:
        """Every hypothesis of every run from its estimate (x (R, n), P (R, n, n)) at the switch, its transition
        fixed there (the SPRT's bank) and, with the joint switch estimate, started there with the switch state
        carried (the estimating bank, N(augmented_prior(x, P))).

        The SPRT's bank starts from (x, κ P), κ = ``inflation`` (1 for the first
        bank, which starts from the given prior, not a switch estimate); with
        κ = 1 a run whose estimate is its filter ``row`` (≥ 0) copies that filter
        in its own state form (factors propagated, no re-initialization).
        """
        H, R = len(self.models), x.shape[0]
        every = np.repeat(np.arange(R), H)
        copied = np.flatnonzero(row >= 0) if inflation == 1 and estimate is test else np.zeros(0, dtype=int)
        started = np.setdiff1d(np.arange(R), copied)
        parts = []
        if copied.size:
            parts.append(self.estimator.take(test.state, np.repeat(test.offsets[copied] + row[copied], H)))
        if started.size:
            parts.append(self.estimator.initialize(np.repeat(x[started], H, axis=0), np.repeat(inflation * P[started], H, axis=0)))
        state = parts[0]
        if len(parts) > 1:  # the copied runs, then the started ones: back to run order
            position = np.empty(R, dtype=int)
            position[np.concatenate([copied, started])] = np.arange(R)
            state = self.estimator.take(self.estimator.concatenate(parts), (position[:, None] * H + np.arange(H)).reshape(-1))
        test.set(state, self.models * R, np.repeat(x, H, axis=0), every)
        if estimate is not test:
            prior = [augmented_prior(x[r], P[r]) for r in range(R)]
            mean = np.repeat(np.stack([p[0] for p in prior]), H, axis=0)
            estimate.start(mean, np.repeat(np.stack([p[1] for p in prior]), H, axis=0), self.bank_models * R, mean, every)
