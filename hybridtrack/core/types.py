"""Frozen value types passed between components.

Arrays inside them are read-only float64 copies; equality compares arrays with
``np.array_equal``; array fields take no part in the hash (``hash=False``), so
equal objects hash equal and objects differing only in arrays collide.  A
wrong shape, NaN/inf or a non-symmetric / non-PSD covariance raises
``ValueError`` naming the field.
"""

from __future__ import annotations

import attrs
import numpy as np

from hybridtrack.core.validation import readonly_array_field


@attrs.frozen
class Gaussian:
    """A Gaussian state N(mean, cov); mean of shape (n,), cov of shape (n, n), symmetric PSD."""

    mean: np.ndarray = readonly_array_field((None,))
    cov: np.ndarray = readonly_array_field(covariance=True)

    def __attrs_post_init__(self):
        n = self.mean.shape[0]
        if self.cov.shape != (n, n):
            raise ValueError(f"cov: expected shape ({n}, {n}) to match mean of shape ({n},), got {self.cov.shape}")

    @property
    def dim(self) -> int:
        return self.mean.shape[0]


@attrs.frozen
class Measurement:
    """One measurement vector ``z`` (shape (m,)) of sensor ``sensor`` at step ``step``."""

    sensor: str
    step: int = attrs.field(validator=attrs.validators.ge(0))
    z: np.ndarray = readonly_array_field((None,))


@attrs.frozen
class Decision:
    """A detector's decision event: at ``step`` detector ``detector`` (its label) chose ``mode``.

    ``statistic`` is the value that crossed the threshold (e.g. a log-likelihood
    ratio or a signal-function value), ``message`` a human-readable line;
    ``time`` the measurement time in seconds of that step, filled in by the
    pipeline or adaptive estimator that ran the detector (None until then).
    """

    step: int
    detector: str
    mode: str
    statistic: float = attrs.field(converter=float)
    message: str = ""
    time: float | None = None
