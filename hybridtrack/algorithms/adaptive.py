"""Adaptive estimation: the estimate follows the filter of the identified motion mode (SPEC §4, §7).

Two drivers compose registered plugins — motion models, an estimator, a
detector — around a :class:`~hybridtrack.engine.bank.FilterBank` whose membership
changes over time, which a fixed-bank :class:`~hybridtrack.engine.pipeline.Pipeline`
cannot express:

* :class:`KnownSwitchAdaptive` — seed 001 Algorithm 1.  At every known
  switching moment (the start of every schedule segment, the first included)
  a bank of 2n+1 filters (straight, n left and n right turns with radii
  r_min … r_max) is re-created from the current estimate (x̂, P), each turn's
  ω and centre fixed from x̂ (SPEC §7); the detector (default
  ``sprt_pairwise``, rule (5)) eliminates hypotheses; until it decides the
  estimate follows the filter of the previously chosen hypothesis (seed 001
  line 9, ``follow="previous"``) or, with ``follow="most_likely"``, the
  hypothesis still in play with the largest accumulated log-likelihood
  L_i = Σ ℓ_i since the switch (the leader of the pairwise test); after the
  decision only the chosen filter runs to the end of the segment (lines 14–16).
* :class:`UnknownChangeAdaptive` — seed 000 Algorithm 3 repeated.  Filter 0
  runs the current mode; at every step one filter per alternative mode is
  started from filter 0's estimate, hypothesising the change there; the
  detector (default ``sprt_unknown_change``) averages the ratios over change
  times and applies rule (24).  A change to p makes the most likely filter of
  p the new filter 0 (the estimate follows it) and restarts the test; "no
  change" (every ln λ ≤ B) restarts the test with filter 0 alone.  The bank is
  bounded by ``bank_size`` alternative filters, pruned by the detector's rule
  (``"oldest"`` or seed 003's ``"nearest_lower"``), or by Algorithm 4's
  estimate (``bank_size="algorithm4"``, oldest first).

Step convention (as the Pipeline): step 0 updates the prior with z_0; step
k ≥ 1 predicts over Δt_k = t_k − t_{k−1} and updates.  ``run`` takes the
measurement ``times`` (seconds, strictly increasing, any spacing) or uses
``tau`` for regular sampling; each step's transitions are built for its Δt.
The bank keeps the estimator's own state form between steps
(:class:`~hybridtrack.engine.bank.FilterBank`).  With the ``decentralized`` estimator every node's
locally computed ℓ and NIS (seed 000 eq. 22) feed node copies of the detector
and of the signal function, recorded beside the centralized values.

Recording (through the recorder passed in): ``world/estimate/<name>``, the bank's
hypotheses ``world/estimate/<name>/hypotheses/<h>`` while in play (each from its switch),
``detector/<detector>/log_ratio/<mode>`` with ``…/upper`` and ``…/lower``,
``detector/signal_function/signal`` with ±bounds, ``estimator/<name>/bank_size``
and the decisions as events.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.algorithms.algorithm4 import algorithm4_bank_size, wald_pair
from hybridtrack.algorithms.switch_state import SwitchAugmented, augmented_layout, augmented_prior
from hybridtrack.core.components import require
from hybridtrack.core.interfaces import Estimator, MotionModel, Sensor
from hybridtrack.core.plugins import resolve, resolve_registry
from hybridtrack.core.protocols import ChangeTimeTest, HypothesisTest, ScoreDetector
from hybridtrack.core.registry import Registry
from hybridtrack.core.types import Decision, Gaussian, Schedule
from hybridtrack.core.validation import check_positive, check_positive_int
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.pipeline import mode_labels
from hybridtrack.engine.run_bank import RunBank, batch_measurements, batch_prior, batch_times, batchable, check_recorders, per_run
from hybridtrack.recording import decision_text, log_estimate, log_measurements
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import check_tau, step_intervals

# --------------------------------------------------------------------------- composition helpers


def turn_bank(r_min: float = 1.0, r_max: float = 10.0, n: int = 10, noise_cov=None) -> list[tuple[str, dict]]:
    """The 2n+1 hypotheses of seed 001 §3: straight, left turns r_1 … r_n, right turns r_1 … r_n.

    Radii r_i = r_min + (i − 1)(r_max − r_min)/(n − 1) (n = 1: r_min alone, which must equal r_max).
    """
    n = check_positive_int(n, "n")
    r_min, r_max = float(r_min), float(r_max)
    if not (np.isfinite(r_min) and r_min > 0):
        raise ValueError(f"r_min: expected a positive radius, got {r_min!r}")
    if not np.isfinite(r_max) or r_min > r_max:
        raise ValueError(f"r_min, r_max: expected 0 < r_min ≤ r_max, got r_min = {r_min}, r_max = {r_max}")
    if n == 1 and r_min != r_max:
        raise ValueError(f"n: one radius needs r_min = r_max, got r_min = {r_min}, r_max = {r_max}")
    extra = {} if noise_cov is None else {"noise_cov": noise_cov}
    radii = np.linspace(r_min, r_max, n)
    return (
        [("straight", dict(extra))]
        + [("left_turn", {"radius": float(r), **extra}) for r in radii]
        + [("right_turn", {"radius": float(r), **extra}) for r in radii]
    )


def _models(modes, registry) -> list[MotionModel]:
    models = [resolve("motion_model", m, registry) for m in modes]
    if not models:
        raise ValueError("modes: expected at least one motion mode, got an empty set")
    layouts = {m.layout for m in models}
    if len(layouts) != 1:
        raise ValueError(f"modes: every mode must share one state layout, got {sorted(layouts)}")
    return models


def _prior(prior) -> Gaussian:
    return prior if isinstance(prior, Gaussian) else Gaussian(*prior)


def _record_run(recorder, adaptive, z: np.ndarray, run, hypotheses: Sequence[str], truth) -> tuple[np.ndarray, np.ndarray]:
    """What every adaptive run records: the truth (if given), the measurements, the selected estimate with
    its 2σ ellipses, each hypothesis's estimate while in play (``…/hypotheses/<h>``, NaN gaps), ln λ per hypothesis with A (``upper``) and B (``lower``), and the decisions.
    Returns the steps and times for the caller's own series."""
    steps = np.arange(run.means.shape[0])
    times = run.times
    if truth is not None:
        recorder.log_path("world/truth", steps, truth.positions[: steps.size], times)
    network = adaptive.network
    log_measurements(recorder, network.sensors, network.split(z[: steps.size]), steps, times)
    position = [adaptive.layout.index("x"), adaptive.layout.index("y")]
    log_estimate(recorder, adaptive.name, steps, run.means, run.covs, position, times)
    if run.hypothesis_positions is not None:  # the bank's hypotheses fanning out of each switch, each in its colour
        for j, name in enumerate(hypotheses):
            path = run.hypothesis_positions[:, j]
            if np.isfinite(path).any():
                recorder.log_path(f"world/estimate/{adaptive.name}/hypotheses/{name}", steps, path, times)
    base = f"detector/{adaptive.detector.label}"
    _log_columns(recorder, f"{base}/log_ratio", steps, run.log_ratios, hypotheses, times)
    recorder.log_scalars(f"{base}/upper", steps, np.full(steps.size, run.upper), times)
    recorder.log_scalars(f"{base}/lower", steps, np.full(steps.size, run.lower), times)
    for d in run.decisions:
        recorder.log_event(d.step, decision_text(d), d.time)
    return steps, times


def _mixture(means: np.ndarray, covs: np.ndarray, loglik: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moment-matched mixture of Gaussians N(x_i, P_i) with weights w_i ∝ exp(L_i) (log-sum-exp, no underflow).

    x̄ = Σ w_i x_i,  P̄ = Σ w_i (P_i + (x_i − x̄)(x_i − x̄)ᵀ).
    """
    w = np.exp(loglik - loglik.max())
    w /= w.sum()
    x = w @ means
    d = means - x
    P = np.einsum("i,ijk->jk", w, covs) + np.einsum("i,ij,ik->jk", w, d, d)
    return x, 0.5 * (P + P.T)


def _mixtures(means: np.ndarray, covs: np.ndarray, loglik: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_mixture` of each run's filters in play: means (U, H, n), covs (U, H, n, n), L (U, H), active (U, H)."""
    top = np.max(np.where(active, loglik, -np.inf), axis=1, keepdims=True)
    w = np.where(active, np.exp(np.where(active, loglik - top, 0.0)), 0.0)
    w /= w.sum(axis=1, keepdims=True)
    x = np.einsum("ui,uij->uj", w, means)
    d = means - x[:, None, :]
    P = np.einsum("ui,uijk->ujk", w, covs) + np.einsum("ui,uij,uik->ujk", w, d, d)
    return x, 0.5 * (P + np.swapaxes(P, -1, -2))


def _offsets(sizes: np.ndarray) -> np.ndarray:
    """First filter of each run in a bank ordered run by run, from the runs' bank sizes."""
    return np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int)


def _split_runs(network, z: np.ndarray, r: int) -> dict[str, np.ndarray]:
    return network.split(z[r])


def _log_columns(recorder, entity: str, steps, values: np.ndarray, names: Sequence[str], times) -> None:
    """One scalar series per column, NaN where not finite: a hypothesis not in play leaves a gap (rerun breaks
    a line at NaN, so no line joins two periods in play); a column never finite is not logged."""
    for j, name in enumerate(names):
        finite = np.isfinite(values[:, j])
        if finite.any():
            recorder.log_scalars(f"{entity}/{name}", steps, np.where(finite, values[:, j], np.nan), times)


# --------------------------------------------------------------------------- known switching moments


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


@attrs.frozen(eq=False)
class KnownSwitchRun:
    """Algorithm 1's output: the selected estimate (K+1, n), covariances, the hypothesis followed per step,
    the log-likelihood ratios per hypothesis (K+1, H; NaN when not in play) and the per-segment outcomes;
    ``hypothesis_positions`` (K+1, H, 2), kept only when the run is recorded: each hypothesis's filtered position
    from the switch (where every hypothesis starts at the followed estimate) until it is eliminated or decided,
    NaN elsewhere."""

    layout: tuple[str, ...]
    hypotheses: tuple[str, ...]
    times: np.ndarray
    means: np.ndarray
    covs: np.ndarray
    followed: np.ndarray
    log_ratios: np.ndarray
    segments: tuple[SegmentOutcome, ...]
    decisions: tuple[Decision, ...]
    upper: float
    lower: float
    hypothesis_positions: np.ndarray | None = None


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
        registry = resolve_registry(registry)
        self.models = _models(modes if modes is not None else turn_bank(r_min, r_max, n, noise_cov), registry)
        self.hypotheses = mode_labels(self.models)
        self.layout = self.models[0].layout
        joint = switch_estimate == "joint"
        self.bank_models = [SwitchAugmented(m) for m in self.models] if joint else self.models
        self.bank_layout = augmented_layout(self.layout) if joint else self.layout
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.tau = None if tau is None else check_tau(tau)
        self.estimator: Estimator = resolve("estimator", estimator, registry)
        spec = detector if detector is not None else ("sprt_pairwise", {"alpha": alpha, "beta": beta})
        self.detector = resolve("detector", spec, registry)
        require(self.detector, HypothesisTest, "detector (Algorithm 1 needs a test over a fixed bank, e.g. 'sprt_pairwise')")
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
        """Algorithm 1 over ``segments`` (step counts, or a Schedule) on measurements of steps 0 … K.

        ``times``: the K+1 measurement times in seconds (default 0, τ, 2τ, …).
        """
        lengths = [s.steps for s in segments.segments] if isinstance(segments, Schedule) else [int(t) for t in segments]
        if not lengths or min(lengths) < 1:
            raise ValueError(f"segments: expected positive segment lengths, got {lengths}")
        z = self.network.stack(measurements)
        K = sum(lengths)
        if z.shape[0] != K + 1:
            raise ValueError(f"measurements: expected {K + 1} steps (0 … {K}) for segments totalling {K}, got {z.shape[0]}")
        t, dt = step_intervals(times, self.tau, K + 1)
        prior = _prior(prior)
        H, n = len(self.models), len(self.layout)
        sensors = self.network.sensors
        means, covs = np.zeros((K + 1, n)), np.zeros((K + 1, n, n))
        followed = np.zeros(K + 1, dtype=int)
        ratios = np.full((K + 1, H), np.nan)
        # the SPRT's bank (transitions fixed at x̂_{s|s}) and, with the joint switch estimate, the estimating bank
        test = FilterBank(self.estimator, self.layout)
        joint = self.switch_estimate == "joint"
        estimate = FilterBank(self.estimator, self.bank_layout) if joint else test

        # Algorithm 1: x̂ := x0; the first bank's transitions come from the given initial state
        self._start_banks(test, estimate, prior.mean, prior.cov, inflation=1.0)
        test.update_only(z[0], sensors)
        if joint:
            estimate.update_only(z[0], sensors)
        x, P = estimate.means[0, :n], estimate.covs[0, :n, :n]
        means[0], covs[0] = x, P
        position = [self.layout.index("x"), self.layout.index("y")]
        fan = np.full((K + 1, H, 2), np.nan) if recorder is not None else None  # only a recorded run keeps them
        q, k, row = 0, 0, 0
        since = np.zeros(2)  # after a decision: log-likelihood of the refined and the fixed filter
        outcomes, decisions = [], []
        detector = self.detector
        for number, T in enumerate(lengths):
            if number:  # new banks at the switch, from the estimate followed at the end of the last segment
                self._start_banks(test, estimate, x, P, row)
            if fan is not None:  # every hypothesis starts at the followed estimate of the switch
                fan[k] = means[k, position]
            detector.hypotheses = self.hypotheses
            detector.reset()
            decision_step = None
            accumulated = np.zeros(H)  # L_i: log-likelihood since the switch (of the estimating bank)
            for step in range(k + 1, k + T + 1):
                innovation = test.step(dt[step - 1], z[step], sensors)
                scores = estimate.step(dt[step - 1], z[step], sensors) if joint else innovation
                row = 0
                if decision_step is None:
                    out = detector.observe(step, innovation.loglik, innovation.nis, innovation.measurement_dim)
                    active = np.asarray(out.statistics.get("active", np.ones(H)), dtype=float) > 0
                    ratios[step] = np.where(active, out.statistics["log_ratio"], np.nan)
                    accumulated += np.asarray(scores.loglik, dtype=float)
                    row = q
                    if self.follow != "previous" and active.any():
                        row = q = int(np.argmax(np.where(active, accumulated, -np.inf)))
                    if out.decision is not None:
                        q, row, decision_step = int(detector.decided), int(detector.decided), step
                        ratios[step, q] = out.statistics["log_ratio"][q]
                        decisions.append(attrs.evolve(out.decision, time=float(t[step])))
                    if fan is not None:  # the hypotheses in play (and the one just decided)
                        shown = active.copy()
                        shown[q] |= out.decision is not None
                        fan[step] = np.where(shown[:, None], estimate.means[:, position], np.nan)
                if self.follow == "mixture" and decision_step is None and active.any():
                    x, P = _mixture(estimate.means[active, :n], estimate.covs[active, :n, :n], accumulated[active])
                    row = None  # the next bank (if the segment ends undecided) starts from the mixture
                elif joint and decision_step is not None and decision_step < step:
                    # after the decision: the chosen hypothesis with its switch state refined (EKF) and with it fixed
                    # at x̂_{s|s}, weighted by their likelihood since the decision (the refinement is kept while the
                    # data support it)
                    since += (float(scores.loglik[0]), float(innovation.loglik[0]))
                    x, P = _mixture(
                        np.stack([estimate.means[0, :n], test.means[0]]), np.stack([estimate.covs[0, :n, :n], test.covs[0]]), since
                    )
                    row = None
                else:
                    x, P = estimate.means[row, :n], estimate.covs[row, :n, :n]
                if decision_step == step:
                    test.keep([q])
                    if joint:  # the chosen hypothesis refines ω and the centre with the switch estimate (EKF)
                        estimate.keep([q])
                        estimate.replace_models([SwitchAugmented(self.models[q], relinearize=True)])
                        since = np.zeros(2)
                    row = 0
                means[step], covs[step], followed[step] = x, P, q
            outcomes.append(SegmentOutcome(k, T, self.hypotheses[q], q, self.models[q].radius, decision_step))
            k += T
        run = KnownSwitchRun(
            self.layout,
            self.hypotheses,
            t,
            means,
            covs,
            followed,
            ratios,
            tuple(outcomes),
            tuple(decisions),
            float(detector.upper),
            float(detector.lower),
            fan,
        )
        if recorder is not None:
            self._record(recorder, z, run, truth)
        return run

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
        """Algorithm 1 on R runs at once: equal to ``[self.run(...) for each run]`` (to rounding, 1e-12).

        ``measurements``: sensor name → (R, K+1, m); ``times`` (K+1,) shared or
        (R, K+1) per run (default 0, τ, 2τ, …); ``prior`` one Gaussian or
        per-run (means (R, n), covs (n, n) or (R, n, n)); ``segments`` shared by
        the runs; ``truth`` one per run (recordings only); ``recorders`` run
        index → Recorder for the runs to record.  The R banks are one stacked
        bank (:class:`~hybridtrack.engine.run_bank.RunBank`): the switch
        re-creates every run's bank, a run's decision keeps its chosen filter
        (index arrays through the estimator's ``take``), the detector runs as
        ``detector.batch(R)`` (vectorized for ``sprt_pairwise``).  The joint
        switch estimate, decentralized and sampling estimators run the runs
        one after the other.
        """
        lengths = [s.steps for s in segments.segments] if isinstance(segments, Schedule) else [int(t) for t in segments]
        if not lengths or min(lengths) < 1:
            raise ValueError(f"segments: expected positive segment lengths, got {lengths}")
        z = batch_measurements(self.network, measurements)
        R, K = z.shape[0], sum(lengths)
        if z.shape[1] != K + 1:
            raise ValueError(f"measurements: expected {K + 1} steps (0 … {K}) for segments totalling {K}, got {z.shape[1]}")
        t, dt = batch_times(times, self.tau, R, K + 1)
        H, n = len(self.models), len(self.layout)
        x0, P0 = batch_prior(prior, R, n)
        truths = per_run(truth, R, "truth")
        recorders = check_recorders(recorders, R)
        if self.switch_estimate == "joint" or not batchable(self.estimator):
            return [
                self.run(
                    _split_runs(self.network, z, r),
                    Gaussian(x0[r], P0[r]),
                    lengths,
                    times=t[r] if times is not None else None,
                    recorder=recorders.get(r),
                    truth=truths[r],
                )
                for r in range(R)
            ]
        means, covs = np.zeros((R, K + 1, n)), np.zeros((R, K + 1, n, n))
        followed = np.zeros((R, K + 1), dtype=int)
        ratios = np.full((R, K + 1, H), np.nan)
        bank = RunBank(self.estimator, self.layout, self.network.sensors)
        runs = np.arange(R)
        every = np.repeat(runs, H)
        # Algorithm 1: x̂ := x0; the first bank's transitions come from the given initial state
        bank.set(
            self.estimator.initialize(np.repeat(x0, H, axis=0), np.repeat(P0, H, axis=0)), self.models * R, np.repeat(x0, H, axis=0), every
        )
        bank.step(None, z[every, 0])
        sizes = np.full(R, H)
        first = _offsets(sizes)
        x, P = bank.means[first], bank.covs[first]
        means[:, 0], covs[:, 0] = x, P
        position = [self.layout.index("x"), self.layout.index("y")]
        fans = {r: np.full((K + 1, H, 2), np.nan) for r in recorders}  # only the recorded runs keep them
        recorded = np.array(sorted(fans), dtype=int)
        q, row = np.zeros(R, dtype=int), np.zeros(R, dtype=int)  # row −1: the estimate is a mixture
        outcomes, decisions = [[] for _ in runs], [[] for _ in runs]
        batch = self.detector.batch(R)
        k = 0
        for number, T in enumerate(lengths):
            if number:  # new banks at the switch, from the estimate followed at the end of the last segment
                self._start_batch(bank, x, P, row, _offsets(sizes))
                sizes = np.full(R, H)
            for r, fan in fans.items():  # every hypothesis starts at the followed estimate of the switch
                fan[k] = means[r, k, position]
            batch.reset(self.hypotheses)
            decision_step = np.full(R, -1)
            accumulated = np.zeros((R, H))  # L_i: log-likelihood since the switch
            for step in range(k + 1, k + T + 1):
                offsets = _offsets(sizes)
                loglik, nis, m = bank.step(dt[bank.run, step - 1], z[bank.run, step])
                row = np.zeros(R, dtype=int)
                open_ = np.flatnonzero(decision_step < 0)
                newly = np.zeros(0, dtype=int)
                mix = np.zeros(0, dtype=int)
                if open_.size:
                    idx = offsets[open_, None] + np.arange(H)
                    out = batch.observe(step, open_, loglik[idx], nis[idx], m[offsets[open_]])
                    active = out.active > 0
                    ratios[open_, step] = np.where(active, out.log_ratio, np.nan)
                    accumulated[open_] += loglik[idx]
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
                        r = open_[u]
                        decisions[r].append(attrs.evolve(out.decisions[u], time=float(t[r, step])))
                    for u in np.flatnonzero(np.isin(open_, recorded)):  # the hypotheses in play (and the one just decided)
                        shown = active[u].copy()
                        shown[q[open_[u]]] |= bool(done[u])
                        fans[open_[u]][step] = np.where(shown[:, None], bank.means[idx[u]][:, position], np.nan)
                    if self.follow == "mixture":
                        pick = ~done & active.any(axis=1)
                        mix = open_[pick]
                        if mix.size:
                            sub = idx[pick]
                            x_mix, P_mix = _mixtures(bank.means[sub], bank.covs[sub], accumulated[mix], active[pick])
                chosen_rows = offsets + row
                x, P = bank.means[chosen_rows].copy(), bank.covs[chosen_rows].copy()
                if mix.size:
                    x[mix], P[mix] = x_mix, P_mix
                    row[mix] = -1  # the next bank (if the segment ends undecided) starts from the mixture
                if newly.size:  # the decided runs keep only the chosen filter
                    keep = np.ones(len(bank), dtype=bool)
                    keep[(offsets[newly, None] + np.arange(H)).reshape(-1)] = False
                    keep[offsets[newly] + q[newly]] = True
                    bank.take(np.flatnonzero(keep))
                    sizes[newly] = 1
                    row[newly] = 0
                means[:, step], covs[:, step], followed[:, step] = x, P, q
            for r in runs:
                decided_at = None if decision_step[r] < 0 else int(decision_step[r])
                outcomes[r].append(SegmentOutcome(k, T, self.hypotheses[q[r]], int(q[r]), self.models[q[r]].radius, decided_at))
            k += T
        results = []
        for r in runs:
            run = KnownSwitchRun(
                self.layout,
                self.hypotheses,
                t[r],
                means[r],
                covs[r],
                followed[r],
                ratios[r],
                tuple(outcomes[r]),
                tuple(decisions[r]),
                float(batch.upper),
                float(batch.lower),
                fans.get(r),
            )
            if r in recorders:
                self._record(recorders[r], z[r], run, truths[r])
            results.append(run)
        return results

    def _start_batch(self, bank: RunBank, x: np.ndarray, P: np.ndarray, row: np.ndarray, offsets: np.ndarray) -> None:
        """:meth:`_start_banks` for every run of a stacked bank: a run whose estimate is a filter (row ≥ 0) with
        κ = 1 copies that filter in its own state form; the others start from (x, κ P)."""
        H, R = len(self.models), x.shape[0]
        inflation = self.switch_inflation
        copy_runs = np.flatnonzero(row >= 0) if inflation == 1 else np.zeros(0, dtype=int)
        init_runs = np.setdiff1d(np.arange(R), copy_runs)
        parts, order = [], []
        if copy_runs.size:
            parts.append(self.estimator.take(bank.state, np.repeat(offsets[copy_runs] + row[copy_runs], H)))
            order.append(copy_runs)
        if init_runs.size:
            parts.append(self.estimator.initialize(np.repeat(x[init_runs], H, axis=0), np.repeat(inflation * P[init_runs], H, axis=0)))
            order.append(init_runs)
        state = parts[0] if len(parts) == 1 else self.estimator.concatenate(parts)
        if len(parts) > 1:
            position = np.empty(R, dtype=int)
            position[np.concatenate(order)] = np.arange(R)
            state = self.estimator.take(state, (position[:, None] * H + np.arange(H)).reshape(-1))
        bank.set(state, self.models * R, np.repeat(x, H, axis=0), np.repeat(np.arange(R), H))

    def _start_banks(
        self, test: FilterBank, estimate: FilterBank, x: np.ndarray, P: np.ndarray, row: int | None = None, inflation: float | None = None
    ) -> None:
        """Every hypothesis from the estimate (x, P) at the switch, its transition fixed there (the SPRT's bank) and,
        with the joint switch estimate, started there with the switch state carried (the estimating bank).

        The SPRT's bank starts from (x, κ P), κ = ``switch_inflation`` (1 for the
        first bank, which starts from the given prior, not a switch estimate); with κ = 1
        a followed filter ``row`` of that bank is copied in its own state form
        (factors propagated, no re-initialization).
        """
        labels = range(len(self.models))
        inflation = self.switch_inflation if inflation is None else inflation
        if row is not None and estimate is test and inflation == 1:
            test.restart(row, self.models, x, labels=labels)
        else:
            test.start(x, inflation * P, self.models, x, labels=labels)
        if estimate is not test:
            mean, cov = augmented_prior(x, P)
            estimate.start(mean, cov, self.bank_models, mean, labels=labels)

    def _record(self, recorder, z: np.ndarray, run: KnownSwitchRun, truth) -> None:
        steps, times = _record_run(recorder, self, z, run, run.hypotheses, truth)
        recorder.log_scalars(f"estimator/{self.name}/followed", steps, run.followed.astype(float), times)
        recorder.log_modes(f"world/estimate/{self.name}", steps, run.followed, run.hypotheses, times)
        # filters running per step: the hypotheses still in play, one after the decision
        bank_size = np.maximum(1, np.isfinite(run.log_ratios).sum(axis=1))
        recorder.log_scalars(f"estimator/{self.name}/bank_size", steps, bank_size.astype(float), times)


# --------------------------------------------------------------------------- unknown change time


@attrs.frozen
class ChangeEvent:
    """A detected change: at ``step`` the mode became ``mode``; the most likely change step was ``change_step``."""

    step: int
    mode: str
    change_step: int


@attrs.frozen(eq=False)
class UnknownChangeRun:
    """Algorithm 3 repeated: the selected estimate (K+1, n), the mode followed per step (index into
    ``modes``), ln λ per mode (K+1, M; NaN for the current mode and at step 0), the bank size (number of
    filters) per step, the signal function of filter 0 and its bounds, decisions, detected changes, and,
    with a decentralized estimator, the same series computed at each node (K+1, N, …);
    ``hypothesis_positions`` (K+1, M, 2), kept only when the run is recorded: the position of each alternative
    mode's most likely filter (largest ψ over its change times) at every step, NaN for the current mode."""

    layout: tuple[str, ...]
    modes: tuple[str, ...]
    times: np.ndarray
    means: np.ndarray
    covs: np.ndarray
    mode: np.ndarray
    log_ratios: np.ndarray
    bank_sizes: np.ndarray
    signal: np.ndarray
    signal_bounds: np.ndarray
    decisions: tuple[Decision, ...]
    changes: tuple[ChangeEvent, ...]
    upper: float
    lower: float
    bank_limit: int | None
    node_log_ratios: np.ndarray | None = None
    node_signal: np.ndarray | None = None
    hypothesis_positions: np.ndarray | None = None

    def first_change(self, after: int = 0) -> ChangeEvent | None:
        """The first detected change at a step > ``after``."""
        return next((c for c in self.changes if c.step > after), None)


class UnknownChangeAdaptive:
    """Seed 000 Algorithm 3, repeated: growing (or bounded) bank, rule (24), the estimate follows the identified mode.

    ``modes``: the M motion modes (objects, names or (name, parameters));
    ``initial_mode`` the index of the mode at the start.  ``detector``: an
    object or spec of a change-time SPRT (default ``sprt_unknown_change`` with
    ``alpha``, ``beta``); ``bank_size`` bounds the alternative filters (an int,
    ``"algorithm4"`` or None for the growing bank of the seed); ``pruning``
    overrides the detector's rule.  ``signal``: a signal-function detector
    watching filter 0 (None to skip).  ``max_bank_size``: a growing bank
    (``bank_size=None``) that passes this many alternative filters — e.g.
    through a long gap without measurements, where every step adds M − 1
    filters and nothing decides — gets a RuntimeWarning and is pruned to that
    size by the detector's rule from then on.
    """

    def __init__(
        self,
        *,
        modes: Sequence[Any],
        sensors: SensorNetwork | Sequence[Sensor],
        tau: float | None = None,
        estimator: Any = "kalman",
        detector: Any = None,
        alpha: float = 0.05,
        beta: float = 0.05,
        initial_mode: int = 0,
        bank_size: int | str | None = None,
        pruning: str | None = None,
        signal: Any = "signal_function",
        max_bank_size: int = 5000,
        name: str = "unknown_change",
        registry: Registry | None = None,
    ):
        registry = resolve_registry(registry)
        self.models = _models(modes, registry)
        if len(self.models) < 2:
            raise ValueError(f"modes: a change needs at least two modes, got {len(self.models)}")
        self.labels = mode_labels(self.models)
        self.layout = self.models[0].layout
        if isinstance(initial_mode, bool) or not isinstance(initial_mode, (int, np.integer)) or not 0 <= initial_mode < len(self.models):
            raise ValueError(f"initial_mode: expected an index in 0 … {len(self.models) - 1}, got {initial_mode!r}")
        self.initial_mode = int(initial_mode)
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.tau = None if tau is None else check_tau(tau)
        self.estimator: Estimator = resolve("estimator", estimator, registry)
        spec = detector if detector is not None else ("sprt_unknown_change", {"alpha": alpha, "beta": beta})
        self.detector = resolve("detector", spec, registry)
        require(self.detector, ChangeTimeTest, "detector (Algorithm 3 needs a change-time test, e.g. 'sprt_unknown_change')")
        if pruning is not None:
            if pruning not in ChangeTimeTest.PRUNING_RULES:
                raise ValueError(f"pruning: expected one of {ChangeTimeTest.PRUNING_RULES}, got {pruning!r}")
            self.detector.pruning = pruning
        if isinstance(bank_size, str):
            if bank_size != "algorithm4":
                raise ValueError(f"bank_size: expected a positive integer, 'algorithm4' or None, got {bank_size!r}")
            if pruning is None:
                self.detector.pruning = "oldest"
        elif bank_size is not None:
            bank_size = check_positive_int(bank_size, "bank_size")
        self.bank_size = bank_size
        self.max_bank_size = check_positive_int(max_bank_size, "max_bank_size")
        self.signal = None if signal is None else require(resolve("detector", signal, registry), ScoreDetector, "signal")
        self.name = name

    # ------------------------------------------------------------------ Algorithm 4
    def algorithm4_bank_size(self, switch_state, horizon: int = 300, dt: float | None = None) -> int:
        """Alternative filters to keep: Algorithm 4's steps per change time × (M − 1), from ``switch_state``.

        The steps are of ``dt`` seconds (default ``tau``; with irregular times the run uses the first Δt).
        """
        dt = check_tau(self.tau if dt is None else dt)
        x_s = np.asarray(switch_state, dtype=float)
        H = self.network.jacobian(x_s, self.layout)
        R = self.network.noise_cov()
        base = self.models[self.initial_mode].transition(dt, x_s)
        pairs = []
        for p, model in enumerate(self.models):
            if p == self.initial_mode:
                continue
            t = model.transition(dt, x_s)
            pairs.append(
                wald_pair(
                    (base.F, base.B, base.process_noise),
                    (t.F, t.B, t.process_noise),
                    H,
                    R,
                    x_s,
                    self.detector.alpha,
                    self.detector.beta,
                    horizon=horizon,
                )
            )
        return algorithm4_bank_size(pairs) * (len(self.models) - 1)

    def _algorithm4_cached(self, switch_state, dt) -> int:
        key = (np.asarray(switch_state, dtype=float).tobytes(), dt, self.detector.alpha, self.detector.beta)
        cache = self.__dict__.setdefault("_algorithm4", {})
        if key not in cache:
            cache[key] = self.algorithm4_bank_size(switch_state, dt=dt)
        return cache[key]

    # ------------------------------------------------------------------ the run
    def _restart(self, detectors, current: int) -> list[int]:
        alternatives = [i for i in range(len(self.models)) if i != current]
        for detector in detectors:
            detector.hypotheses = (self.labels[current],) + tuple(self.labels[i] for i in alternatives)
            detector.reset()
        return alternatives

    def run(self, measurements: Mapping[str, np.ndarray], prior, *, times=None, recorder=None, truth=None) -> UnknownChangeRun:
        """Algorithm 3, repeated, on measurements of steps 0 … K at ``times`` (seconds; default 0, τ, 2τ, …)."""
        z = self.network.stack(measurements)
        prior = _prior(prior)
        K = z.shape[0] - 1
        t, dt = step_intervals(times, self.tau, K + 1)
        n, M = len(self.layout), len(self.models)
        limit = self._algorithm4_cached(prior.mean, float(dt[0]) if K else self.tau) if self.bank_size == "algorithm4" else self.bank_size
        sensors = self.network.sensors
        detector = self.detector
        signal = self.signal
        node_detectors: list = []
        node_signals: list = []
        capped = False

        means, covs = np.zeros((K + 1, n)), np.zeros((K + 1, n, n))
        mode = np.zeros(K + 1, dtype=int)
        ratios = np.full((K + 1, M), np.nan)
        bank_sizes = np.zeros(K + 1, dtype=int)
        signal_values = np.full(K + 1, np.nan)
        bounds = np.full((K + 1, 2), np.nan)
        node_ratios, node_signal = None, None
        decisions, changes = [], []
        position = [self.layout.index("x"), self.layout.index("y")]
        fan = np.full((K + 1, M, 2), np.nan) if recorder is not None else None  # only a recorded run keeps them

        current = self.initial_mode
        alternatives = self._restart([detector], current)
        if signal is not None:
            signal.reset()
        bank = FilterBank(self.estimator, self.layout)
        bank.start(prior.mean, prior.cov, [self.models[current]], prior.mean)
        innovation = bank.update_only(z[0], sensors)
        if signal is not None:
            out = signal.observe(0, innovation.loglik[:1], innovation.nis[:1], innovation.measurement_dim)
            signal_values[0], bounds[0] = out.statistics["signal"][0], (out.thresholds["lower"], out.thresholds["upper"])
        means[0], covs[0], mode[0], bank_sizes[0] = bank.means[0], bank.covs[0], current, 1
        scores = bank.node_scores()
        if scores is not None:  # decentralized: every node runs its own copy of the detectors
            N = scores[0].shape[0]
            node_detectors = [copy.deepcopy(detector) for _ in range(N)]
            node_ratios, node_signal = np.full((K + 1, N, M), np.nan), np.full((K + 1, N), np.nan)
            if signal is not None:
                node_signals = [copy.deepcopy(signal) for _ in range(N)]
                for i, ns in enumerate(node_signals):
                    ns.reset()
                    node_signal[0, i] = ns.observe(0, scores[0][i][:1], scores[1][i][:1], innovation.measurement_dim).statistics["signal"][
                        0
                    ]

        for k in range(1, K + 1):
            # 1. one new filter per alternative, hypothesising the change at k: a copy of filter 0's state
            bank.branch(0, [self.models[i] for i in alternatives], bank.means[0], labels=[(i, k) for i in alternatives])
            for d in [detector] + node_detectors:
                d.add(np.arange(1, M), k)
            # 2. one step of the whole bank, then the ratios (25) and rule (24)
            innovation = bank.step(dt[k - 1], z[k], sensors)
            m = innovation.measurement_dim
            out = detector.observe(k, innovation.loglik, innovation.nis, m)
            ratios[k, alternatives] = out.statistics["log_ratio"]
            bank_sizes[k] = len(bank)
            if fan is not None and (out.decision is None or detector.decided):
                # each alternative's most likely filter (entry e is row 1 + e of the bank); none once "no change" is accepted
                for p, mode_index in enumerate(alternatives, start=1):
                    rows = np.flatnonzero(detector.modes == p)
                    if rows.size:
                        fan[k, mode_index] = bank.means[1 + rows[np.argmax(detector.log_psi[rows])], position]
            scores = bank.node_scores()
            for i, d in enumerate(node_detectors):
                d.observe(k, scores[0][i], scores[1][i], m)
                node_ratios[k, i, alternatives] = d.log_ratios()
            if signal is not None:
                s = signal.observe(k, innovation.loglik[:1], innovation.nis[:1], m)
                signal_values[k], bounds[k] = s.statistics["signal"][0], (s.thresholds["lower"], s.thresholds["upper"])
                for i, ns in enumerate(node_signals):
                    node_signal[k, i] = ns.observe(k, scores[0][i][:1], scores[1][i][:1], m).statistics["signal"][0]
            # 3. act on the decision, or bound the bank
            if out.decision is not None:
                decisions.append(attrs.evolve(out.decision, time=float(t[k])))
                if detector.decided:  # a change to alternatives[p − 1], followed by its most likely filter
                    entry = int(detector.chosen_entry)
                    change = ChangeEvent(k, self.labels[alternatives[detector.decided - 1]], int(detector.starts[entry]))
                    changes.append(change)
                    current = alternatives[detector.decided - 1]
                    bank.keep([1 + entry])
                    if signal is not None:
                        for s_ in [signal] + node_signals:
                            s_.reset()
                else:  # H_0 accepted: the test restarts with filter 0 alone
                    bank.keep([0])
                alternatives = self._restart([detector] + node_detectors, current)
            else:
                cap = limit
                if cap is None and len(bank) - 1 > self.max_bank_size:  # the growing bank, e.g. through a long gap
                    if not capped:
                        warnings.warn(
                            f"{self.name}: the growing bank reached {len(bank) - 1} alternative filters at step {k} "
                            f"(max_bank_size = {self.max_bank_size}); pruning to {self.max_bank_size} by the "
                            f"{detector.pruning!r} rule from now on",
                            RuntimeWarning,
                            stacklevel=2,
                        )
                        capped = True
                    cap = self.max_bank_size
                rows = detector.prune(cap)
                for d in node_detectors:
                    d.keep(rows)
                bank.keep(np.concatenate([[0], rows + 1]))
            means[k], covs[k], mode[k] = bank.means[0], bank.covs[0], current
        run = UnknownChangeRun(
            self.layout,
            self.labels,
            t,
            means,
            covs,
            mode,
            ratios,
            bank_sizes,
            signal_values,
            bounds,
            tuple(decisions),
            tuple(changes),
            float(detector.upper),
            float(detector.lower),
            limit,
            node_ratios,
            node_signal,
            fan,
        )
        if recorder is not None:
            self._record(recorder, z, run, truth)
        return run

    def run_batch(self, measurements: Mapping[str, np.ndarray], prior, *, times=None, truth=None, recorders=None) -> list[UnknownChangeRun]:
        """Algorithm 3, repeated, on R runs at once: equal to ``[self.run(...) for each run]`` (to rounding, 1e-12).

        ``measurements``: sensor name → (R, K+1, m); ``times`` (K+1,) shared or
        (R, K+1) per run; ``prior`` one Gaussian or per-run (means (R, n), covs
        (n, n) or (R, n, n)); ``truth`` one per run; ``recorders`` run index →
        Recorder.  Every run's growing bank lives in one stacked bank
        (:class:`~hybridtrack.engine.run_bank.RunBank`, run by run): the new
        filters of all runs are added, and decisions and pruning applied, by
        one index array per step through the estimator's ``take``.  The
        change-time test and the signal function keep per-run bookkeeping
        (entries, change times, pruning), so each run has its own copy of them.
        Decentralized and sampling estimators run the runs one after the other.
        """
        z = batch_measurements(self.network, measurements)
        R, K = z.shape[0], z.shape[1] - 1
        t, dt = batch_times(times, self.tau, R, K + 1)
        n, M = len(self.layout), len(self.models)
        x0, P0 = batch_prior(prior, R, n)
        truths = per_run(truth, R, "truth")
        recorders = check_recorders(recorders, R)
        if not batchable(self.estimator):
            return [
                self.run(
                    _split_runs(self.network, z, r),
                    Gaussian(x0[r], P0[r]),
                    times=t[r] if times is not None else None,
                    recorder=recorders.get(r),
                    truth=truths[r],
                )
                for r in range(R)
            ]
        runs = np.arange(R)
        limits = [
            self._algorithm4_cached(x0[r], float(dt[r, 0]) if K else self.tau) if self.bank_size == "algorithm4" else self.bank_size
            for r in runs
        ]
        test = self.detector.batch(R)  # Algorithm 3's test of every run (vectorized for sprt_unknown_change)
        signals = [None if self.signal is None else copy.deepcopy(self.signal) for _ in runs]
        capped = np.zeros(R, dtype=bool)
        means, covs = np.zeros((R, K + 1, n)), np.zeros((R, K + 1, n, n))
        mode = np.zeros((R, K + 1), dtype=int)
        ratios = np.full((R, K + 1, M), np.nan)
        bank_sizes = np.zeros((R, K + 1), dtype=int)
        signal_values = np.full((R, K + 1), np.nan)
        bounds = np.full((R, K + 1, 2), np.nan)
        decisions, changes = [[] for _ in runs], [[] for _ in runs]
        position = [self.layout.index("x"), self.layout.index("y")]
        fans = {r: np.full((K + 1, M, 2), np.nan) for r in recorders}  # only the recorded runs keep them
        current = np.full(R, self.initial_mode)
        others = np.array([[i for i in range(M) if i != c] for c in range(M)])  # the alternatives of each current mode
        names = [(self.labels[c],) + tuple(self.labels[i] for i in others[c]) for c in range(M)]
        test.restart(runs, [names[self.initial_mode]] * R)
        for s_ in signals:
            if s_ is not None:
                s_.reset()
        bank = RunBank(self.estimator, self.layout, self.network.sensors)
        bank.set(self.estimator.initialize(x0, P0), [self.models[self.initial_mode]] * R, x0, runs)
        loglik, nis, m = bank.step(None, z[:, 0])
        for r, s_ in enumerate(signals):
            if s_ is not None:
                out = s_.observe(0, loglik[r : r + 1], nis[r : r + 1], int(m[r]))
                signal_values[r, 0], bounds[r, 0] = out.statistics["signal"][0], (out.thresholds["lower"], out.thresholds["upper"])
        means[:, 0], covs[:, 0], mode[:, 0], bank_sizes[:, 0] = bank.means, bank.covs, current, 1
        sizes = np.ones(R, dtype=int)
        for k in range(1, K + 1):
            # 1. one new filter per alternative in every run, hypothesising the change at k: copies of its filter 0
            offsets = _offsets(sizes)
            switch = bank.means[offsets]
            grown = _offsets(sizes + (M - 1))
            rows = np.empty(len(bank) + R * (M - 1), dtype=int)
            rows[grown[bank.run] + np.arange(len(bank)) - offsets[bank.run]] = np.arange(len(bank))
            added = (grown + sizes)[:, None] + np.arange(M - 1)
            rows[added] = offsets[:, None]
            fresh = np.zeros(rows.size, dtype=bool)
            fresh[added] = True
            bank.take(rows, fresh)
            sizes, offsets = sizes + (M - 1), grown
            alternatives = others[current]
            bank.assign(added, [self.models[i] for i in alternatives.reshape(-1)], np.repeat(switch, M - 1, axis=0))
            test.add(k)
            # 2. one step of the whole bank, then every run's ratios (25) and rule (24)
            loglik, nis, m = bank.step(dt[bank.run, k - 1], z[bank.run, k])
            entries = np.ones(len(bank), dtype=bool)
            entries[offsets] = False
            entry_rows = np.flatnonzero(entries)
            out = test.observe(k, loglik[offsets], loglik[entry_rows], nis[offsets], nis[entry_rows], m[offsets])
            ratios[runs[:, None], k, alternatives] = out.log_ratio
            bank_sizes[:, k] = sizes
            for r, fan in fans.items():  # each alternative's most likely filter (test entry e is bank row entry_rows[e])
                if out.decided[r] == 0:  # "no change" accepted: no alternative in play (the test has restarted)
                    continue
                for p, mode_index in enumerate(alternatives[r], start=1):
                    rows = np.flatnonzero((test.run == r) & (test.modes == p))
                    if rows.size:
                        fan[k, mode_index] = bank.means[entry_rows[rows[np.argmax(test.log_psi[rows])]], position]
            for r, signal in enumerate(signals):
                if signal is not None:
                    s = signal.observe(k, loglik[offsets[r] : offsets[r] + 1], nis[offsets[r] : offsets[r] + 1], int(m[offsets[r]]))
                    signal_values[r, k], bounds[r, k] = s.statistics["signal"][0], (s.thresholds["lower"], s.thresholds["upper"])
            # 3. act on the decisions, or bound the banks
            open_ = np.flatnonzero(out.decided < 0)
            caps = np.full(open_.size, -1)
            for u, r in enumerate(open_):
                cap = limits[r]
                if cap is None and sizes[r] - 1 > self.max_bank_size:  # the growing bank, e.g. through a long gap
                    if not capped[r]:
                        warnings.warn(
                            f"{self.name}: the growing bank reached {sizes[r] - 1} alternative filters at step {k} "
                            f"(max_bank_size = {self.max_bank_size}); pruning to {self.max_bank_size} by the "
                            f"{test.pruning!r} rule from now on",
                            RuntimeWarning,
                            stacklevel=2,
                        )
                        capped[r] = True
                    cap = self.max_bank_size
                caps[u] = -1 if cap is None else cap
            kept = test.prune(open_, caps)
            keep = np.zeros(len(bank), dtype=bool)
            keep[offsets[open_]] = True
            is_open = np.zeros(R, dtype=bool)
            is_open[open_] = True
            keep[entry_rows[kept & is_open[bank.run[entry_rows]]]] = True
            done = np.flatnonzero(out.decided >= 0)
            for r in done:
                decisions[r].append(attrs.evolve(out.decisions[r], time=float(t[r, k])))
                if out.decided[r] > 0:  # a change to alternatives[p − 1], followed by its most likely filter
                    current[r] = alternatives[r, out.decided[r] - 1]
                    changes[r].append(ChangeEvent(k, self.labels[current[r]], int(out.chosen_start[r])))
                    keep[offsets[r] + 1 + out.chosen_entry[r]] = True
                    if signals[r] is not None:
                        signals[r].reset()
                else:  # H_0 accepted: the test restarts with filter 0 alone
                    keep[offsets[r]] = True
            if done.size:
                test.restart(done, [names[c] for c in current[done]])
            bank.take(np.flatnonzero(keep))
            sizes = np.bincount(bank.run, minlength=R)
            first = _offsets(sizes)
            means[:, k], covs[:, k], mode[:, k] = bank.means[first], bank.covs[first], current
        results = []
        for r in runs:
            run = UnknownChangeRun(
                self.layout,
                self.labels,
                t[r],
                means[r],
                covs[r],
                mode[r],
                ratios[r],
                bank_sizes[r],
                signal_values[r],
                bounds[r],
                tuple(decisions[r]),
                tuple(changes[r]),
                float(test.upper),
                float(test.lower),
                limits[r],
                hypothesis_positions=fans.get(r),
            )
            if r in recorders:
                self._record(recorders[r], z[r], run, truths[r])
            results.append(run)
        return results

    def _record(self, recorder, z: np.ndarray, run: UnknownChangeRun, truth) -> None:
        steps, times = _record_run(recorder, self, z, run, run.modes, truth)
        if self.signal is not None:
            sig = f"detector/{self.signal.label}"
            recorder.log_scalars(f"{sig}/signal", steps, run.signal, times)
            recorder.log_scalars(f"{sig}/lower", steps, run.signal_bounds[:, 0], times)
            recorder.log_scalars(f"{sig}/upper", steps, run.signal_bounds[:, 1], times)
        recorder.log_scalars(f"estimator/{self.name}/bank_size", steps, run.bank_sizes.astype(float), times)
        recorder.log_scalars(f"estimator/{self.name}/mode", steps, run.mode.astype(float), times)
        recorder.log_modes(f"world/estimate/{self.name}", steps, run.mode, run.modes, times)
