"""Measurement times: strictly increasing seconds at any spacing, or ``tau`` as the shorthand for regular sampling.

Every component that steps through measurements (the pipeline, the adaptive
estimators, the simulator) takes ``times`` (shape (K,), seconds, strictly
increasing, finite) or ``tau`` (times 0, τ, 2τ, …) and builds each step's
transition for its own Δt_k = t_k − t_{k−1}.
"""

from __future__ import annotations

import numpy as np

from hybridtrack.core.validation import check_positive


def check_times(times, name: str = "times", steps: int | None = None) -> np.ndarray:
    """``times`` as a float64 array (K,), strictly increasing and finite; a ValueError names the first bad index."""
    try:
        t = np.array(times, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name}: expected a sequence of times in seconds, got {type(times).__name__} ({error})") from None
    if t.ndim != 1:
        raise ValueError(f"{name}: expected shape (K,) (one time per step), got {t.shape}")
    if steps is not None and t.shape[0] != steps:
        raise ValueError(f"{name}: expected {steps} times (one per measurement step), got {t.shape[0]}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"{name}: time at index {bad[0]} is {float(t[bad[0]])} (expected finite seconds)")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        what = "a duplicate of" if dt[bad[0]] == 0 else "earlier than"
        raise ValueError(
            f"{name}: time at index {i} ({float(t[i])!r}) is {what} the time at index {i - 1} ({float(t[i - 1])!r}); times must be strictly increasing"
        )
    t.setflags(write=False)
    return t


def check_tau(tau) -> float:
    """A positive finite sampling period in seconds."""
    return check_positive(tau, "tau (the sampling period in seconds)")


def step_intervals(times, tau, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(times (K,), Δt (K−1,)) of ``steps`` steps: ``times`` if given (checked), else 0, τ, 2τ, … with every Δt
    exactly τ (not a difference of rounded times)."""
    if times is not None:
        t = check_times(times, steps=steps)
        return t, np.diff(t)
    if tau is None:
        raise ValueError("times: give the measurement times (seconds) or the sampling period tau")
    tau = check_tau(tau)
    t = np.arange(steps) * tau
    t.setflags(write=False)
    return t, np.full(max(steps - 1, 0), tau)
