"""Signal function detector: the standardized χ² statistic of the NIS with ±c bounds (SPEC §4; seed 000 eqs. 22–23).

For every filter j of the watched bank, over the steps since the last reset
(``window=None``) or the last ``window`` measured steps:

    S_j = (Σ NIS_j − D) / √(2D),   D = Σ m_k,

compared with bounds for a two-sided per-step false-alarm probability
``alpha`` (default 2(1 − Φ(3)), i.e. the 3σ rule ±3; see
:mod:`hybridtrack_plugins.detectors.signal_bounds` for the ``"chi2"`` calibration).
A value of filter ``watch`` outside the bounds is an alarm ("change"); with
``reset_on_alarm`` the accumulation restarts after it.

Decentralized use: node i's NIS from its own (x⁻, I⁻, x⁺, I⁺) and the broadcast Σ_j z_jᵀR_j⁻¹z_j
(seed 000 eq. 22; docs/detectors.md) fed to :meth:`observe` give its signal function, equal to the
centralized one (tests/plugins/test_detectors_signal.py).
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
        self._sum = None  # Σ NIS per filter
        self._dof = 0.0
        self._recent: deque = deque(maxlen=self.window)  # (nis (M,), m) of the last `window` measured steps

    def observe(self, step, loglik, nis, m) -> DetectorStep:
        return observe_copies(step, [self], np.atleast_1d(np.asarray(nis, dtype=float))[None], int(m))[0]

    def batch(self, runs: int) -> SignalFunctionBatch:
        """``runs`` copies of this detector, vectorized over the runs (:class:`SignalFunctionBatch`)."""
        return SignalFunctionBatch(self, runs)


def observe_copies(step, detectors: list[SignalFunction], nis: np.ndarray, m: int) -> list[DetectorStep]:
    """One step of U copies of a :class:`SignalFunction` on NIS (U, M): Σ NIS and D of each, S and the bounds
    (one quantile per distinct D) of all at once; a change when D > 0 and the watched S leaves [lower, upper]
    (then a reset if ``reset_on_alarm``)."""
    first = detectors[0]
    M = nis.shape[1]
    if first.watch >= M:
        raise ValueError(f"watch: filter {first.watch} is not in a bank of {M} filters")
    for d in detectors:
        if d._sum is not None and d._sum.shape != (M,):
            raise ValueError(f"nis: the watched bank changed from {d._sum.shape[0]} to {M} filters; call reset() first")
    for d, values in zip(detectors, nis):
        if first.window is not None and m > 0:
            d._recent.append((values, m))
            d._sum = np.sum([v for v, _ in d._recent], axis=0)
            d._dof = float(sum(k for _, k in d._recent))
    totals = np.stack([np.zeros(M) if d._sum is None else d._sum for d in detectors])
    dofs = np.array([d._dof for d in detectors], dtype=float)
    if first.window is None and m > 0:
        totals, dofs = totals + nis, dofs + m
    signals = signal_bounds.standardize(totals, dofs[:, None])
    if first.calibration == "normal":  # ±Φ⁻¹(1 − α/2) whatever D: one quantile for all runs
        limits = dict.fromkeys(np.unique(dofs), signal_bounds.bounds(first.alpha, 0.0, "normal"))
    else:
        limits = {dof: signal_bounds.bounds(first.alpha, float(dof), first.calibration) for dof in np.unique(dofs)}
    outputs = []
    for d, total, signal, dof in zip(detectors, totals, signals, dofs):
        d._sum, d._dof = total, float(dof)
        lower, upper = limits[dof]
        value = float(signal[first.watch])
        decision = None
        if dof > 0 and not (lower <= value <= upper):
            side = "above" if value > upper else "below"
            message = f"signal function {value:.2f} {side} the bound ({lower:.2f}, {upper:.2f}), D = {dof:g}"
            decision = Decision(step, d.label, "change", value, message)
            if d.reset_on_alarm:
                d.reset()
        outputs.append(DetectorStep({"signal": signal.copy(), "dof": d._dof}, {"upper": upper, "lower": lower}, decision))
    return outputs


class SignalFunctionBatch(ScoreDetectorBatch):
    """R copies of a :class:`SignalFunction` fed together by :func:`observe_copies` (a subclass: one by one).
    Equal to ``observe`` run by run (the same arithmetic per element)."""

    def observe(self, step, runs, loglik, nis, m) -> list[DetectorStep]:
        if type(self.detector) is not SignalFunction:
            return super().observe(step, runs, loglik, nis, m)
        return observe_copies(step, [self.copies[int(r)] for r in runs], np.asarray(nis, dtype=float), int(m))


@hookimpl
def register_detectors(registry):
    registry.add(SignalFunction.name, SignalFunction)
