"""The reference of every key ``hybridtrack track`` accepts, by section: type or unit, default and meaning.

``python -m hybridtrack.apps.config_reference > docs/config.md`` writes the documentation page
(:func:`reference_markdown`).  :data:`REFERENCE` holds one :class:`Entry` per key of
:data:`hybridtrack.apps.tracking.CONFIG_KEYS`, in the order of the page; ``tests/test_config_reference.py``
checks that its keys are those of ``CONFIG_KEYS`` section by section (:func:`check_reference`: a key the parser
accepts without an entry here fails) and that ``docs/config.md`` is :func:`reference_markdown`'s text.

Defaults are read from the code, never retyped: the ``read_tracks`` keywords' defaults from its signature, the
constants of :mod:`hybridtrack.apps.tracking` (``ALTITUDE_DEFAULTS``, ``TURN_RATE_SIGMA``, ``DEFAULT_OBJECT_CLASS``,
``CLASS_JUMP_TOLERANCE``, ``JUMP_SIGMAS``, ``MULTIPLE_MODEL``, ``PRESETS``) and of
:mod:`hybridtrack.io.track_files` (``SPEED_LIMITS``, ``SPEED_UNITS``, ``TIME_UNITS``, ``PROJECTIONS``), the position
sensor's ``time_jitter`` default from the registry, and the defaults :func:`~hybridtrack.apps.tracking.load_config`
fills in from what it returns for the smallest configurations (:func:`filled_defaults`).
"""

from __future__ import annotations

import inspect
import json
import math
from collections.abc import Callable
from functools import cache
from typing import Any

import attrs

from hybridtrack.apps import tracking
from hybridtrack.core.registry import registry_or_default
from hybridtrack.io import track_files

#: the command that writes the page
COMMAND = "python -m hybridtrack.apps.config_reference > docs/config.md"
#: the sigma (m) of the probe configurations whose filled-in defaults :func:`filled_defaults` reads
_PROBE_SIGMA = 1.0
#: a configuration that ``track`` runs with every other key at its default (shown on the page, loaded by the test)
MINIMAL_EXAMPLE = """\
[reader]
time = "time"             # the column names of your file; x/y in metres, or:
lat = "lat"
lon = "lon"

[measurement]
sigma = 10.0              # m, the position noise: required

[estimator]
algorithm = "imm"         # required: a registered algorithm (hybridtrack plugins)
modes = ["straight", {name = "coordinated_turn"}]
noise_density = 0.001     # m²/s³ of white acceleration
"""


@attrs.frozen
class Entry:
    """One key: ``kind`` its type or unit, ``meaning`` what it does, ``default`` a function of no argument returning
    the default read from the code (None: no default value), and ``absent`` the text shown when there is none."""

    kind: str
    meaning: str
    default: Callable[[], Any] | None = None
    absent: str = "—"


def toml_value(value: Any) -> str:
    """``value`` as TOML writes it: ``"text"``, ``true``, ``0.001``, ``[1, 2]``, ``{name = "stop"}``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:g}" if math.isfinite(value) else str(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"value: expected a TOML string, number, boolean, array or table, got {value!r}")


def reader_default(name: str) -> Any:
    """The default of ``read_tracks``' keyword ``name`` (None when it has none or does not take it)."""
    parameter = inspect.signature(track_files.read_tracks).parameters.get(name)
    return None if parameter is None or parameter.default is inspect.Parameter.empty else parameter.default


@cache
def filled_defaults() -> dict:
    """What :func:`~hybridtrack.apps.tracking.load_config` fills in, from the smallest configurations: ``"imm"`` — an
    ``imm`` of its default modes (the turns at one radius), ``"unknown_change"`` — an ``unknown_change`` of one
    straight mode; both with ``[measurement] sigma`` = 1 m and nothing else."""
    measurement = {"sigma": _PROBE_SIGMA}
    return {
        "imm": tracking.load_config({"measurement": measurement, "estimator": {"algorithm": "imm", "radii": [1.0]}}),
        "unknown_change": tracking.load_config(
            {"measurement": measurement, "estimator": {"algorithm": "unknown_change", "modes": ["straight"]}}
        ),
    }


def _filled(*path: str) -> Callable[[], Any]:
    def read():
        value = filled_defaults()[path[0]]
        for key in path[1:]:
            value = value[key]
        return value

    return read


def _default_modes() -> list[str]:
    # the default mode names in order (the probe expanded the bare turns over one radius)
    return list(dict.fromkeys(name for name, _ in filled_defaults()["imm"]["estimator"]["modes"]))


def _ratio(section: str, key: str, base_section: str, base_key: str) -> float:
    probe = filled_defaults()["imm"]
    return probe[section][key] / probe[base_section][base_key]


def _time_jitter_default() -> float:
    factory = registry_or_default(None).get("sensor", "position")
    return inspect.signature(factory).parameters["time_jitter"].default


def _speed_limits() -> str:
    return ", ".join(f"`{name!r}` {limit:g} m/s".replace("'", '"') for name, limit in track_files.SPEED_LIMITS.items())


def _choices(values) -> str:
    return ", ".join(toml_value(v) for v in values)


def _reader_column(name: str, what: str, absent: str = "none") -> Entry:
    return Entry("string (a column name)", what, lambda: reader_default(name), absent=absent)


def _reader() -> dict[str, Entry]:
    default_class = tracking.DEFAULT_OBJECT_CLASS
    default_limit = track_files.SPEED_LIMITS[default_class]
    return {
        "preset": Entry(
            f"string: {_choices(sorted(tracking.PRESETS))}",
            "start from the column names and codes of a known file (`solent_ais`: `hybridtrack.io.track_files.SOLENT_AIS`, "
            "the Solent AIS CSV in `data/solent_ais/`); the other keys of `[reader]` override them",
            absent="none",
        ),
        "format": Entry(
            'string: "csv", "gpx", "nmea"',
            "what the file is: a CSV (or `.csv.gz`) with a header row, a GPX file, or NMEA 0183 AIS sentences "
            "([Track your own file](own_files.md)); the column keys below, `time` to `speed_not_available`, are for CSV "
            "files: GPX and NMEA files set their own, and a value other than the default is refused",
            lambda: reader_default("format"),
            absent="from the file's extension: `.csv` or `.csv.gz`, `.gpx`, `.nmea` or `.ais` (any other refused)",
        ),
        "time": _reader_column(
            "time",
            "the time column: numbers (seconds, or milliseconds with `time_unit`), ISO 8601 time stamps (no zone = UTC) "
            "or the form of `time_format`; the track times are seconds after the earliest time stamp "
            "([Time formats](time_formats.md))",
        ),
        "time_unit": Entry(
            f"string: {_choices(track_files.TIME_UNITS)}",
            "the unit of numeric times (seconds, milliseconds); without it numbers of 10¹¹ or more are refused "
            "(epoch milliseconds read as seconds)",
            lambda: reader_default("time_unit"),
            absent="seconds, and numbers ≥ 10¹¹ refused",
        ),
        "time_format": Entry(
            "string (a strptime format)",
            'time stamps that are neither numbers nor ISO 8601, e.g. `"%d/%m/%Y %H:%M:%S"` for `12/01/2016 13:02:11`; '
            "UTC unless the format holds a zone (`%z`); not with `time_unit`",
            lambda: reader_default("time_format"),
            absent="none: numbers or ISO 8601",
        ),
        "x": _reader_column("x", "east position column, metres (files in a plane; not with `lat`/`lon`)"),
        "y": _reader_column("y", "north position column, metres"),
        "lat": _reader_column(
            "lat",
            "latitude column, degrees (WGS-84); with `lon` the positions are projected to metres on the tangent plane at `origin`",
            absent="none: `x`, `y` in metres",
        ),
        "lon": _reader_column("lon", "longitude column, degrees; give both `lat` and `lon`", absent="none: `x`, `y` in metres"),
        "alt": _reader_column(
            "alt",
            "altitude column, metres (height above the WGS-84 ellipsoid with `lat`/`lon`); filtered on its own (`[altitude]`)",
        ),
        "id": _reader_column("id", "object id column: one track per id (an MMSI, a flight)", absent="none: the file is one object"),
        "course": _reader_column("course", "course over ground column, degrees clockwise from north"),
        "speed": _reader_column("speed", "speed over ground column, in `speed_unit`"),
        "speed_unit": Entry(
            f"string: {_choices(track_files.SPEED_UNITS)}",
            "the unit of the `speed` column (stored in m/s)",
            lambda: reader_default("speed_unit"),
        ),
        "course_not_available": Entry(
            "number, degrees",
            "the code meaning no course (AIS: 360): set to NaN, the row kept",
            lambda: reader_default("course_not_available"),
            absent="none",
        ),
        "speed_not_available": Entry(
            "number, in `speed_unit`",
            "the code meaning no speed (AIS: 102.3 knots): set to NaN, the row kept",
            lambda: reader_default("speed_not_available"),
            absent="none",
        ),
        "origin": Entry(
            'string "first", "mean", or [lat°, lon°] / [lat°, lon°, h m]',
            "the tangent point of the projection: the first valid fix of the file, the mean of the fixes kept, or given "
            '(`summary.json` `"origin"`)',
            lambda: reader_default("origin"),
        ),
        "projection": Entry(
            f"string: {_choices(track_files.PROJECTIONS)}",
            "`enu`: exact local east-north-up (WGS-84); `equirectangular`: the cheap approximation, for comparison "
            "([Real data](real_data.md#the-projection-and-its-error))",
            lambda: reader_default("projection"),
        ),
        "max_speed": Entry(
            "number, m/s",
            "the speed limit of the jump check: a burst of fixes unreachable at this speed (+ `jump_tolerance`) is dropped, "
            'a lasting jump flagged; stated on stderr and in `summary.json` (`"max_speed"`)',
            absent=f"the `object_class` limit; neither given: {default_limit:g} m/s (the `{default_class}` class's)",
        ),
        "object_class": Entry(
            "string: " + _choices(track_files.SPEED_LIMITS),
            f"sets `max_speed` to the class's physical limit ({_speed_limits()}) when `max_speed` is not given",
            lambda: default_class,
        ),
        "jump_tolerance": Entry(
            "number, m ≥ 0",
            "the allowance of the jump check for position noise and time-stamp jitter: fix j is reachable from fix i when "
            "\\|p_j − p_i\\| ≤ `max_speed` (t_j − t_i) + `jump_tolerance`",
            absent=f"`{toml_value(reader_default('jump_tolerance'))}` with `max_speed`; with a class (given or the default) "
            f"{tracking.CLASS_JUMP_TOLERANCE:g} m + {tracking.JUMP_SIGMAS:g} (σ + σ_t v_max), σ and σ_t of `[measurement]` "
            "(`sigma`, `time_jitter`), v_max the class's limit",
        ),
        "min_reports": Entry(
            "integer ≥ 2",
            'objects with fewer reports are skipped and listed in `summary.json` `"skipped"`',
            _filled("imm", "min_reports"),
        ),
    }


def _measurement() -> dict[str, Entry]:
    return {
        "sigma": Entry(
            "number, m > 0",
            'position noise σ: the sensor `("position", {"noise_cov": σ² I})` of the registry',
            absent="required",
        ),
        "time_jitter": Entry(
            "number, s > 0",
            "σ_t of the time-stamp error (ADS-B, AIS stamped on receipt): R(x) = σ² I + σ_t² v vᵀ at each filter's "
            "predicted velocity v, an along-track error \\|v\\| σ_t beside the cross-track σ",
            _time_jitter_default,
        ),
        "speed_sigma": Entry(
            "number, m/s > 0",
            "measure the reported speed over ground (the `[reader]` `speed` column, required) as part of the velocity "
            "(s sin χ, s cos χ) by the `velocity` sensor; give `speed_sigma` and `course_sigma` both or neither; "
            "a report without course or speed measures the position alone",
            absent="none: positions only",
        ),
        "course_sigma": Entry(
            "number, degrees > 0",
            "the reported course over ground (the `[reader]` `course` column, required): R(x) = σ_s² I + σ_χ² "
            "(\\|v\\|² I − v vᵀ), the course error across the track",
            absent="none: positions only",
        ),
    }


def _altitude() -> dict[str, Entry]:
    defaults = tracking.ALTITUDE_DEFAULTS
    return {
        "sigma": Entry(
            "number, m > 0",
            "altitude noise σ_h of the vertical filter (used only with an `alt` column)",
            lambda: defaults["sigma"],
        ),
        "acceleration_density": Entry(
            "number, m²/s³ > 0",
            "q, the white-noise vertical acceleration density: Q = q [[Δt³/3, Δt²/2], [Δt²/2, Δt]]",
            lambda: defaults["acceleration_density"],
        ),
        "velocity_sigma": Entry("number, m/s > 0", "prior σ of the climb rate (it starts at 0)", lambda: defaults["velocity_sigma"]),
    }


def _prior() -> dict[str, Entry]:
    factor = _ratio("prior", "position_sigma", "measurement", "sigma")
    return {
        "velocity": Entry(
            'string: "two_fixes", "zero"',
            "the initial velocity: (p₁ − p₀)/(t₁ − t₀) of the first two fixes, or zero",
            _filled("imm", "prior", "velocity"),
        ),
        "position_sigma": Entry(
            "number, m > 0",
            "prior σ of the position; the mean is the first fix (step 0 updates with that fix again, leaving ≈ σ)",
            absent=f"{factor:g} × `[measurement] sigma`",
        ),
        "velocity_sigma": Entry("number, m/s > 0", "prior σ of each velocity component", _filled("imm", "prior", "velocity_sigma")),
        "turn_rate_sigma": Entry(
            "number, °/s > 0",
            "prior σ of a turn rate ω in the state (`coordinated_turn`; the mean is 0)",
            lambda: tracking.TURN_RATE_SIGMA,
        ),
    }


def _segments() -> dict[str, Entry]:
    off = _ratio("segments", "turn_rate_off", "segments", "turn_rate_on")
    go = _ratio("segments", "go_speed", "segments", "stop_speed")
    return {
        "by": Entry(
            'string: "model", "motion"',
            "what decides a report's mode in the segments: the followed or most probable model (a turn-rate model's step "
            "a left or right turn by the sign of ω̂), or the estimated motion — the hysteresis of the mode labels on ω̂ and "
            '\\|v̂\\| (needs a mode with ω in its state); the thresholds below need `by = "motion"`',
            _filled("imm", "segments", "by"),
        ),
        "turn_rate_on": Entry(
            "number, °/s > 0",
            "a turn starts when \\|ω̂\\| exceeds it (left for ω̂ > 0)",
            _filled("imm", "segments", "turn_rate_on"),
        ),
        "turn_rate_off": Entry(
            "number, °/s > 0, ≤ `turn_rate_on`",
            "a turn lasts until \\|ω̂\\| falls below it",
            absent=f"{off:g} × `turn_rate_on`",
        ),
        "stop_speed": Entry(
            "number, m/s > 0",
            "a stop starts when the estimated speed falls below it",
            _filled("imm", "segments", "stop_speed"),
        ),
        "go_speed": Entry("number, m/s > 0, ≥ `stop_speed`", "a stop lasts until the speed exceeds it", absent=f"{go:g} × `stop_speed`"),
        "sojourn_quantile": Entry(
            "number in [0, 1)",
            "q > 0: each mode's minimum duration d_j = −T_j ln(1 − q), the q-quantile of its sojourn prior (`[estimator] sojourn` T_j): "
            "causally a switch is taken once it has lasted d_j (dated from its start, decided d_j later: the `decisions`' `time` and "
            "`start`); with `--smooth` segments shorter than d_j are merged into their longer neighbour; `imm`, `gpb1`, `gpb2` only, "
            "either `by` ([Real data](real_data.md#minimum-durations))",
            _filled("imm", "segments", "sojourn_quantile"),
        ),
    }


def _estimator() -> dict[str, Entry]:
    multiple = ", ".join(f"`{name}`" for name in tracking.MULTIPLE_MODEL)
    return {
        "algorithm": Entry(
            "string (a registered algorithm)",
            '`"unknown_change"` (the SPRT bank with unknown change time), `"imm"`, `"gpb1"`, `"gpb2"` (multiple model) or a '
            "third party's; `hybridtrack plugins` lists them. The tracker gives it `modes`, `sensors`, `estimator` (`filter`), "
            '`name` (`"track"`) and `registry`',
            absent="required (or `kind`)",
        ),
        "kind": Entry(
            "string",
            'the older spelling of `algorithm` (`kind = "imm"` with `method = "gpb2"` reads as `algorithm = "gpb2"`); give one of the two',
            absent="none",
        ),
        "method": Entry(f"string: {multiple}", 'with `kind = "imm"`: which multiple-model method (the older spelling)', absent="none"),
        "filter": Entry(
            "string (a registered estimator)",
            "the filter inside each mode (`kalman`, `ekf`, `ukf`, …; `hybridtrack plugins`)",
            _filled("imm", "estimator", "filter"),
        ),
        "noise_density": Entry(
            "number, m²/s³ > 0",
            "q, the white-acceleration density of every mode: Q(Δt) = q [[Δt³/3, Δt²/2], [Δt²/2, Δt]] per axis, so the noise "
            "grows with the time between reports (`hybridtrack.sdk.process_noise`; `constant_acceleration` takes it as its "
            "jerk density, m²/s⁵, `stop` as its position random walk, m²/s; a mode table may give its own; "
            "[Motion models](motion.md#process-noise-per-second)); not with `process_noise`",
            absent="none",
        ),
        "process_noise": Entry(
            "number, m/s per report > 0",
            "the older per-report form: σ_w, every model's `noise_cov` = σ_w² I whatever the Δt (σ_w per report of τ seconds "
            "is q = σ_w²/τ); not with `noise_density`",
            _filled("imm", "estimator", "process_noise"),
            absent="",
        ),
        "modes": Entry(
            "array of names or tables",
            'registered motion models: a name (`"straight"`) or a table `{name = …, <any parameter of that model>}` '
            '(`{name = "left_turn", radius = 500}`, `{name = "coordinated_turn", max_rate = 0.05}`, '
            '`{name = "stop", noise_density = 0.01}`); a key the model does not take is refused with its parameter list; '
            "the `[estimator]` noise goes to each model that takes it and whose table gives none. A bare `left_turn` or "
            "`right_turn` needs `radii`",
            _default_modes,
        ),
        "radii": Entry(
            "array of numbers, m > 0",
            "turn radii: every bare turn name of `modes` becomes one mode per radius",
            absent="none",
        ),
        "alpha": Entry(
            "number in (0, 0.5)",
            "`unknown_change` only: the SPRT's false-alarm probability α (thresholds A = ln((1 − β)/α))",
            _filled("unknown_change", "estimator", "alpha"),
        ),
        "beta": Entry(
            "number in (0, 0.5)",
            "`unknown_change` only: the SPRT's missed-change probability β (B = ln(β/(1 − α)))",
            _filled("unknown_change", "estimator", "beta"),
        ),
        "bank_size": Entry(
            'integer ≥ 1 or "algorithm4"',
            "`unknown_change` only: the most alternative filters (change hypotheses) kept, pruned oldest first "
            '(`"algorithm4"`: the bound estimated by seed 000\'s Algorithm 4)',
            _filled("unknown_change", "estimator", "bank_size"),
        ),
        "initial_mode": Entry(
            "string (a mode name)",
            "`unknown_change` only: the mode followed at the start (a turn with a radius is named `left_turn_r500`)",
            absent="the first mode",
        ),
        "sojourn": Entry(
            "number, s > 0, or one per mode",
            f"{multiple} only: the mean time in a mode, Π(Δt) = expm(Λ Δt) with Λ_ii = −1/T_i",
            _filled("imm", "estimator", "sojourn"),
        ),
        "parameters": Entry(
            "table",
            'further keywords of the algorithm\'s factory (`{pruning = "oldest"}`, `{missing_variance = {omega = 1e-4}}`); '
            "not the keywords the tracker gives",
            _filled("imm", "estimator", "parameters"),
        ),
    }


def _association() -> dict[str, Entry]:
    from hybridtrack.apps.association_keys import ASSOCIATION_DEFAULTS as D

    def d(key):
        return lambda: D[key]

    return {
        "method": Entry(
            '`"gnn"`, `"jpda"` or `"mht"`',
            "the association over tracks: global nearest neighbour, joint probabilistic data association, or multiple "
            "hypothesis tracking (the `hypotheses` best global hypotheses, `mht_scans`-scan pruning; `updates_per_scan` = 1)",
            d("method"),
        ),
        "motion": Entry(
            '`"cv"` or `"modes"`',
            "each track's filter during association: a constant-velocity Kalman filter, or the IMM of `[estimator]` (its modes); "
            "the segments per track always come from `[estimator]` run on the detections the track took",
            d("motion"),
        ),
        "scan_window": Entry("number, s > 0", "detections grouped into scans of this many seconds (not with `scan`)", absent="none"),
        "scan": Entry("string (a column)", "the column that numbers the scans (not with `scan_window`)", absent="none"),
        "detection_probability": Entry(
            "number in (0, 1]", "P_D, the probability that an object is detected in a scan", d("detection_probability")
        ),
        "clutter_density": Entry("number, 1/m² per scan > 0", "λ, false detections per m² per scan", d("clutter_density")),
        "birth_density": Entry(
            "number, 1/m² per scan > 0",
            "β_NT, new objects per m² per scan: a new track's score starts at ln(β_NT/λ)",
            absent="`clutter_density`",
        ),
        "gate_probability": Entry("number in (0, 1)", "P_G, the χ² gate's probability", d("gate_probability")),
        "initiation": Entry(
            '`"two_point"` or `"single_point"`',
            "new tracks from two detections of consecutive scans (the velocity between them) or from one (at rest, `velocity_sigma`)",
            d("initiation"),
        ),
        "updates_per_scan": Entry(
            "integer ≥ 1",
            "how many detections one track may take in a scan: several reports of one object in a time window (AIS in 10 s scans)",
            d("updates_per_scan"),
        ),
        "hypotheses": Entry(
            "integer ≥ 1", '`method = "mht"`: K, the global hypotheses kept each scan (1: the same as `"gnn"`)', d("hypotheses")
        ),
        "mht_scans": Entry(
            "integer ≥ 1",
            '`method = "mht"`: N of the N-scan pruning: decisions older than N scans are those of the best hypothesis',
            d("mht_scans"),
        ),
        "seed_window": Entry(
            "number, s > 0",
            "two-point: how long a detection no track took waits for its second point (objects that report every few minutes)",
            absent="one scan",
        ),
        "max_speed": Entry("number, m/s > 0", "the fastest a two-point track may start", absent="the reader's speed limit"),
        "velocity_sigma": Entry(
            "number, m/s > 0", "the velocity prior σ of a single-point track and of a second point", absent="`max_speed`/2"
        ),
        "noise_density": Entry(
            "number, m²/s³ > 0", '`motion = "cv"`: its white-acceleration density', absent="`[estimator] noise_density`"
        ),
        "management": Entry(
            '`"m_of_n"` or `"score"`',
            "confirmation and deletion: M-of-N logic, or Blackman's track score (an SPRT of target against clutter)",
            d("management"),
        ),
        "confirm_hits": Entry("integer ≥ 1", "M-of-N: M, the detections that confirm a track …", d("confirm_hits")),
        "confirm_scans": Entry("integer ≥ 1", "… within its first N scans", d("confirm_scans")),
        "delete_misses": Entry(
            "integer ≥ 1", "M-of-N: a confirmed track is deleted after this many scans in a row without a detection", d("delete_misses")
        ),
        "false_track_probability": Entry(
            "number in (0, 1)", "score: α, confirming a false track; T_c = ln((1 − β)/α)", d("false_track_probability")
        ),
        "track_loss_probability": Entry(
            "number in (0, 1)", "score: β, deleting a true track; T_d = ln(β/(1 − α))", d("track_loss_probability")
        ),
        "deletion_drop": Entry(
            "number > 0", "score: a confirmed track is deleted when its score falls this far below its maximum", absent="T_c − T_d"
        ),
        "max_coast": Entry("number, s > 0", "either rule: a track without a detection for this long is deleted", absent="none"),
        "duplicate_probability": Entry(
            "number in (0, 1)",
            "gnn / jpda: of two tracks that both took a detection and whose (x, vx, y, vy) agree within χ²₄ at this"
            " probability, the later-started is a duplicate (one object's reports shared by two tracks)",
            absent="off",
        ),
        "duplicate_scans": Entry("integer ≥ 1", "a track found a duplicate in this many scans in a row is deleted", d("duplicate_scans")),
        "reacquire_window": Entry(
            "number, s > 0",
            "gnn / jpda: a track confirmed whose (x, vx, y, vy) agrees (χ²₄ at gate_probability) with a confirmed track deleted"
            " this long ago or less, predicted over the gap, takes that track's id: one id for an object heard again after a silence",
            absent="off",
        ),
    }


#: the sections' titles on the page
TITLES = {
    "reader": "the file, its columns and the jump check",
    "measurement": "what is measured, and its noise",
    "altitude": "the vertical filter (files with an `alt` column)",
    "prior": "the start of every track",
    "segments": "how reports are called straight, turn or stop",
    "estimator": "the algorithm, its modes and their noise",
    "association": "unlabelled detections: scans, association and track management (`hybridtrack.apps.multitarget`)",
}


def reference() -> dict[str, dict[str, Entry]]:
    """Section → key → :class:`Entry`, in the page's order (the defaults are read when :func:`reference_markdown` runs)."""
    return {
        "reader": _reader(),
        "measurement": _measurement(),
        "altitude": _altitude(),
        "prior": _prior(),
        "segments": _segments(),
        "estimator": _estimator(),
        "association": _association(),
    }


def reference_differences(entries: dict[str, dict[str, Entry]] | None = None) -> dict[str, dict[str, list[str]]]:
    """Section → ``{"missing": keys CONFIG_KEYS accepts without an entry, "extra": entries of keys it does not
    accept}``, for the sections where the two differ (a section on one side only: all its keys)."""
    entries = reference() if entries is None else entries
    out = {}
    for section in dict.fromkeys([*tracking.CONFIG_KEYS, *entries]):
        accepted, described = set(tracking.CONFIG_KEYS.get(section, ())), set(entries.get(section, {}))
        if accepted != described:
            out[section] = {"missing": sorted(accepted - described), "extra": sorted(described - accepted)}
    return out


def check_reference(entries: dict[str, dict[str, Entry]] | None = None) -> None:
    """A ValueError naming, per section, the keys ``hybridtrack track`` accepts that have no entry in the reference
    and the entries of keys it does not accept (:func:`reference_differences`); nothing when they agree."""
    differences = reference_differences(entries)
    if differences:
        parts = [
            f"[{section}]"
            + (f" accepted without an entry: {d['missing']}" if d["missing"] else "")
            + (f" described but not accepted: {d['extra']}" if d["extra"] else "")
            for section, d in differences.items()
        ]
        raise ValueError(
            "config reference: the keys of hybridtrack.apps.tracking.CONFIG_KEYS and of hybridtrack/apps/config_reference.py differ: "
            + "; ".join(parts)
        )


def default_text(entry: Entry) -> str:
    """The default column of one key: the TOML value read from the code, or the entry's text when there is none."""
    value = entry.default() if entry.default is not None else None
    return entry.absent if value is None else f"`{toml_value(value)}`"


def reference_markdown() -> str:
    """The page ``docs/config.md``: one table per section (key, type or unit, default, meaning)."""
    lines = [
        "# Configuration reference: `hybridtrack track` and `hybridtrack fit`",
        "",
        f"<!-- generated by `{COMMAND}`: edit hybridtrack/apps/config_reference.py, not this page -->",
        "",
        f"This page is generated from the code: `{COMMAND}` (`hybridtrack/apps/config_reference.py`). Its keys are",
        "`hybridtrack.apps.tracking.CONFIG_KEYS`, every key the configuration parser",
        "(`hybridtrack.apps.tracking.load_config`) accepts, and its defaults are read from the code; a test fails when",
        "the two part.",
        "",
        "A configuration is a TOML file of up to six tables. Unknown tables and keys are refused (with the list of",
        "the keys that section takes), as are bad values: one line on stderr naming the key, exit status 2",
        "([Troubleshooting](troubleshooting.md)). The smallest useful file:",
        "",
        "```toml",
        MINIMAL_EXAMPLE.rstrip("\n"),
        "```",
        "",
        "`examples/ships.toml`, `examples/ships_sprt.toml`, `examples/ships_turn_rate.toml` and `examples/aircraft.toml`",
        "are complete starting points ([Real data](real_data.md)).",
    ]
    for section, entries in reference().items():
        lines += ["", f"## `[{section}]`: {TITLES[section]}", "", "| key | type / unit | default | meaning |", "|---|---|---|---|"]
        lines += [f"| `{key}` | {entry.kind} | {default_text(entry)} | {entry.meaning} |" for key, entry in entries.items()]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    check_reference()
    print(reference_markdown(), end="")
