"""GLR with a sliding window on an N(0, 1) sequence (seed 003 eqs. 5–6; SPEC §4 "GLR").

    g_n = max_{n−W < k ≤ n} (y_k + … + y_n)² / (2(n − k + 1)),   alarm when g_n > λ

— the generalized likelihood ratio for a change of the mean of unknown size
and sign in the last W steps.  λ = λ(α) and the input's normalization: see
:mod:`._scalar`.  After an alarm the window restarts.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.validation import check_positive_int
from hybridtrack_plugins.detectors._scalar import ScalarDetector
from hybridtrack_plugins.detectors.null_calibration import h0_sample


class GLR(ScalarDetector):
    """Sliding-window GLR for a mean change of unknown size (seed 003)."""

    name = "glr"

    def __init__(self, window: int = 10, **options):
        """``options``: alpha, watch, reference, normalize, seed, null_sample of :class:`ScalarDetector`."""
        self.window = check_positive_int(window, "window")
        super().__init__(**options)

    def h0_sample(self) -> np.ndarray:
        return h0_sample("glr", self.window, self.seed)

    def reset(self) -> None:
        self._recent: deque = deque(maxlen=self.window)
        self._g = 0.0

    def update_statistic(self, y: float) -> float:
        self._recent.append(y)
        sums = np.cumsum(np.asarray(self._recent)[::-1])  # y_n, y_n + y_{n−1}, …
        self._g = float(np.max(sums * sums / (2.0 * np.arange(1, sums.size + 1))))
        return self._g

    def current(self) -> float:
        return self._g


@hookimpl
def register_detectors(registry):
    registry.add(GLR.name, GLR)
