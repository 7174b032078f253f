"""``cumulative_llr``: a change-time SPRT with a GLR-style maximum over change times.

Written only against ``hybridtrack.core.interfaces``, ``hybridtrack.core.protocols`` and ``hybridtrack.sdk.thresholds``.

H_0: the current mode (row 0 of the bank) goes on; H_p (p = 1 … M−1): the mode
changed to p at some unknown step.  Each entry e (an alternative p and a
hypothesised change step j, one filter of the bank) accumulates

    ln ψ_e(k) = ln ψ_e(k−1) + ℓ_e(k) − ℓ_0(k),     ln ψ_e = 0 when the entry is added,

and the ratio of alternative p is the largest over its entries (the
generalized-likelihood choice of the change time, where the built-in
``sprt_unknown_change`` averages over change times):

    ln λ_p = max_{e of p} ln ψ_e.

Wald's rule with A = ln((1−β)/α) (``upper``), B = ln(β/(1−α)) (``lower``):
max_p ln λ_p ≥ A → change to that p (``decided = p``, ``chosen_entry`` its
entry with the largest ln ψ); every ln λ_p ≤ B → "no change" (``decided = 0``);
otherwise continue.  After a decision the output is frozen until ``reset()``.

Two ways to drive it:

* a growing bank (:class:`~hybridtrack.algorithms.unknown_change.UnknownChangeAdaptive`):
  the driver calls :meth:`add` before each step; rows 1 … E of the scores are
  the entries in the order added; ``statistics["log_ratio"]`` is ln λ_p for
  p = 1 … M−1; :meth:`prune` bounds the entries (``"oldest"``: drop the
  entries started longest ago; ``"nearest_lower"``: drop the smallest ln ψ,
  those nearest B);
* a fixed bank of M filters without :meth:`add` (a
  :class:`~hybridtrack.engine.pipeline.Pipeline`, or
  :class:`~hybridtrack.algorithms.known_switch.KnownSwitchAdaptive`): rows 1 … M−1
  are entries of alternatives 1 … M−1 started at the first step, and the test
  is one between the M hypotheses of the bank: ``statistics["log_ratio"]`` has
  one value per filter, (−max_p ln λ_p, ln λ_1, …, ln λ_{M−1}) — row 0 is
  H_0 against its strongest rival — with ``statistics["active"]`` 1 until the
  decision; ``decided`` is the index of the accepted filter (0 for H_0).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack.core.interfaces import DetectorStep
from hybridtrack.core.protocols import ChangeTimeTest
from hybridtrack.core.types import Decision
from hybridtrack.sdk.thresholds import WaldThresholds


class CumulativeLLR(WaldThresholds, ChangeTimeTest):
    """Change-time SPRT, ln λ_p = max over change times of the cumulative log-likelihood ratio."""

    name = "cumulative_llr"

    def __init__(
        self,
        alpha: float = 0.05,
        beta: float = 0.05,
        hypotheses: Sequence[str] | None = None,
        bank_size: int | None = None,
        pruning: str = "nearest_lower",
    ):
        self.set_error_probabilities(alpha, beta)
        self.hypotheses = None if hypotheses is None else tuple(str(h) for h in hypotheses)
        if pruning not in self.PRUNING_RULES:
            raise ValueError(f"pruning: expected one of {self.PRUNING_RULES}, got {pruning!r}")
        if bank_size is not None and (isinstance(bank_size, bool) or int(bank_size) != bank_size or bank_size < 1):
            raise ValueError(f"bank_size: expected a positive integer or None, got {bank_size!r}")
        self.pruning = pruning
        self.bank_size = None if bank_size is None else int(bank_size)
        self.reset()

    # ------------------------------------------------------------------ bookkeeping
    def reset(self) -> None:
        self.modes = np.zeros(0, dtype=int)  # the alternative p of each entry
        self.starts = np.zeros(0, dtype=int)  # its hypothesised change step
        self.log_psi = np.zeros(0)
        self.fixed_bank = False  # True once fed a bank without add(): one test between its M filters
        self.steps_seen = 0
        self.decided: int | None = None
        self.chosen_entry: int | None = None
        self._frozen: tuple | None = None

    def add(self, modes: Sequence[int], start: int) -> None:
        modes = np.asarray(modes, dtype=int).reshape(-1)
        if modes.size and modes.min() < 1:
            raise ValueError(f"modes: alternatives are numbered from 1 (0 is the current mode), got {modes.tolist()}")
        self.modes = np.concatenate([self.modes, modes])
        self.starts = np.concatenate([self.starts, np.full(modes.size, int(start))])
        self.log_psi = np.concatenate([self.log_psi, np.zeros(modes.size)])

    def keep(self, rows: Sequence[int]) -> None:
        rows = np.asarray(rows, dtype=int).reshape(-1)
        self.modes, self.starts, self.log_psi = self.modes[rows], self.starts[rows], self.log_psi[rows]

    def prune(self, bank_size: int | None = None) -> np.ndarray:
        size = self.bank_size if bank_size is None else int(bank_size)
        E = self.log_psi.size
        if size is None or E <= size:
            return np.arange(E)
        if self.pruning == "oldest":
            order = np.lexsort((np.arange(E), -self.starts))  # newest first
        else:
            order = np.lexsort((np.arange(E), -self.log_psi))  # largest ln ψ first: those nearest B go
        rows = np.sort(order[:size])
        self.keep(rows)
        return rows

    # ------------------------------------------------------------------ the test
    def _alternatives(self) -> int:
        if self.hypotheses is not None:
            return len(self.hypotheses) - 1
        return int(self.modes.max()) if self.modes.size else 0

    def log_ratios(self) -> np.ndarray:
        """ln λ_p = max over the entries of p of ln ψ, p = 1 … M−1 (−inf for an alternative without entries)."""
        out = np.full(self._alternatives(), -np.inf)
        for p in range(1, out.size + 1):
            values = self.log_psi[self.modes == p]
            if values.size:
                out[p - 1] = values.max()
        return out

    def _name(self, index: int) -> str:
        if self.hypotheses is not None and index < len(self.hypotheses):
            return self.hypotheses[index]
        return f"H{index}"

    def observe(self, step, loglik, nis, m) -> DetectorStep:
        if self._frozen is not None:  # decided: report the final values until reset()
            return DetectorStep(*self._frozen)
        loglik = np.atleast_1d(np.asarray(loglik, dtype=float))
        if self.steps_seen == 0 and self.modes.size == 0 and loglik.size > 1:
            self.add(np.arange(1, loglik.size), step)  # a fixed bank: every alternative from the first step
            self.fixed_bank = True
        if loglik.size != 1 + self.modes.size:
            raise ValueError(f"loglik: expected {1 + self.modes.size} filters (the current mode and its entries), got {loglik.size}")
        if self.hypotheses is not None and self.fixed_bank and len(self.hypotheses) != loglik.size:
            raise ValueError(f"hypotheses: {len(self.hypotheses)} names for a bank of {loglik.size} filters")
        self.steps_seen += 1
        if m > 0:
            self.log_psi = self.log_psi + (loglik[1:] - loglik[0])
        ratios = self.log_ratios()
        decision = None
        best = float(ratios.max()) if ratios.size else -np.inf
        if best >= self.upper:
            p = int(np.argmax(ratios)) + 1
            rows = np.flatnonzero(self.modes == p)
            self.chosen_entry = int(rows[np.argmax(self.log_psi[rows])])
            self.decided = p
            start = int(self.starts[self.chosen_entry])
            message = f"change to {self._name(p)} (most likely at step {start}), ln λ = {best:.2f} ≥ A = {self.upper:.2f}"
            decision = Decision(step, self.label, self._name(p), best, message)
        elif ratios.size and best <= self.lower:
            self.decided = 0
            decision = Decision(step, self.label, self._name(0), best, f"no change: every ln λ ≤ B = {self.lower:.2f}")
        thresholds = {"upper": self.upper, "lower": self.lower}
        if self.fixed_bank:
            statistics = {
                "log_ratio": np.concatenate([[-best], ratios]),
                "active": np.full(ratios.size + 1, 0.0 if self.decided is not None else 1.0),
            }
        else:
            statistics = {"log_ratio": ratios, "entries": float(self.modes.size)}
        if self.decided is not None:
            self._frozen = (statistics, thresholds, None)
        return DetectorStep(statistics, thresholds, decision)
