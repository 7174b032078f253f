"""One entry that records any algorithm's result: :func:`log_result`, where ``recorder.log_result(result, **context)``
(:class:`~hybridtrack.recording.recorder.Recorder`) lands; the engine and the algorithms never import recording.

Each result type, a third party's too, registers its writer with ``@log_result.register`` in a recording module.
"""

from __future__ import annotations

from functools import singledispatch


@singledispatch
def log_result(result, recorder, **context) -> None:
    """Write ``result`` through ``recorder``; ``context`` carries what the result does not hold (measurements,
    truth, the sensor network, the estimator, …) as each writer documents."""
    raise TypeError(f"result: no recording is registered for {type(result).__name__}; register one with @log_result.register")
