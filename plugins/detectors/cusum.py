"""Two-sided CUSUM (Page) on an N(0, 1) sequence, beside the GLR (SPEC §4; seed 003 ref. 26, Lai 1995).

    g⁺_n = max(0, g⁺_{n−1} + y_n − κ),  g⁻_n = max(0, g⁻_{n−1} − y_n − κ),  g_n = max(g⁺_n, g⁻_n)

κ (``drift``) is half the smallest mean shift to detect quickly.  Alarm when
g_n > λ(α) (λ(α) and the input's normalization: see :mod:`._scalar`); restart
after an alarm.
"""

from __future__ import annotations

import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.validation import check_positive
from hybridtrack_plugins.detectors._scalar import ScalarDetector
from hybridtrack_plugins.detectors.null_calibration import h0_sample


class CUSUM(ScalarDetector):
    """Page's two-sided CUSUM for a mean shift of either sign."""

    name = "cusum"

    def __init__(self, drift: float = 0.5, **options):
        """``options``: alpha, watch, reference, normalize, seed, null_sample of :class:`ScalarDetector`."""
        self.drift = check_positive(drift, "drift")
        super().__init__(**options)

    def h0_sample(self) -> np.ndarray:
        return h0_sample("cusum", self.drift, self.seed)

    def reset(self) -> None:
        self._up = self._down = 0.0

    def update_statistic(self, y: float) -> float:
        self._up = max(0.0, self._up + y - self.drift)
        self._down = max(0.0, self._down - y - self.drift)
        return self.current()

    def current(self) -> float:
        return max(self._up, self._down)


@hookimpl
def register_detectors(registry):
    registry.add(CUSUM.name, CUSUM)
