"""Seed 000 Algorithm 3, repeated: a change at an unknown time, the estimate follows the identified mode (SPEC §4).

Filter 0 runs the current mode; at every step one filter per alternative mode
is started from filter 0's estimate, hypothesising the change there; the
detector (default ``sprt_unknown_change``) averages the ratios over change
times and applies rule (24).  A change to p makes the most likely filter of p
the new filter 0 (the estimate follows it) and restarts the test; "no change"
(every ln λ ≤ B) restarts the test with filter 0 alone.  The bank is bounded
by ``bank_size`` alternative filters, pruned by the detector's rule
(``"oldest"`` or seed 003's ``"nearest_lower"``), or by Algorithm 4's estimate
(``bank_size="algorithm4"``, oldest first).  With the ``decentralized``
estimator every node's locally computed ℓ and NIS (seed 000 eq. 22) feed node
copies of the detector and of the signal function, kept beside the
centralized values.

One implementation over R runs on one :class:`~hybridtrack.engine.bank.FilterBank`;
:meth:`UnknownChangeAdaptive.run` is the batch of one (step convention and recording: :mod:`.bank_runs`).
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.algorithms.algorithm4 import algorithm4_bank_size, wald_pair
from hybridtrack.algorithms.bank_runs import run_alone, run_banks
from hybridtrack.algorithms.mode_sets import resolve_modes
from hybridtrack.core.components import require
from hybridtrack.core.interfaces import Estimator, Sensor
from hybridtrack.core.plugins import resolve
from hybridtrack.core.protocols import ChangeTimeTest, ScoreDetector
from hybridtrack.core.registry import Registry, registry_or_default
from hybridtrack.core.validation import check_positive_int
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.layouts import LayoutFill, union_layout
from hybridtrack.engine.pipeline import mode_labels
from hybridtrack.engine.results import RunResult
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import check_tau

__all__ = ["ChangeEvent", "UnknownChangeAdaptive", "UnknownChangeRun"]


@attrs.frozen
class ChangeEvent:
    """A detected change: at ``step`` the mode became ``mode``; the most likely change step was ``change_step``."""

    step: int
    mode: str
    change_step: int


@attrs.frozen(eq=False, kw_only=True)
class UnknownChangeRun(RunResult):
    """Algorithm 3 repeated: ``mode`` (K+1,) the mode followed per step (index into ``modes``), ln λ per mode
    (K+1, M; NaN for the current mode and at step 0), the bank size (number of filters) per step, the signal
    function of filter 0 and its bounds, the detected changes, the thresholds A (``upper``), B (``lower``) and
    the bank limit; with a decentralized estimator the same series computed at each node (K+1, N, …);
    ``hypothesis_positions`` (K+1, M, 2), kept only when the run is recorded: the position of each alternative
    mode's most likely filter (largest ψ over its change times) at every step, NaN for the current mode."""

    log_ratios: np.ndarray
    bank_sizes: np.ndarray
    signal: np.ndarray
    signal_bounds: np.ndarray
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


def _entries(test, r: int) -> tuple[np.ndarray, np.ndarray]:
    """(alternative p, ln ψ) of run ``r``'s entries in a change-time test batch: the flat arrays of a vectorized
    batch (``sprt_unknown_change``), else run r's copy's."""
    if hasattr(test, "log_psi"):
        mine = test.run == r
        return test.modes[mine], test.log_psi[mine]
    return np.asarray(test.copies[r].modes), np.asarray(test.copies[r].log_psi)


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

    Modes of different state layouts (the 4-state modes beside ``coordinated_turn`` with ω, or the 6-state
    constant acceleration) share one bank in their union layout (:mod:`hybridtrack.engine.layouts`): a
    hypothesis of another layout starts from the current estimate with each component it adds at
    ``missing_mean``, ``missing_variance`` (a number, or component → value, e.g. ``{"omega": 1e-4}``), and the
    estimate and the outputs are in the union layout.  ``bank_size="algorithm4"`` needs modes of one layout.
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
        missing_mean: float | Mapping[str, float] = 0.0,
        missing_variance: float | Mapping[str, float] = 1.0,
    ):
        registry = registry_or_default(registry)
        self.models = resolve_modes(modes, registry, one_layout=False)
        if len(self.models) < 2:
            raise ValueError(f"modes: a change needs at least two modes, got {len(self.models)}")
        self.labels = mode_labels(self.models)
        self.layout = union_layout([m.layout for m in self.models])
        self.missing = {"missing_mean": missing_mean, "missing_variance": missing_variance}
        LayoutFill(self.layout, **self.missing)  # checked here, named in the error
        if isinstance(initial_mode, bool) or not isinstance(initial_mode, (int, np.integer)) or not 0 <= initial_mode < len(self.models):
            raise ValueError(f"initial_mode: expected an index in 0 … {len(self.models) - 1}, got {initial_mode!r}")
        self.initial_mode = int(initial_mode)
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.tau = None if tau is None else check_tau(tau)
        self.estimator: Estimator = resolve("estimator", estimator, registry)
        spec = detector if detector is not None else ("sprt_unknown_change", {"alpha": alpha, "beta": beta})
        needs = "detector (Algorithm 3 needs a change-time test, e.g. 'sprt_unknown_change')"
        self.detector = require(resolve("detector", spec, registry), ChangeTimeTest, needs)
        if pruning is not None:
            if pruning not in ChangeTimeTest.PRUNING_RULES:
                raise ValueError(f"pruning: expected one of {ChangeTimeTest.PRUNING_RULES}, got {pruning!r}")
            self.detector.pruning = pruning
        if isinstance(bank_size, str):
            if bank_size != "algorithm4":
                raise ValueError(f"bank_size: expected a positive integer, 'algorithm4' or None, got {bank_size!r}")
            if pruning is None:
                self.detector.pruning = "oldest"
            if len({m.layout for m in self.models}) > 1:
                raise ValueError(f"bank_size: 'algorithm4' needs modes of one state layout, got {sorted({m.layout for m in self.models})}")
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
        H, R = self.network.jacobian(x_s, self.layout), self.network.noise_cov()
        alpha, beta = self.detector.alpha, self.detector.beta
        fixed = [(t.F, t.B, t.process_noise) for t in (model.transition(dt, x_s) for model in self.models)]
        base = fixed[self.initial_mode]
        pairs = [wald_pair(base, f, H, R, x_s, alpha, beta, horizon=horizon) for p, f in enumerate(fixed) if p != self.initial_mode]
        return algorithm4_bank_size(pairs) * (len(self.models) - 1)

    def _algorithm4_cached(self, switch_state, dt) -> int:
        key = (np.asarray(switch_state, dtype=float).tobytes(), dt, self.detector.alpha, self.detector.beta)
        cache = self.__dict__.setdefault("_algorithm4", {})
        if key not in cache:
            cache[key] = self.algorithm4_bank_size(switch_state, dt=dt)
        return cache[key]

    # ------------------------------------------------------------------ the run
    def run(self, measurements: Mapping[str, np.ndarray], prior, *, times=None, recorder=None, truth=None) -> UnknownChangeRun:
        """Algorithm 3, repeated, on measurements of steps 0 … K at ``times`` (seconds; default 0, τ, 2τ, …):
        the :meth:`run_batch` of one run."""
        return run_alone(self, measurements, prior, times=times, recorder=recorder, truth=truth)

    def run_batch(self, measurements: Mapping[str, np.ndarray], prior, *, times=None, truth=None, recorders=None) -> list[UnknownChangeRun]:
        """Algorithm 3, repeated, on R runs at once (the inputs and the recording as
        :func:`~hybridtrack.algorithms.bank_runs.run_banks` takes them).

        Every run's growing bank lives in one
        :class:`~hybridtrack.engine.bank.FilterBank` (run by run): the new
        filters of all runs are added, and decisions and pruning applied, by
        one index array per step through the estimator's ``take``.  The
        change-time test runs as ``detector.batch(R)``; the signal function and
        a decentralized estimator's node copies keep one copy per run.
        """
        signal = None if self.signal is None else self.signal.label
        return run_banks(self, self._runs, measurements, prior, times, truth, recorders, signal=signal)

    def _runs(self, z, t, dt, x0, P0, recorded: list[int]) -> list[UnknownChangeRun]:
        """Algorithm 3, repeated, on the R runs of one bank (``runs_of`` of
        :func:`~hybridtrack.algorithms.bank_runs.run_banks`)."""
        R, K = z.shape[0], z.shape[1] - 1
        n, M = len(self.layout), len(self.models)
        runs = np.arange(R)
        limits = [
            self._algorithm4_cached(x0[r], float(dt[r, 0]) if K else self.tau) if self.bank_size == "algorithm4" else self.bank_size
            for r in runs
        ]
        test = self.detector.batch(R)  # Algorithm 3's test of every run (vectorized for sprt_unknown_change)
        signals = None if self.signal is None else self.signal.batch(R)  # the signal function of every run
        capped = np.zeros(R, dtype=bool)
        means, covs = np.zeros((R, K + 1, n)), np.zeros((R, K + 1, n, n))
        mode = np.zeros((R, K + 1), dtype=int)
        ratios = np.full((R, K + 1, M), np.nan)
        bank_sizes = np.zeros((R, K + 1), dtype=int)
        signal_values = np.full((R, K + 1), np.nan)
        bounds = np.full((R, K + 1, 2), np.nan)
        decisions, changes = [[] for _ in runs], [[] for _ in runs]
        position = [self.layout.index("x"), self.layout.index("y")]
        fans = {r: np.full((K + 1, M, 2), np.nan) for r in recorded}  # only the recorded runs keep them
        current = np.full(R, self.initial_mode)
        others = np.array([[i for i in range(M) if i != c] for c in range(M)])  # the alternatives of each current mode
        names = [(self.labels[c],) + tuple(self.labels[i] for i in others[c]) for c in range(M)]
        test.restart(runs, [names[self.initial_mode]] * R)
        bank = FilterBank(self.estimator, self.layout, self.network.sensors, **self.missing)
        bank.start(x0, P0, [self.models[self.initial_mode]] * R, x0, runs)
        scores = bank.step(None, z[:, 0])

        def observe_signals(k, loglik, nis, m):
            """The signal function of every run on its current filter's scores (R,), the runs grouped by m."""
            for dim in np.unique(m):
                group = np.flatnonzero(m == dim)
                for r, s in zip(group, signals.observe(k, group, loglik[group, None], nis[group, None], int(dim))):
                    signal_values[r, k], bounds[r, k] = s.statistics["signal"][0], (s.thresholds["lower"], s.thresholds["upper"])

        if signals is not None:
            for signal in signals.copies:
                signal.reset()
            observe_signals(0, scores.loglik, scores.nis, scores.m)
        means[:, 0], covs[:, 0], mode[:, 0], bank_sizes[:, 0] = bank.means, bank.covs, current, 1
        nodes = self._start_nodes(bank, names[self.initial_mode], K, scores.m)
        for k in range(1, K + 1):
            # 1. one new filter per alternative in every run, hypothesising the change at k: copies of its filter 0
            offsets = bank.offsets
            alternatives = others[current]
            bank.add(
                np.repeat(offsets, M - 1), [self.models[i] for i in alternatives.reshape(-1)], np.repeat(bank.means[offsets], M - 1, axis=0)
            )
            test.add(k)
            if nodes is not None:
                for d in (d for tests in nodes[0] for d in tests):
                    d.add(np.arange(1, M), k)
            # 2. one step of the whole bank, then every run's ratios (25) and rule (24)
            scores = bank.step(dt[:, k - 1], z[:, k])
            offsets, sizes = bank.offsets, bank.sizes
            entries = np.ones(len(bank), dtype=bool)
            entries[offsets] = False
            entry_rows = np.flatnonzero(entries)
            loglik, nis, m = scores.loglik, scores.nis, scores.m
            out = test.observe(k, loglik[offsets], loglik[entry_rows], nis[offsets], nis[entry_rows], m[offsets])
            ratios[runs[:, None], k, alternatives] = out.log_ratio
            bank_sizes[:, k] = sizes
            for r, fan in fans.items():  # each alternative's most likely filter (entry e of run r is bank row offsets[r] + 1 + e)
                if out.decided[r] == 0:  # "no change" accepted: no alternative in play (the test has restarted)
                    continue
                entry_modes, log_psi = _entries(test, r)
                for p, mode_index in enumerate(alternatives[r], start=1):
                    rows = np.flatnonzero(entry_modes == p)
                    if rows.size:
                        fan[k, mode_index] = bank.means[offsets[r] + 1 + rows[np.argmax(log_psi[rows])], position]
            if signals is not None:
                observe_signals(k, loglik[offsets], nis[offsets], m[offsets])
            if nodes is not None:
                self._observe_nodes(nodes, bank, k, alternatives, m)
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
                            stacklevel=3,
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
            if nodes is not None:  # the node copies keep the entries the test kept
                for r in open_:
                    for d in nodes[0][r]:
                        d.keep(np.flatnonzero(kept[bank.run[entry_rows] == r]))
            done = np.flatnonzero(out.decided >= 0)
            for r in done:
                decisions[r].append(attrs.evolve(out.decisions[r], time=float(t[r, k])))
                if out.decided[r] > 0:  # a change to alternatives[p − 1], followed by its most likely filter
                    current[r] = alternatives[r, out.decided[r] - 1]
                    changes[r].append(ChangeEvent(k, self.labels[current[r]], int(out.chosen_start[r])))
                    keep[offsets[r] + 1 + out.chosen_entry[r]] = True
                    for signal in ([] if signals is None else [signals.copies[r]]) + ([] if nodes is None else nodes[1][r]):
                        signal.reset()
                else:  # H_0 accepted: the test restarts with filter 0 alone
                    keep[offsets[r]] = True
                if nodes is not None:
                    for d in nodes[0][r]:
                        d.hypotheses = names[current[r]]
                        d.reset()
            if done.size:
                test.restart(done, [names[c] for c in current[done]])
            bank.take(np.flatnonzero(keep))
            first = bank.offsets
            means[:, k], covs[:, k], mode[:, k] = bank.means[first], bank.covs[first], current
        return [
            UnknownChangeRun(
                layout=self.layout,
                modes=self.labels,
                times=t[r],
                means=means[r],
                covs=covs[r],
                mode=mode[r],
                decisions=tuple(decisions[r]),
                log_ratios=ratios[r],
                bank_sizes=bank_sizes[r],
                signal=signal_values[r],
                signal_bounds=bounds[r],
                changes=tuple(changes[r]),
                upper=float(test.upper),
                lower=float(test.lower),
                bank_limit=limits[r],
                node_log_ratios=None if nodes is None else nodes[2][r],
                node_signal=None if nodes is None else nodes[3][r],
                hypothesis_positions=fans.get(r),
            )
            for r in runs
        ]

    def _start_nodes(self, bank: FilterBank, hypotheses: tuple[str, ...], K: int, m: np.ndarray):
        """A decentralized estimator's node copies of the test and the signal function per run, from the node
        scores of step 0: (tests [r][i], signals [r][i], ln λ (R, K+1, N, M), signal (R, K+1, N)); None when
        the estimator gives no node scores."""
        scores = bank.node_scores()
        if scores is None:
            return None
        N, R, M = scores[0].shape[0], bank.runs, len(self.models)
        proto = copy.deepcopy(self.detector)
        proto.hypotheses = hypotheses
        proto.reset()
        tests = [[copy.deepcopy(proto) for _ in range(N)] for _ in range(R)]
        signals = [[] if self.signal is None else [copy.deepcopy(self.signal) for _ in range(N)] for _ in range(R)]
        node_ratios, node_signal = np.full((R, K + 1, N, M), np.nan), np.full((R, K + 1, N), np.nan)
        for r, row in enumerate(bank.offsets):
            for i, ns in enumerate(signals[r]):
                ns.reset()
                out = ns.observe(0, scores[0][i, row : row + 1], scores[1][i, row : row + 1], int(m[row]))
                node_signal[r, 0, i] = out.statistics["signal"][0]
        return tests, signals, node_ratios, node_signal

    def _observe_nodes(self, nodes, bank: FilterBank, k: int, alternatives: np.ndarray, m: np.ndarray) -> None:
        """Feed every node's copies the ℓ and NIS that node computed for its run's filters (zero when nothing
        was measured)."""
        tests, signals, node_ratios, node_signal = nodes
        scores = bank.node_scores()
        N = len(tests[0])
        if scores is None:
            scores = (np.zeros((N, len(bank))), np.zeros((N, len(bank))))
        for r, (row, size) in enumerate(zip(bank.offsets, bank.sizes)):
            block, dim = slice(row, row + size), int(m[row])
            for i, d in enumerate(tests[r]):
                d.observe(k, scores[0][i, block], scores[1][i, block], dim)
                node_ratios[r, k, i, alternatives[r]] = d.log_ratios()
            for i, ns in enumerate(signals[r]):
                node_signal[r, k, i] = ns.observe(k, scores[0][i, row : row + 1], scores[1][i, row : row + 1], dim).statistics["signal"][0]
