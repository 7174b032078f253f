"""Recording: Rerun recorders, logging of results (one writer module per result family), the viewer layout and
style, offline inspection.  Reads results; never called from inside a step.
"""

from hybridtrack.recording import (
    adaptive,  # noqa: F401  (registers the KnownSwitchRun, UnknownChangeRun and ScheduleRun writers)
    multiple_model,  # noqa: F401  (registers the MultipleModelRun writer)
    pipeline,  # noqa: F401  (registers the writer of a pipeline run with log_result)
)
from hybridtrack.recording.layout import (
    LEGEND_CORNERS,
    MAP_VIEW_NAME,
    MODE_PANEL_TITLE,
    TRAIL_STEPS,
    VIEW_CLASSES,
    content_blueprint,
    map_zoom,
)
from hybridtrack.recording.recorder import (
    APPLICATION_ID,
    MAX_RECORDABLE_SECONDS,
    NullRecorder,
    Recorder,
    RerunRecorder,
    check_recordable_times,
    decision_text,
    ellipse_outlines,
    log_estimate,
    log_measurements,
    nis_bounds,
    open_recorder,
    recording_id,
    short_decision,
)
from hybridtrack.recording.style import finite_runs, is_hypothesis, log_ratio_name, mode_lanes, palette, series_style, spatial_style

__all__ = [
    "APPLICATION_ID",
    "LEGEND_CORNERS",
    "MAP_VIEW_NAME",
    "MODE_PANEL_TITLE",
    "MAX_RECORDABLE_SECONDS",
    "NullRecorder",
    "Recorder",
    "RerunRecorder",
    "TRAIL_STEPS",
    "VIEW_CLASSES",
    "check_recordable_times",
    "content_blueprint",
    "decision_text",
    "ellipse_outlines",
    "finite_runs",
    "is_hypothesis",
    "log_estimate",
    "log_measurements",
    "log_ratio_name",
    "map_zoom",
    "mode_lanes",
    "nis_bounds",
    "open_recorder",
    "palette",
    "recording_id",
    "series_style",
    "short_decision",
    "spatial_style",
]
