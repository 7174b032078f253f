"""One entry that records any algorithm's result: :func:`log_result` (``recorder.log_result(result, …)``).

The engine and the algorithms never import the recording layer: a run hands
its finished result to ``recorder.log_result(result, **context)`` (a method of
the :class:`~hybridtrack.recording.recorder.Recorder` protocol), which lands
here and dispatches on the result's type.  Each result type registers its
writer (entity paths in ``docs/recording.md``) with ``@log_result.register``
in the recording module of its algorithm; a third party's result type
registers its own the same way.
"""

from __future__ import annotations

from functools import singledispatch


@singledispatch
def log_result(result, recorder, **context) -> None:
    """Write ``result`` through ``recorder``; ``context`` carries what the result does not hold (measurements,
    truth, the sensor network, the estimator, …) as each writer documents."""
    raise TypeError(f"result: no recording is registered for {type(result).__name__}; register one with @log_result.register")
