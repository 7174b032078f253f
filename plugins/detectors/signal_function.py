"""Signal function detector: the standardized χ² statistic of the NIS with ±c bounds (SPEC §4; seed 000 eqs. 22–23).

For every filter j of the watched bank, over the steps since the last reset
(``window=None``) or the last ``window`` measured steps:

    S_j = (Σ NIS_j − D) / √(2D),   D = Σ m_k,

compared with bounds for a two-sided per-step false-alarm probability
``alpha`` (default 2(1 − Φ(3)), i.e. the 3σ rule ±3; see
:mod:`hybridtrack_plugins.detectors.signal_bounds` for the ``"chi2"`` calibration).
A value of filter ``watch`` outside the bounds is an alarm ("change"); with
``reset_on_alarm`` the accumulation restarts after it.

Decentralized use: node i of the decentralized information filter computes
NIS from its own (x⁻, I⁻, x⁺, I⁺) and the broadcast Σ_j z_jᵀR_j⁻¹z_j (seed 000
eq. 22); feeding those values to :meth:`observe` gives node i's signal
function, equal to the centralized one (tests/plugins/test_detectors_signal.py).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import DetectorStep
from hybridtrack.core.protocols import ScoreDetector, ScoreDetectorBatch
from hybridtrack.core.types import Decision
from hybridtrack.core.validation import check_positive_int
from hybridtrack.sdk.thresholds import THREE_SIGMA_ALPHA, check_probability
from hybridtrack_plugins.detectors import signal_bounds


class SignalFunction(ScoreDetector):
    """Standardized χ² signal function of the NIS, cumulative or sliding-window, with ±c bounds."""

    name = "signal_function"

    def __init__(
        self,
        window: int | None = None,
        alpha: float = THREE_SIGMA_ALPHA,
        calibration: str = "normal",
        watch: int = 0,
        reset_on_alarm: bool = True,
    ):
        self.window = None if window is None else check_positive_int(window, "window")
        if calibration not in signal_bounds.CALIBRATIONS:
            raise ValueError(f"calibration: expected one of {signal_bounds.CALIBRATIONS}, got {calibration!r}")
        self.calibration = calibration
        self.alpha = alpha
        self.watch = check_positive_int(watch, "watch", minimum=0)
        self.reset_on_alarm = bool(reset_on_alarm)
        self.reset()

    @property
    def alpha(self) -> float:
        """Two-sided per-step false-alarm probability; setting it moves the bounds (dynamic thresholds)."""
        return self._alpha

    @alpha.setter
    def alpha(self, value) -> None:
        self._alpha = check_probability(value, "alpha")

    def reset(self) -> None:
        self._sum = None  # Σ NIS per filter (cumulative mode)
        self._dof = 0.0
        self._recent: deque = deque()  # (nis (M,), m) of the last `window` measured steps

    def _accumulate(self, nis: np.ndarray, m: int) -> tuple[np.ndarray, float]:
        if self._sum is None:
            self._sum = np.zeros_like(nis)
        if self._sum.shape != nis.shape:
            raise ValueError(f"nis: the watched bank changed from {self._sum.shape[0]} to {nis.shape[0]} filters; call reset() first")
        if m > 0:
            if self.window is None:
                self._sum = self._sum + nis
                self._dof += m
            else:
                self._recent.append((nis, m))
                if len(self._recent) > self.window:
                    self._recent.popleft()
                self._sum = np.sum([v for v, _ in self._recent], axis=0)
                self._dof = float(sum(k for _, k in self._recent))
        return self._sum, self._dof

    def observe(self, step, loglik, nis, m) -> DetectorStep:
        nis = np.atleast_1d(np.asarray(nis, dtype=float))
        if self.watch >= nis.shape[0]:
            raise ValueError(f"watch: filter {self.watch} is not in a bank of {nis.shape[0]} filters")
        total, dof = self._accumulate(nis, int(m))
        signal = signal_bounds.standardize(total, dof)
        lower, upper = signal_bounds.bounds(self.alpha, dof, self.calibration)
        return self._output(step, signal, dof, lower, upper)

    def _output(self, step, signal: np.ndarray, dof: float, lower: float, upper: float) -> DetectorStep:
        """The step's output from S (M,) and its bounds: a change when D > 0 and the watched S leaves
        [lower, upper] (then a reset if ``reset_on_alarm``)."""
        value = float(signal[self.watch])
        decision = None
        if dof > 0 and not (lower <= value <= upper):
            side = "above" if value > upper else "below"
            decision = Decision(
                step, self.label, "change", value, f"signal function {value:.2f} {side} the bound ({lower:.2f}, {upper:.2f}), D = {dof:g}"
            )
            if self.reset_on_alarm:
                self.reset()
        return DetectorStep({"signal": signal.copy(), "dof": dof}, {"upper": upper, "lower": lower}, decision)

    def batch(self, runs: int) -> SignalFunctionBatch:
        """``runs`` copies of this detector, vectorized over the runs when cumulative (:class:`SignalFunctionBatch`)."""
        return SignalFunctionBatch(self, runs)


class SignalFunctionBatch(ScoreDetectorBatch):
    """R copies of a :class:`SignalFunction` fed together: for a cumulative one, Σ NIS, D, S and the bounds (one
    quantile per distinct D) over the runs at once; a windowed one (or a subclass) steps the copies one by one.
    Equal to ``observe`` run by run (the same arithmetic per element)."""

    def observe(self, step, runs, loglik, nis, m) -> list[DetectorStep]:
        first = self.detector
        if first.window is not None or type(first) is not SignalFunction:
            return super().observe(step, runs, loglik, nis, m)
        detectors = [self.copies[int(r)] for r in runs]
        nis = np.asarray(nis, dtype=float)
        R, M = nis.shape
        if first.watch >= M:
            raise ValueError(f"watch: filter {first.watch} is not in a bank of {M} filters")
        for d in detectors:
            if d._sum is not None and d._sum.shape != (M,):
                raise ValueError(f"nis: the watched bank changed from {d._sum.shape[0]} to {M} filters; call reset() first")
        totals = np.stack([np.zeros(M) if d._sum is None else d._sum for d in detectors])
        dofs = np.array([d._dof for d in detectors], dtype=float)
        m = int(m)
        if m > 0:
            totals = totals + nis
            dofs = dofs + m
        signals = signal_bounds.standardize(totals, dofs[:, None])
        if first.calibration == "normal":  # ±Φ⁻¹(1 − α/2) whatever D: one quantile for all runs
            common = signal_bounds.bounds(first.alpha, 0.0, "normal")
            limits = {dof: common for dof in np.unique(dofs)}
        else:
            limits = {dof: signal_bounds.bounds(first.alpha, float(dof), first.calibration) for dof in np.unique(dofs)}
        outputs = []
        for r, d in enumerate(detectors):
            d._sum, d._dof = totals[r], float(dofs[r])
            lower, upper = limits[dofs[r]]
            outputs.append(d._output(step, signals[r], float(dofs[r]), lower, upper))
        return outputs


@hookimpl
def register_detectors(registry):
    registry.add(SignalFunction.name, SignalFunction)
