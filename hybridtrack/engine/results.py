"""The result family: every algorithm's run result derives from :class:`RunResult`.

One axis order everywhere: a single run's arrays start with the step axis
(K+1, …); stacked runs put the run axis first (R, K+1, …).

:meth:`RunResult.to_pandas` gives the estimate as a table (pandas, an optional dependency imported only there:
:func:`import_pandas`).
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

    def first_steps(self, steps: int):
        """This run cut to its steps 0 … ``steps`` − 1 (a run padded to a batch's length, cut back): every array field
        whose first axis is the steps' sliced, every tuple of events with a ``step`` (decisions, changes) kept up to
        that step; the other fields as they are."""
        total = self.steps
        if not 1 <= steps <= total:
            raise ValueError(f"steps: expected 1 … {total} (the run's steps), got {steps!r}")
        cut = {}
        for field in attrs.fields(type(self)):
            value = getattr(self, field.name)
            if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == total:
                cut[field.name] = value[:steps]
            elif isinstance(value, tuple) and value and all(hasattr(v, "step") for v in value):
                cut[field.name] = tuple(v for v in value if v.step < steps)
        return attrs.evolve(self, **cut)

    def to_pandas(self):
        """The estimate as a :class:`pandas.DataFrame`: a column ``time`` (s) and one column per ``layout`` component.

        One row per step for means (K+1, n).  A fixed bank's means (K+1, M, n) are in long format: one row per step
        and filter, steps in order and the filters in ``modes`` order within a step, with a column ``filter`` (the
        filter's name, from ``modes``) after ``time``.  With ``mode`` (not None) a last column ``mode``: the label
        (from ``modes``) of the mode followed at that step.  The covariances (and a subclass's further arrays) are
        left out.  A ValueError when the means are neither (K+1, n) nor (K+1, M, n) of ``layout``, ``times`` and
        ``modes``, or a layout component is named ``time``, ``filter`` or ``mode``; an ImportError (with the
        ``pip install`` line) without pandas."""
        pd = import_pandas("RunResult.to_pandas")
        times = np.asarray(self.times, dtype=float)
        means = np.array(self.means, dtype=float)  # a copy: a pipeline's arrays are read-only views of its storage
        layout = list(self.layout)
        clash = sorted({"time", "filter", "mode"} & set(layout))
        if clash:
            raise ValueError(f"layout: component(s) {clash} clash with to_pandas' own columns time, filter, mode")
        steps = times.shape[0]
        if means.ndim == 2 and means.shape == (steps, len(layout)):
            filters = 1
            frame = pd.DataFrame(means, columns=layout)
        elif means.ndim == 3 and means.shape == (steps, len(self.modes), len(layout)):
            filters = means.shape[1]
            frame = pd.DataFrame(means.reshape(steps * filters, len(layout)), columns=layout)
            frame.insert(0, "filter", np.tile(np.array(self.modes, dtype=object), steps))
        else:
            raise ValueError(
                f"means: expected (K+1, n) = ({steps}, {len(layout)}) or (K+1, M, n) = ({steps}, {len(self.modes)}, {len(layout)})"
                f" for {steps} times, {len(self.modes)} modes and layout {tuple(layout)}, got shape {means.shape}"
            )
        frame.insert(0, "time", np.repeat(times, filters))
        if self.mode is not None:
            labels = np.array(self.modes, dtype=object)[np.asarray(self.mode, dtype=np.intp)]
            frame["mode"] = np.repeat(labels, filters)
        return frame


def import_pandas(what: str):
    """The pandas module, imported on first use; without it an ImportError naming ``what`` needs it and the
    ``pip install hybridtrack[pandas]`` that brings it."""
    try:
        import pandas
    except ImportError as error:
        raise ImportError(f"{what} needs pandas, which is not installed: pip install hybridtrack[pandas]") from error
    return pandas
