"""The result family: every algorithm's run result derives from :class:`RunResult`.

One axis order everywhere: a single run's arrays start with the step axis
(K+1, …); stacked runs put the run axis first (R, K+1, …).
"""

from __future__ import annotations

import attrs
import numpy as np

from hybridtrack.core.types import Decision


@attrs.frozen(eq=False, kw_only=True)
class RunResult:
    """One run over steps 0 … K: what every algorithm reports.

    * ``layout`` — the state components (n);
    * ``modes`` — the names of the modes (hypotheses, filters) that ``mode`` indexes;
    * ``times`` (K+1,) — the measurement times, seconds;
    * ``means`` (K+1, n) and ``covs`` (K+1, n, n) — the estimate x̂_{k|k}, P_{k|k}
      (a fixed bank without a selection reports every filter: (K+1, M, n), (K+1, M, n, n));
    * ``mode`` (K+1,) — the index into ``modes`` of the mode the algorithm follows at
      each step (None for a fixed bank, which follows none);
    * ``decisions`` — the detectors' decisions, in step order.
    """

    layout: tuple[str, ...]
    modes: tuple[str, ...]
    times: np.ndarray
    means: np.ndarray
    covs: np.ndarray
    mode: np.ndarray | None = None
    decisions: tuple[Decision, ...] = ()

    @property
    def steps(self) -> int:
        """K + 1, the number of measurement steps."""
        return len(self.times)
