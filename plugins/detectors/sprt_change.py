"""SPRT with unknown change time over a growing bank of filters (seed 000 Algorithm 3, eqs. 24–25; SPEC §4).

Hypothesis H_0: the current mode 0 goes on; H_p (p = 1 … M−1): the mode
changed to p at some unknown step j.  Filter F_1^0 runs mode 0 since the test
began; at every step j a filter F_j^p per alternative p is started,
hypothesising the change at j.  With ℓ the innovation log-likelihood,

    ln ψ_j^p(k) = ln ψ_j^p(k−1) + ℓ_j^p(k) − ℓ_1^0(k),   ln ψ_j^p(j−1) = 0   (eq. 25 with the
                  determinant ratio the right way up, √(det S_0 / det S_p): SPEC §4)
    ln λ_{p,k} = ln((1/k) Σ_{j=1}^{k} ψ_j^p(k)) = logsumexp_j ln ψ_j^p(k) − ln k

(change time uniform on [1, k]; k counts the steps since the test began).
Decision rule (24) with A = ln((1−β)/α) (``upper``), B = ln(β/(1−α)) (``lower``):
any ln λ_p ≥ A → change to the largest such p; all ln λ_p ≤ B → H_0 ("stay"),
and the test restarts; otherwise continue.  With ``averaging="none"`` the
mean over change times is replaced by the sum (a fixed bank whose filters all
start at the first step is then the multi-hypothesis SPRT with a known change
time).

Bookkeeping (who drives the bank calls these): the innovation's row 0 is
F_1^0 and rows 1 … E are the entries in the order of :meth:`add`;
:meth:`prune` bounds the bank and returns the rows kept:

* ``"oldest"`` — drop the entries started longest ago (a sliding window
  over change times, the rule seed 003 improves on);
* ``"nearest_lower"`` — drop the entries whose ln ψ is nearest the lower bound
  B, i.e. the smallest (seed 003, Zakharov's rule).

Fed a fixed bank of M filters without any :meth:`add` (e.g. by
:class:`~hybridtrack.algorithms.known_switch.KnownSwitchAdaptive` between its known
switches), rows 1 … M−1 become the entries of modes 1 … M−1 started at the first
step.  A :class:`~hybridtrack.engine.pipeline.Pipeline` refuses the test
(``requires_bank_management = "unknown_change"``): on its bank, whose filters
are never restarted, it decides at most once, late (11–26 steps into a turn
that Algorithm 3 detects after 6–11, in five simulated runs), with the change
time "step 0".
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import DetectorStep
from hybridtrack.core.protocols import ChangeTimeStep, ChangeTimeTest, ChangeTimeTestBatch
from hybridtrack.core.types import Decision
from hybridtrack.core.validation import check_positive_int
from hybridtrack.sdk.thresholds import WaldThresholds

PRUNING_RULES = ChangeTimeTest.PRUNING_RULES
AVERAGING = ("uniform", "none")


def _offsets(counts: np.ndarray) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)


def _check_hypotheses(names) -> tuple[str, ...]:
    names = tuple(str(h) for h in names)
    if len(names) < 2:
        raise ValueError(f"hypotheses: expected the current mode and at least one alternative, got {names!r}")
    return names


def rule(step, label, hypotheses, ratios, run, modes, starts, log_psi, upper, lower):
    """Rule (24) for R tests at once: ``ratios`` (R, P) ln λ_p, ``hypotheses`` one tuple of names per test, the
    entries' test ``run``, alternative ``modes``, change steps ``starts`` and ln ψ (flat, test by test).

    Returns ``decided`` (R,) −1 (continue), 0 (no change) or the alternative p of a change, the entry followed
    after a change (index among its test's entries, −1 otherwise) and its change step, and the Decisions.
    """
    R, P = ratios.shape
    best = ratios.max(axis=1) if P else np.full(R, -np.inf)
    change = best >= upper
    stay = ~change & np.isfinite(ratios).all(axis=1) & (best <= lower) & (P > 0)
    decided, entry, start = np.full(R, -1), np.full(R, -1), np.full(R, -1)
    decisions = [None] * R
    offsets = _offsets(np.bincount(run, minlength=R))
    for r in np.flatnonzero(change):
        p = int(np.argmax(ratios[r])) + 1
        rows = np.flatnonzero((run == r) & (modes == p))
        chosen = int(rows[np.argmax(log_psi[rows])])
        decided[r], entry[r], start[r] = p, chosen - offsets[r], int(starts[chosen])
        name, value = hypotheses[r][p], float(ratios[r, p - 1])
        message = f"change to {name} (most likely at step {start[r]}), ln λ = {value:.2f} ≥ A = {upper:.2f}"
        decisions[r] = Decision(step, label, name, value, message)
    for r in np.flatnonzero(stay):
        decided[r] = 0
        message = f"no change: every ln λ ≤ B = {lower:.2f}; the test restarts"
        decisions[r] = Decision(step, label, hypotheses[r][0], float(best[r]), message)
    return decided, entry, start, decisions


def change_log_ratios(run, modes, log_psi, k, P: int, uniform: bool) -> np.ndarray:
    """ln λ_p (R, P) of R tests from their entries' ``run``, alternative ``modes`` and ln ψ, and k (R,) (−inf for
    an alternative with no entry): scipy's log-sum-exp with the largest term taken out, ln λ = a + ln c +
    log1p(Σ_{others} e^{ψ−a} / c), a the largest ln ψ of the group, c how many reach it; minus ln k if ``uniform``."""
    R = k.size
    group = run * P + (modes - 1)
    top = np.full(R * P, -np.inf)
    np.maximum.at(top, group, log_psi)
    at_top = log_psi == top[group]
    count = np.bincount(group, weights=at_top, minlength=R * P)
    rest = np.bincount(group, weights=np.where(at_top, 0.0, np.exp(log_psi - top[group])), minlength=R * P)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(
            count > 0, np.log1p(np.where(count > 0, rest / np.maximum(count, 1), 0.0)) + np.log(np.maximum(count, 1)) + top, -np.inf
        )
    out = out.reshape(R, P)
    if uniform:
        out = out - np.where(k > 0, np.log(np.maximum(k, 1)), 0.0)[:, None]
    return out


def pruned(run, starts, log_psi, bounds, pruning) -> np.ndarray:
    """The entries kept when each test's entries are bounded to ``bounds`` (R,) (−1: unbounded) by the rule
    ``pruning`` (ties by order): "oldest" keeps the latest ``starts``, "nearest_lower" the largest ln ψ."""
    index = np.arange(run.size)
    order = np.lexsort((index, -starts if pruning == "oldest" else -log_psi, run))
    rank = np.empty_like(index)
    rank[order] = index - _offsets(np.bincount(run, minlength=bounds.size))[run[order]]
    limit = bounds[run]
    return (limit < 0) | (rank < limit)


class ChangeTimeSPRTBatch(ChangeTimeTestBatch):
    """R copies of :class:`ChangeTimeSPRT` as flat arrays over every run's entries (run by run): mode, change
    step and ln ψ per entry, k per run."""

    def __init__(self, detector: ChangeTimeSPRT, runs: int):
        self.detector = detector
        self.runs = int(runs)
        self.upper, self.lower, self.pruning = detector.upper, detector.lower, detector.pruning
        self.uniform = detector.averaging == "uniform"
        self.bank_size = detector.bank_size
        self.hypotheses: list = [detector.hypotheses] * self.runs
        self.run = np.zeros(0, dtype=int)
        self.modes = np.zeros(0, dtype=int)
        self.starts = np.zeros(0, dtype=int)
        self.log_psi = np.zeros(0)
        self.k = np.zeros(self.runs, dtype=int)

    @property
    def counts(self) -> np.ndarray:
        return np.bincount(self.run, minlength=self.runs)

    def _keep(self, mask: np.ndarray) -> None:
        self.run, self.modes, self.starts, self.log_psi = self.run[mask], self.modes[mask], self.starts[mask], self.log_psi[mask]

    def restart(self, runs, hypotheses) -> None:
        runs = np.asarray(runs, dtype=int)
        for r, names in zip(runs, hypotheses):
            self.hypotheses[r] = _check_hypotheses(names)
        self._keep(~np.isin(self.run, runs))
        self.k[runs] = 0

    def add(self, start: int) -> None:
        P = len(self.hypotheses[0]) - 1
        new = np.repeat(np.arange(self.runs), P)  # P entries per run, after the run's own (a stable sort by run)
        run = np.concatenate([self.run, new])
        order = np.argsort(run, kind="stable")
        self.run = run[order]
        self.modes = np.concatenate([self.modes, np.tile(np.arange(1, P + 1), self.runs)])[order]
        self.starts = np.concatenate([self.starts, np.full(new.size, int(start))])[order]
        self.log_psi = np.concatenate([self.log_psi, np.zeros(new.size)])[order]

    def observe(self, step, loglik0, loglik, nis0, nis, m) -> ChangeTimeStep:
        P = len(self.hypotheses[0]) - 1
        loglik0, loglik, m = np.asarray(loglik0, dtype=float), np.asarray(loglik, dtype=float), np.asarray(m)
        if loglik.size != self.run.size:
            raise ValueError(f"loglik: expected {self.run.size} entries, got {loglik.size}")
        self.k += 1
        self.log_psi = np.where(m[self.run] > 0, self.log_psi + (loglik - loglik0[self.run]), self.log_psi)
        ratios = change_log_ratios(self.run, self.modes, self.log_psi, self.k, P, self.uniform)
        decided, entry, start, decisions = rule(
            step, self.detector.label, self.hypotheses, ratios, self.run, self.modes, self.starts, self.log_psi, self.upper, self.lower
        )
        stay = decided == 0
        if stay.any():  # restart with the same (fixed) bank
            self.log_psi = np.where(stay[self.run], 0.0, self.log_psi)
            self.k[stay] = 0
        return ChangeTimeStep(ratios, decided, entry, start, tuple(decisions))

    def prune(self, runs, caps) -> np.ndarray:
        runs, caps = np.asarray(runs, dtype=int), np.asarray(caps, dtype=int)
        bounds = np.full(self.runs, -1)
        bounds[runs] = np.where(caps < 0, -1 if self.bank_size is None else self.bank_size, caps)
        if (bounds[runs] == 0).any():
            raise ValueError("bank_size: expected a positive integer, got 0")
        keep = pruned(self.run, self.starts, self.log_psi, bounds, self.pruning)
        self._keep(keep)
        return keep


class ChangeTimeSPRT(WaldThresholds, ChangeTimeTest):
    """Algorithm 3 of seed 000: log-likelihood ratios averaged over change times, rule (24), bank pruning."""

    name = "sprt_unknown_change"
    #: its alternatives are the filters Algorithm 3 starts at every step: on a fixed bank it decides at most once, late
    requires_bank_management = "unknown_change"

    def __init__(
        self,
        alpha: float = 0.05,
        beta: float = 0.05,
        hypotheses: Sequence[str] | None = None,
        averaging: str = "uniform",
        bank_size: int | None = None,
        pruning: str = "nearest_lower",
    ):
        self.set_error_probabilities(alpha, beta)
        self.hypotheses = None if hypotheses is None else _check_hypotheses(hypotheses)
        if averaging not in AVERAGING:
            raise ValueError(f"averaging: expected one of {AVERAGING}, got {averaging!r}")
        if pruning not in PRUNING_RULES:
            raise ValueError(f"pruning: expected one of {PRUNING_RULES}, got {pruning!r}")
        self.averaging = averaging
        self.bank_size = None if bank_size is None else check_positive_int(bank_size, "bank_size")
        self.pruning = pruning
        self.reset()

    # ------------------------------------------------------------------ bank bookkeeping
    def reset(self) -> None:
        """Start a new test: no entries, k = 0."""
        self.modes = np.zeros(0, dtype=int)  # alternative p of each entry (1 … M−1)
        self.starts = np.zeros(0, dtype=int)  # hypothesised change step j of each entry
        self.log_psi = np.zeros(0)
        self.k = 0
        self.alternatives: int | None = None if self.hypotheses is None else len(self.hypotheses) - 1
        self.decided: int | None = None
        self.chosen_entry: int | None = None
        self._last: tuple | None = None

    def add(self, modes: Sequence[int], start: int) -> None:
        """Append entries F_start^p for the alternatives ``modes`` (each in 1 … M−1), ln ψ = 0."""
        modes = np.asarray(modes, dtype=int).reshape(-1)
        if modes.size and modes.min() < 1:
            raise ValueError(f"modes: alternatives are numbered from 1 (0 is the current mode), got {modes.tolist()}")
        if self.alternatives is not None and modes.size and modes.max() > self.alternatives:
            raise ValueError(f"modes: alternative {modes.max()} beyond the {self.alternatives} alternatives")
        self.modes = np.concatenate([self.modes, modes])
        self.starts = np.concatenate([self.starts, np.full(modes.size, int(start))])
        self.log_psi = np.concatenate([self.log_psi, np.zeros(modes.size)])

    def keep(self, rows: np.ndarray) -> None:
        """Keep only the entries ``rows`` (indices into the entries, in order)."""
        rows = np.asarray(rows, dtype=int)
        self.modes, self.starts, self.log_psi = self.modes[rows], self.starts[rows], self.log_psi[rows]

    def prune(self, bank_size: int | None = None) -> np.ndarray:
        """Bound the entries to ``bank_size`` (default: the constructor's) by the pruning rule; returns the rows kept."""
        size = self.bank_size if bank_size is None else check_positive_int(bank_size, "bank_size")
        run = np.zeros(self.log_psi.size, dtype=int)
        rows = np.flatnonzero(pruned(run, self.starts, self.log_psi, np.array([-1 if size is None else size]), self.pruning))
        self.keep(rows)
        return rows

    # ------------------------------------------------------------------ the test
    def log_ratios(self) -> np.ndarray:
        """ln λ_p for p = 1 … M−1 (−inf for an alternative with no entry)."""
        P = self.alternatives or (int(self.modes.max()) if self.modes.size else 0)
        run = np.zeros(self.modes.size, dtype=int)
        return change_log_ratios(run, self.modes, self.log_psi, np.array([self.k]), P, self.averaging == "uniform")[0]

    def observe(self, step, loglik, nis, m) -> DetectorStep:
        loglik = np.atleast_1d(np.asarray(loglik, dtype=float))
        if self.decided is not None:  # decided: the final values, no further decision until reset()
            return DetectorStep(*self._last)
        if self.k == 0 and self.modes.size == 0 and loglik.size > 1:
            self.add(np.arange(1, loglik.size), step)  # a fixed bank: every alternative from the first step
        if loglik.size != 1 + self.modes.size:
            raise ValueError(
                f"loglik: expected {1 + self.modes.size} filters (the current mode and {self.modes.size} entries), got {loglik.size}"
            )
        self.k += 1
        if m > 0:
            self.log_psi = self.log_psi + (loglik[1:] - loglik[0])
        ratios = self.log_ratios()
        names = self.hypotheses or tuple(f"H{p}" for p in range(ratios.size + 1))
        run = np.zeros(self.modes.size, dtype=int)
        decided, entry, _, decisions = rule(
            step, self.label, [names], ratios[None], run, self.modes, self.starts, self.log_psi, self.upper, self.lower
        )
        output = ({"log_ratio": ratios, "bank_size": float(self.modes.size)}, {"upper": self.upper, "lower": self.lower}, decisions[0])
        if decided[0] == 0:  # restart with the same (fixed) bank
            self.log_psi = np.zeros_like(self.log_psi)
            self.k = 0
        elif decided[0] > 0:
            self.decided, self.chosen_entry = int(decided[0]), int(entry[0])
            self._last = (output[0], output[1], None)
        return DetectorStep(*output)

    def batch(self, runs: int) -> ChangeTimeSPRTBatch:
        """``runs`` copies of this test vectorized over the runs (each equal to a copy of this test)."""
        return ChangeTimeSPRTBatch(self, runs)


@hookimpl
def register_detectors(registry):
    registry.add(ChangeTimeSPRT.name, ChangeTimeSPRT)
