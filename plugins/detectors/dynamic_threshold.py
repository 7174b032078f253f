"""Dynamic threshold driven by an indirect maneuver cue (seed 003 eqs. 2–4, 7; SPEC §4).

A cue C raises the prior odds of a maneuver by L_C = P(C | maneuver)/P(C | none).
Keeping the posterior odds on an alarm unchanged gives the false-alarm level
α₁ = α·L_C (same power), so while the cue holds the wrapped detector's
threshold moves from λ(α) to λ(α₁) (seed 003 eq. 4: λ_k = λ_start without the
cue, λ_ready with it).  Any detector whose threshold is a function of a
settable ``alpha`` can be wrapped (GLR, CUSUM, the signal function, the SPRTs).

Cues (objects with ``reset()`` and ``update(step, value) -> bool``; the
built-in ones are in :data:`CUES`):

* ``speed_drop`` (seed 003 eq. 7): the cue holds when the current speed
  v_k < (1 − Δ)·v̄, v̄ the mean speed over steps k − 60 … k − 30 (``lags``).

The cue's input (e.g. the estimated speed) is given by :meth:`DynamicThreshold.feed_cue`
before the step; a wrapper never fed behaves as the wrapped detector at α.
"""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Detector, DetectorStep, Innovation
from hybridtrack.core.registry import registry_or_default
from hybridtrack.core.validation import check_positive, check_positive_int
from hybridtrack.sdk.thresholds import check_probability


class SpeedDropCue:
    """Speed loss in a turn (seed 003 eq. 7): v_k < (1 − Δ) · mean(v_{k−60} … v_{k−30})."""

    name = "speed_drop"

    def __init__(self, drop: float = 0.05, lags: tuple[int, int] = (60, 30)):
        self.drop = check_probability(drop, "drop")
        far, near = (check_positive_int(v, "lags") for v in lags)
        if near >= far:
            raise ValueError(f"lags: expected (far, near) with far > near, got {lags!r}")
        self.lags = (far, near)
        self.reset()

    def reset(self) -> None:
        self._speeds: list[float] = []

    def update(self, step: int, speed: float) -> bool:
        """Record this step's speed; True when it is below (1 − Δ) times the reference mean."""
        self._speeds.append(float(speed))
        far, near = self.lags
        if len(self._speeds) <= far:
            return False
        reference = float(np.mean(self._speeds[-far - 1 : -near]))  # steps k−far … k−near
        return self._speeds[-1] < (1.0 - self.drop) * reference


#: cue name → factory (cues are small objects, not a registry kind)
CUES = {SpeedDropCue.name: SpeedDropCue}


def _cue(spec):
    if hasattr(spec, "update") and hasattr(spec, "reset"):
        return spec
    if isinstance(spec, str):
        spec = (spec, {})
    if not (isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], str)):
        raise ValueError(f"cue: expected a cue name, (name, parameters) or an object with update() and reset(), got {spec!r}")
    if spec[0] not in CUES:
        raise ValueError(f"cue: unknown cue {spec[0]!r}; known: {sorted(CUES)}")
    return CUES[spec[0]](**spec[1])


class DynamicThreshold(Detector):
    """Wraps a detector: α while the cue is absent, α·L_C while it holds (seed 003)."""

    name = "dynamic_threshold"

    def __init__(self, detector: Any = "glr", cue: Any = "speed_drop", likelihood_ratio: float = 4.0, registry=None):
        """``detector`` a Detector or a spec resolved in ``registry`` (the one this detector was built from;
        the default registry when None)."""
        self.detector: Detector = (
            detector if isinstance(detector, Detector) else registry_or_default(registry).resolve("detector", detector)
        )
        if not hasattr(self.detector, "alpha"):
            raise ValueError(f"detector: {self.detector.name!r} has no settable 'alpha'; its threshold must be a function of α")
        self.cue = _cue(cue)
        self.likelihood_ratio = check_positive(likelihood_ratio, "likelihood_ratio")
        self.alpha_start = float(self.detector.alpha)
        self.alpha_ready = self.alpha_start * self.likelihood_ratio
        if not 0.0 < self.alpha_ready < 1.0:
            raise ValueError(
                f"likelihood_ratio: α·L_C = {self.alpha_start} × {self.likelihood_ratio} = {self.alpha_ready} is not a probability in (0, 1)"
            )
        # λ(α), the threshold without the cue, reported beside the current one (recorded as static vs dynamic)
        threshold_for = getattr(self.detector, "threshold_for", None)
        self.static_thresholds = {} if threshold_for is None else {"static_threshold": float(threshold_for(self.alpha_start))}
        self.reset()

    @property
    def requires_bank_management(self) -> str | None:
        """The wrapped detector's (the bank it needs is the wrapped test's)."""
        return getattr(self.detector, "requires_bank_management", None)

    def reset(self) -> None:
        self.detector.reset()
        self.cue.reset()
        self.holds = False
        self._apply()

    def _apply(self) -> None:
        wanted = self.alpha_ready if self.holds else self.alpha_start
        if self.detector.alpha != wanted:
            self.detector.alpha = wanted

    def feed_cue(self, step: int, value: float) -> bool:
        """Give the cue its input for this step (e.g. the estimated speed); returns whether it holds."""
        self.holds = bool(self.cue.update(step, value))
        self._apply()
        return self.holds

    def _wrap(self, step: int, out: DetectorStep) -> DetectorStep:
        decision = out.decision
        if decision is not None:
            cue = f"cue {'on' if self.holds else 'off'}, α = {self.detector.alpha:g}"
            decision = attrs.evolve(decision, detector=self.label, message=f"{decision.message} [{cue}]")
        return DetectorStep({**out.statistics, "cue": float(self.holds)}, {**out.thresholds, **self.static_thresholds}, decision)

    def step(self, step: int, innovation: Innovation) -> DetectorStep:
        return self._wrap(step, self.detector.step(step, innovation))

    def observe_value(self, step: int, value: float, m: int | None = None) -> DetectorStep:
        """For wrapped scalar detectors (GLR, CUSUM): one raw value of the watched sequence."""
        if not hasattr(self.detector, "observe_value"):
            raise ValueError(f"detector: {self.detector.name!r} takes innovations, not raw values")
        return self._wrap(step, self.detector.observe_value(step, value, m))


@hookimpl
def register_detectors(registry):
    registry.add(DynamicThreshold.name, DynamicThreshold)
