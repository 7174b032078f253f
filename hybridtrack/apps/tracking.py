"""Tracking real position files: a configured estimator run on every object of a file (``hybridtrack track``).

:func:`track_file` reads a time-stamped position file with
:func:`~hybridtrack.io.track_files.read_tracks`, runs one configured estimator per
object at the report times (irregular Δt_k = t_k − t_{k−1}) and writes, per
object, ``OUT/<id>.rrd`` (a Rerun recording: what the estimator logs, plus
:func:`record_track`'s 3-D altitude and map views), ``OUT/<id>.npz`` (``times``
(K,), ``means`` (K, n), ``covariances`` (K, n, n), ``modes`` (K,) the summary
mode name per step, ``radii`` (K,) the turn radius per step (NaN off turns),
``layout``, ``positions`` (K, 2) the measured fixes; for a geographic file ``lat_lon`` (K, 2) the estimate in
degrees; with altitude ``altitude``, ``altitude_mean``, ``altitude_var`` of :func:`filter_altitude`) and
``OUT/summary.json``::

    {"objects": [{"id": str, "output": str (the file stem of its .rrd and .npz),
                  "segments": [{"start": float, "end": float, "mode": str, "radius": float | null,
                                "mean_speed": float, "heading_change": float, "mean_turn_rate": float | null,
                                "start_utc": str, "end_utc": str}],
                  "decisions": [{"time": float, "mode": str, "time_utc": str}]}],
     "skipped": [{"id": str, "reason": str, "failed": true (an object whose tracking failed)}],
     "epoch_utc": str | null, "origin": {"lat": float, "lon": float, "h": float} | null,
     "max_speed": {"max_speed": float, "set_by": str}, "problem_counts": {kind: int},
     "problems": [{"line": int, "column": str | null, "kind": str, "action": str, "message": str, "id": str | null}]}

Times (``start``, ``end``, ``time``) are seconds after the file's earliest time stamp, ``epoch_utc`` (ISO
8601); the ``*_utc`` keys are there for files of ISO time stamps only.  Segment statistics are
:func:`describe_segments`'s (m/s, degrees and °/s, positive to the left); ``origin`` is the map origin (lat°,
lon°, h m) of the projection (None for x/y files); ``problems`` every row the reader dropped, flagged or
repaired, with its reason (:class:`~hybridtrack.io.track_files.Problem`).  The recordings of a file of ISO
time stamps also have the ``utc`` timeline.

Mode names are the motion models' registry names (``acceleration`` for
``constant_acceleration``), ``radius`` the turn radius (m) of the model
followed.  **Segments** (:func:`segments_of`) merge consecutive steps of the
same (mode, radius) of the per-step ``mode`` of the result (the model followed,
or the most probable one of the IMM).  **Decisions** are the detector's
decisions for an algorithm with a detector, else the steps where that mode
changes.

The configuration (TOML tables ``[reader]``, ``[measurement]``, ``[altitude]``,
``[prior]``, ``[segments]``, ``[estimator]``; unknown keys and tables are refused) is tabulated
in ``docs/real_data.md`` and checked by :func:`load_config`.  The algorithm is
built from the registry with the keywords ``modes``, ``sensors`` (the position sensor, and the velocity
sensor of ``[measurement] speed_sigma``/``course_sigma``), ``estimator`` (the filter), ``name`` (``"track"``), ``registry``, its
own keys and ``[estimator] parameters``, so any registered algorithm taking
them (:class:`hybridtrack.core.algorithm.Algorithm`) can be named.  Every user
error — a missing file, unknown key, bad value, unknown algorithm or mode — is
a :class:`ConfigError` (a ValueError) naming the key.
"""

from __future__ import annotations

import contextlib
import inspect
import json
import math
import os
import re
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from datetime import UTC, timedelta
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import attrs
import numpy as np

from hybridtrack.algorithms.bank_runs import record_run, run_ragged
from hybridtrack.apps.geojson import tracks_geojson
from hybridtrack.apps.mode_labels import motion_states
from hybridtrack.core.plugins import resolve
from hybridtrack.core.registry import registry_or_default
from hybridtrack.core.validation import check_positive
from hybridtrack.io.track_files import SOLENT_AIS, SPEED_LIMITS, Track, problem_kinds, read_tracks, unproject

#: reader presets by name (the ``preset`` key of ``[reader]``)
PRESETS = {"solent_ais": SOLENT_AIS}
#: the multiple-model algorithms (``method`` of the older ``kind = "imm"`` spelling picks one)
MULTIPLE_MODEL = ("imm", "gpb1", "gpb2")
#: registry name → summary mode name
SUMMARY_NAMES = {"constant_acceleration": "acceleration"}
#: the object class whose speed limit applies when ``[reader]`` gives neither ``max_speed`` nor ``object_class``
DEFAULT_OBJECT_CLASS = "aircraft"
#: ``jump_tolerance`` (m) with a class's speed limit when ``[reader]`` does not give it: 100 m plus 5 times the fixes'
#: noise, σ + σ_t v_max (the position σ and the along-track error of a time-stamp jitter σ_t at the class's speed)
CLASS_JUMP_TOLERANCE = 100.0
JUMP_SIGMAS = 5.0
#: problem kinds that are not faults — the file's own "not available" codes, an AIS log's messages that are no position
#: reports — ``--strict`` lets them pass
NOT_FAULTS = ("not_available", "not_position")
#: the prior σ of a turn rate ω in the state (°/s): a ship's or an airliner's standard-rate turn is within 1.5 σ
TURN_RATE_SIGMA = 2.0
#: the vertical filter's defaults: σ_h (m), white-acceleration density q (m²/s³), prior σ of the climb rate (m/s)
ALTITUDE_DEFAULTS = {"sigma": 10.0, "acceleration_density": 0.1, "velocity_sigma": 5.0}

#: keys that belong to one algorithm (``imm``: the whole multiple-model family), given to its factory (but ``method``)
_KIND_ONLY = {"unknown_change": ("alpha", "beta", "bank_size", "initial_mode"), "imm": ("sojourn", "method")}
#: every key `hybridtrack track` accepts, by section (load_config refuses any other; docs/config.md is generated from it)
CONFIG_KEYS = {
    "reader": set(inspect.signature(read_tracks).parameters) - {"source", "warn"} | {"preset", "min_reports"},  # read_tracks' keywords
    "measurement": {"sigma", "time_jitter", "speed_sigma", "course_sigma"},
    "altitude": set(ALTITUDE_DEFAULTS),
    "prior": {"velocity", "position_sigma", "velocity_sigma", "turn_rate_sigma"},
    "segments": {"by", "turn_rate_on", "turn_rate_off", "stop_speed", "go_speed"},
    "estimator": {"algorithm", "kind", "filter", "process_noise", "noise_density", "modes", "radii", "parameters"}
    | set(_KIND_ONLY["unknown_change"] + _KIND_ONLY["imm"]),
}
#: the keywords the tracker itself gives every algorithm (``[estimator] parameters`` may not repeat them)
_RESERVED = {"modes", "sensors", "estimator", "name", "registry", "alpha", "beta", "bank_size", "initial_mode", "sojourn"}


class ConfigError(ValueError):
    """A configuration the tracker cannot use: the message names the file, the key and what is expected."""


def _positive(section: str, key: str, value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
        raise ConfigError(f"{where}: [{section}] {key} = {value!r}; expected a positive number")
    return float(value)


def load_config(config: str | os.PathLike | Mapping[str, Any], registry=None) -> dict:
    """The checked configuration (a dict of the four sections, defaults filled) from a TOML file or a mapping.

    ``[estimator] algorithm`` must name an algorithm of ``registry`` (default: the installed plugins')."""
    if isinstance(config, Mapping):
        where, raw = "config", dict(config)
    else:
        where = str(config)
        if not Path(config).is_file():
            raise ConfigError(f"{where}: no such configuration file")
        try:
            raw = tomllib.loads(Path(config).read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
            raise ConfigError(f"{where}: not a valid TOML file ({error})") from None
    unknown = sorted(set(raw) - set(CONFIG_KEYS))
    if unknown:
        raise ConfigError(f"{where}: unknown section(s) {unknown}; expected some of {sorted(CONFIG_KEYS)}")
    out = {}
    for section, keys in CONFIG_KEYS.items():
        table = raw.get(section, {})
        if not isinstance(table, Mapping):
            raise ConfigError(f"{where}: [{section}] must be a table, got {table!r}")
        bad = sorted(set(table) - keys)
        if bad:
            raise ConfigError(f"{where}: unknown key(s) {bad} in [{section}]; expected some of {sorted(keys)}")
        out[section] = dict(table)
    preset = out["reader"].pop("preset", None)
    if preset is not None and preset not in PRESETS:
        raise ConfigError(f"{where}: [reader] preset = {preset!r}; expected one of {sorted(PRESETS)}")
    reader = out["reader"] = {**PRESETS.get(preset, {}), **out["reader"]}
    min_reports = out["min_reports"] = reader.pop("min_reports", 3)
    if isinstance(min_reports, bool) or not isinstance(min_reports, int) or min_reports < 2:
        raise ConfigError(f"{where}: [reader] min_reports = {min_reports!r}; expected an integer ≥ 2")
    if isinstance(reader.get("origin"), list):
        reader["origin"] = tuple(reader["origin"])

    sigma = out["measurement"].get("sigma")
    if sigma is None:
        raise ConfigError(f"{where}: [measurement] sigma (m) is required")
    out["measurement"]["sigma"] = _positive("measurement", "sigma", sigma, where)
    if "time_jitter" in out["measurement"]:
        out["measurement"]["time_jitter"] = _positive("measurement", "time_jitter", out["measurement"]["time_jitter"], where)
    if "max_speed" in reader:
        out["speed_limit"] = {"max_speed": reader["max_speed"], "set_by": "[reader] max_speed"}
    else:
        chosen = reader.get("object_class", DEFAULT_OBJECT_CLASS)
        if chosen not in SPEED_LIMITS:
            raise ConfigError(f"{where}: [reader] object_class = {chosen!r}; expected one of {sorted(SPEED_LIMITS)}")
        given = "object_class" in reader
        reader["object_class"] = chosen
        jitter = out["measurement"].get("time_jitter", 0.0)
        tolerance = CLASS_JUMP_TOLERANCE + JUMP_SIGMAS * (out["measurement"]["sigma"] + jitter * SPEED_LIMITS[chosen])
        reader.setdefault("jump_tolerance", tolerance)
        out["speed_limit"] = {
            "max_speed": SPEED_LIMITS[chosen],
            "set_by": f"[reader] object_class {chosen!r}"
            if given
            else f"default: no [reader] max_speed or object_class, the {chosen!r} class's",
        }
    velocity = [key for key in ("speed_sigma", "course_sigma") if key in out["measurement"]]
    if velocity:  # the reported course and speed as a velocity measurement
        if len(velocity) == 1:
            raise ConfigError(f"{where}: [measurement] speed_sigma (m/s) and course_sigma (degrees): give both or neither")
        for key in velocity:
            out["measurement"][key] = _positive("measurement", key, out["measurement"][key], where)
        if reader.get("course") is None or reader.get("speed") is None:
            raise ConfigError(
                f"{where}: [measurement] speed_sigma and course_sigma measure the reported course and speed: [reader] needs"
                f" the course and speed columns (course = ..., speed = ...), got course = {reader.get('course')!r}, speed = {reader.get('speed')!r}"
            )

    alt = out["altitude"]
    for key, default in ALTITUDE_DEFAULTS.items():
        alt[key] = _positive("altitude", key, alt.get(key, default), where)

    prior = out["prior"]
    prior.setdefault("velocity", "two_fixes")
    if prior["velocity"] not in ("two_fixes", "zero"):
        raise ConfigError(f"{where}: [prior] velocity = {prior['velocity']!r}; expected 'two_fixes' or 'zero'")
    prior["position_sigma"] = _positive("prior", "position_sigma", prior.get("position_sigma", 10.0 * out["measurement"]["sigma"]), where)
    prior["velocity_sigma"] = _positive("prior", "velocity_sigma", prior.get("velocity_sigma", 10.0), where)
    prior["turn_rate_sigma"] = _positive("prior", "turn_rate_sigma", prior.get("turn_rate_sigma", TURN_RATE_SIGMA), where)

    out["segments"] = _segment_rule(out["segments"], where)

    est = out["estimator"]
    given = [key for key in ("algorithm", "kind") if key in est]  # kind: the older spelling
    if len(given) != 1:
        raise ConfigError(f"{where}: [estimator] algorithm (a registered algorithm name) is required, once (kind is its older spelling)")
    kind = est.pop(given[0])
    known = registry_or_default(registry).names("algorithm")
    if kind not in known:
        raise ConfigError(f"{where}: [estimator] {given[0]} = {kind!r}; expected a registered algorithm, one of {known}")
    family = "imm" if kind in MULTIPLE_MODEL else kind
    for other, keys in _KIND_ONLY.items():
        misplaced = sorted(set(est).intersection(keys)) if other != family else []
        if misplaced:
            raise ConfigError(f"{where}: [estimator] key(s) {misplaced} belong to kind {other!r}, not {kind!r}")
    method = est.pop("method", None)
    if method is not None:  # the older spelling: kind = "imm", method = "gpb2"
        if method not in MULTIPLE_MODEL or kind not in ("imm", method):
            raise ConfigError(f"{where}: [estimator] method = {method!r}; expected one of {MULTIPLE_MODEL} (or name it: algorithm = ...)")
        kind = method
    est["algorithm"] = kind
    parameters = est.setdefault("parameters", {})
    if not isinstance(parameters, Mapping) or set(parameters) & _RESERVED:
        raise ConfigError(
            f"{where}: [estimator] parameters = {parameters!r}; expected a table of further keyword arguments (not {sorted(_RESERVED)})"
        )
    if "noise_density" in est:  # per second (m²/s³ of white acceleration), else per report (the older form)
        if "process_noise" in est:
            raise ConfigError(f"{where}: [estimator] process_noise (per report) and noise_density (per second): give one")
        est["noise_density"] = _positive("estimator", "noise_density", est["noise_density"], where)
    else:
        est["process_noise"] = _positive("estimator", "process_noise", est.get("process_noise", 0.1), where)
    est["modes"] = _modes(est.get("modes", ["straight", "left_turn", "right_turn"]), est.pop("radii", None), where)
    est.setdefault("filter", "kalman")
    if not isinstance(est["filter"], str):
        raise ConfigError(f"{where}: [estimator] filter = {est['filter']!r}; expected a registered estimator name")
    if family == "unknown_change":
        for key in ("alpha", "beta"):
            value = _positive("estimator", key, est.get(key, 0.01), where)
            if value >= 0.5:
                raise ConfigError(f"{where}: [estimator] {key} = {value!r}; expected an error probability in (0, 0.5)")
            est[key] = value
        bank = est.setdefault("bank_size", 30)
        if bank != "algorithm4" and (isinstance(bank, bool) or not isinstance(bank, int) or bank < 1):
            raise ConfigError(f"{where}: [estimator] bank_size = {bank!r}; expected a positive integer or 'algorithm4'")
        names = [name if "radius" not in params else f"{name}_r{params['radius']:g}" for name, params in est["modes"]]
        first = est.get("initial_mode", names[0])
        if first not in names:
            raise ConfigError(f"{where}: [estimator] initial_mode = {first!r}; expected one of {names}")
        est["initial_mode"] = names.index(first)
    elif family == "imm":
        sojourn = est.setdefault("sojourn", 60.0)
        for v in sojourn if isinstance(sojourn, list) else [sojourn]:
            _positive("estimator", "sojourn", v, where)
        if isinstance(sojourn, list) and len(sojourn) != len(est["modes"]):
            raise ConfigError(f"{where}: [estimator] sojourn: {len(sojourn)} values for {len(est['modes'])} modes")
    return out


def _segment_rule(table: dict, where: str) -> dict:
    """``[segments]`` checked, defaults filled: ``by`` ``"model"`` (the followed or most probable model) or
    ``"motion"`` (the estimated turn rate and speed through :func:`~hybridtrack.apps.mode_labels.motion_states`:
    ``turn_rate_on`` / ``turn_rate_off`` in °/s (0.5 and half of it), ``stop_speed`` / ``go_speed`` in m/s (0.5 and
    twice it))."""
    by = table.get("by", "model")
    if by not in ("model", "motion"):
        raise ConfigError(
            f"{where}: [segments] by = {by!r}; expected 'model' (the most probable model) or 'motion' (the estimated turn rate and speed)"
        )
    if by == "model" and set(table) - {"by"}:
        raise ConfigError(f"{where}: [segments] {sorted(set(table) - {'by'})} need by = 'motion'")
    on = _positive("segments", "turn_rate_on", table.get("turn_rate_on", 0.5), where)
    off = _positive("segments", "turn_rate_off", table.get("turn_rate_off", on / 2), where)
    stop = _positive("segments", "stop_speed", table.get("stop_speed", 0.5), where)
    go = _positive("segments", "go_speed", table.get("go_speed", 2 * stop), where)
    if off > on or go < stop:
        raise ConfigError(
            f"{where}: [segments] expected turn_rate_off ≤ turn_rate_on and go_speed ≥ stop_speed, got {off:g} > {on:g} or {go:g} < {stop:g}"
        )
    return {"by": by, "turn_rate_on": on, "turn_rate_off": off, "stop_speed": stop, "go_speed": go}


def _modes(modes, radii, where) -> list[tuple[str, dict]]:
    """(registry name, parameters) per mode: bare turn names expanded over ``radii``."""
    if not isinstance(modes, list) or not modes:
        raise ConfigError(f"{where}: [estimator] modes = {modes!r}; expected a non-empty list of mode names or tables")
    if radii is not None:
        if not isinstance(radii, list) or not radii:
            raise ConfigError(f"{where}: [estimator] radii = {radii!r}; expected a non-empty list of turn radii (m)")
        radii = [_positive("estimator", "radii", r, where) for r in radii]
    out = []
    for entry in modes:
        if isinstance(entry, str):
            name, params = entry, {}
        elif isinstance(entry, Mapping) and isinstance(entry.get("name"), str):  # any of the model's own parameters
            name, params = entry["name"], {k: v for k, v in entry.items() if k != "name"}
            for key in set(params) & {"radius", "noise_density"}:
                params[key] = _positive("estimator", f"modes.{key}", params[key], where)
        else:
            raise ConfigError(
                f"{where}: [estimator] modes entry {entry!r}; expected a name or a table {{name = …, <the model's parameters> …}}"
            )
        name = "constant_acceleration" if name == "acceleration" else name
        if name in ("left_turn", "right_turn") and "radius" not in params:
            if radii is None:
                raise ConfigError(f"{where}: [estimator] mode {name!r} needs a radius: give radii = [...] or {{name, radius}}")
            out += [(name, {"radius": r}) for r in radii]
        else:
            out.append((name, params))
    return out


# --------------------------------------------------------------------------- building and running


def build_tracker(config: dict, registry=None):
    """(algorithm, position sensor, models) from a checked configuration (:func:`load_config`; registry resolution,
    no plugin imports); with ``[measurement] speed_sigma`` and ``course_sigma`` the algorithm also has the
    ``velocity`` sensor of the reported course and speed (:func:`measurements_of`)."""
    measurement = config["measurement"]
    sensor = resolve(
        "sensor",
        ("position", {"noise_cov": measurement["sigma"] ** 2 * np.eye(2), "time_jitter": measurement.get("time_jitter", 0.0)}),
        registry,
    )
    sensors = [sensor]
    if "speed_sigma" in measurement:
        course_sigma = math.radians(measurement["course_sigma"])
        sensors.append(resolve("sensor", ("velocity", {"speed_sigma": measurement["speed_sigma"], "course_sigma": course_sigma}), registry))
    est = config["estimator"]
    noise = {"noise_density": est["noise_density"]} if "noise_density" in est else {"noise_cov": est["process_noise"] ** 2 * np.eye(2)}
    specs = []
    for name, params in est["modes"]:
        try:
            factory = registry_or_default(registry).get("motion_model", name)
        except KeyError as error:
            raise ConfigError(f"[estimator] modes: unknown motion model {name!r} ({error.args[0] if error.args else error})") from None
        known = _parameter_names(factory)
        unknown = sorted(set(params) - known) if known is not None else []
        if unknown:
            raise ConfigError(f"[estimator] modes: {name!r} has no parameter {unknown[0]!r}; its parameters are {sorted(known)}")
        # the estimator's noise where the model takes it and the mode table gives none (a stop's own m²/s first)
        inherited = {k: v for k, v in noise.items() if known is None or k in known} if "noise_density" not in params else {}
        try:
            specs.append(resolve("motion_model", (name, {**params, **inherited}), registry))
        except (TypeError, ValueError) as error:
            raise ConfigError(f"[estimator] modes: {name!r} with {params}: {error}") from None
    family = "imm" if est["algorithm"] in MULTIPLE_MODEL else est["algorithm"]
    parameters = {key: est[key] for key in _KIND_ONLY.get(family, ()) if key in est}
    parameters.update(modes=specs, sensors=sensors, estimator=est["filter"], name="track", registry=registry, **est["parameters"])
    try:
        estimator = resolve("algorithm", (est["algorithm"], parameters), registry)
    except (TypeError, ValueError) as error:  # a keyword the algorithm does not take, a bad value, not an algorithm
        raise ConfigError(f"[estimator] algorithm {est['algorithm']!r}: {error}") from None
    except KeyError as error:
        raise ConfigError(f"[estimator]: {error.args[0] if error.args else error}") from None
    if config["segments"]["by"] == "motion" and "omega" not in estimator.layout:
        raise ConfigError(
            f"[segments] by = 'motion' needs a turn-rate estimate: a mode with omega in its state (coordinated_turn); the layout is {estimator.layout}"
        )
    return estimator, sensor, specs


def measurements_of(track: Track, config: dict) -> dict[str, np.ndarray]:
    """The measurements of a track by sensor name: ``position`` (K, 2) its fixes; with ``[measurement]
    speed_sigma``/``course_sigma`` also ``velocity`` (K, 2) = s (sin χ, cos χ) (east, north) of its reported speed s
    and course χ, NaN (no measurement) where either is not available."""
    out = {"position": np.asarray(track.positions[:, :2], dtype=float)}
    if "speed_sigma" in config["measurement"]:
        if track.course is None or track.speed is None:
            raise ValueError(f"object {track.id!r}: [measurement] speed_sigma/course_sigma need its course and speed, the file has none")
        course = np.radians(track.course)
        out["velocity"] = track.speed[:, None] * np.column_stack([np.sin(course), np.cos(course)])
    return out


def _parameter_names(factory) -> set[str] | None:
    """The keyword parameters a component factory takes (None: any, it has ``**kwargs`` or no signature)."""
    try:
        parameters = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        return None
    return {p.name for p in parameters if p.kind in (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)}


def track_prior(track: Track, config: dict, layout: Sequence[str]):
    """(mean, cov) in ``layout``: position = first fix, velocity from the first two fixes (or zero), a turn rate ω (if
    the layout has it) of 0 with σ = ``[prior] turn_rate_sigma`` (°/s), other components 0 with variance 1; diagonal."""
    p = config["prior"]
    z = track.positions[:, :2]
    v = (z[1] - z[0]) / (track.times[1] - track.times[0]) if p["velocity"] == "two_fixes" else np.zeros(2)
    values = {"x": z[0, 0], "y": z[0, 1], "vx": v[0], "vy": v[1]}
    variances = dict.fromkeys(("x", "y"), p["position_sigma"] ** 2) | dict.fromkeys(("vx", "vy"), p["velocity_sigma"] ** 2)
    variances["omega"] = math.radians(p["turn_rate_sigma"]) ** 2
    return np.array([values.get(c, 0.0) for c in layout]), np.diag([variances.get(c, 1.0) for c in layout])


def filter_altitude(times, heights, *, sigma: float, acceleration_density: float, velocity_sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """1-D constant-velocity Kalman filter of the heights h_k (m) at irregular times t_k (s).

    State (h, ḣ); prior (h_0, 0) with covariance diag(σ², σ_v²) — the first fix
    taken as the first estimate, so step 0 has no further update.  Step k ≥ 1
    over Δt = t_k − t_{k−1}: F = [[1, Δt], [0, 1]] and the continuous white-noise
    acceleration model Q = q [[Δt³/3, Δt²/2], [Δt²/2, Δt]] (q the acceleration
    density in m²/s³; Bar-Shalom, Li & Kirubarajan 2001, §6.2.2, eq. 6.2.2-12);
    update with H = [1, 0], R = σ²: S = P₀₀ + σ², K = P[:, 0]/S (scalar
    innovation, no matrix inverse), Joseph form P ← (I − K H) P (I − K H)ᵀ + K σ² Kᵀ.

    Returns ``mean`` (K, 2) (height, climb rate) and ``var`` (K, 2) (their variances);
    a ValueError names a bad input (lengths, non-increasing times, non-finite heights).
    """
    t = np.asarray(times, dtype=np.float64)
    h = np.asarray(heights, dtype=np.float64)
    if t.ndim != 1 or h.shape != t.shape or t.size == 0:
        raise ValueError(f"times, heights: expected two 1-D arrays of one length ≥ 1, got shapes {t.shape} and {h.shape}")
    if not np.all(np.isfinite(h)):
        raise ValueError("heights: expected finite values (the reader drops bad altitude cells)")
    if np.any(np.diff(t) <= 0) or not np.all(np.isfinite(t)):
        raise ValueError("times: expected finite, strictly increasing report times")
    r = check_positive(sigma, "sigma") ** 2
    q = check_positive(acceleration_density, "acceleration_density")
    x = np.array([h[0], 0.0])
    P = np.diag([r, check_positive(velocity_sigma, "velocity_sigma") ** 2])
    means, variances = np.empty((t.size, 2)), np.empty((t.size, 2))
    means[0], variances[0] = x, np.diag(P)
    identity = np.eye(2)
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        F = np.array([[1.0, dt], [0.0, 1.0]])
        Q = q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
        x = F @ x
        P = F @ P @ F.T + Q
        S = P[0, 0] + r
        gain = P[:, 0] / S
        x = x + gain * (h[k] - x[0])
        A = identity - np.outer(gain, [1.0, 0.0])
        P = A @ P @ A.T + r * np.outer(gain, gain)
        means[k], variances[k] = x, np.diag(P)
    return means, variances


def record_track(recorder, name, times, measured=None, estimated=None, lat_lon_measured=None, lat_lon_estimated=None) -> None:
    """What ``hybridtrack track`` adds to the estimator's own logging (``docs/real_data.md``, *What the recording
    shows*; the entity paths in ``docs/recording.md``): ``measured``, ``estimated`` (K, 3) east, north, altitude (m)
    and ``lat_lon_measured``, ``lat_lon_estimated`` (K, 2) degrees (:meth:`~hybridtrack.recording.RerunRecorder.log_geo_path`);
    a NullRecorder ignores them."""
    steps = np.arange(len(times), dtype=np.int64)
    for log, entity, points in (
        (recorder.log_path, "world/measurements/altitude", measured),
        (recorder.log_path, f"world/estimate/{name}/altitude", estimated),
        (recorder.log_geo_path, "map/measurements", lat_lon_measured),
        (recorder.log_geo_path, f"map/estimate/{name}", lat_lon_estimated),
    ):
        if points is not None:
            log(entity, steps, points, times)


def _summary_mode(model) -> tuple[str, float | None]:
    radius = getattr(model, "radius", None)
    return SUMMARY_NAMES.get(model.name, model.name), (None if radius is None else float(radius))


def estimated_turn_rate(models, run, layout) -> np.ndarray:
    """ω̂ (K,) rad/s: of a multiple-model run the mean of the turn-rate models' own estimates (the models with
    ``omega`` in their layout), weighted by their probabilities — not shrunk towards the 0 that the other
    models lack it at; else the run's ω̂."""
    i = layout.index("omega")
    own = np.array(["omega" in m.layout for m in models])
    if getattr(run, "model_means", None) is None or not own.any():
        return run.means[:, i]
    mu = run.mode_probabilities[:, own]
    return np.sum(mu * run.model_means[:, own, i], axis=1) / np.maximum(np.sum(mu, axis=1), 1e-300)


def _step_modes(models, run, layout, rule=None) -> tuple[list[str], list[float | None]]:
    """The summary (mode, radius) of every step.  ``rule`` (``[segments]``) ``by = "motion"``: straight, left or
    right turn, stop by the hysteresis of :func:`~hybridtrack.apps.mode_labels.motion_states` on
    :func:`estimated_turn_rate` and |v̂| (radius None).  Else the followed (most probable) model's; a model with
    the turn rate in its state (``omega``) is a left turn where the estimated ω > 0 and a right turn where it is
    negative (its radius varies along the turn: None)."""
    if rule is not None and rule["by"] == "motion":
        thresholds = {
            "omega_on": math.radians(rule["turn_rate_on"]),
            "omega_off": math.radians(rule["turn_rate_off"]),
            "v_stop": rule["stop_speed"],
            "v_go": rule["go_speed"],
        }
        speed = np.hypot(run.means[:, layout.index("vx")], run.means[:, layout.index("vy")])
        modes = motion_states(estimated_turn_rate(models, run, layout), speed, thresholds)
        return modes, [None] * len(modes)
    omega = run.means[:, layout.index("omega")] if "omega" in layout else None
    out = []
    for k, i in enumerate(run.mode):
        model = models[int(i)]
        out.append((("left_turn" if omega[k] > 0 else "right_turn"), None) if "omega" in model.layout else _summary_mode(model))
    modes, radii = zip(*out)
    return list(modes), list(radii)


def describe_segments(segments: list[dict], times: np.ndarray, means: np.ndarray, layout: Sequence[str], epoch=None) -> list[dict]:
    """Each segment of :func:`segments_of` with what the estimate says about it: ``mean_speed`` (m/s, the mean of
    |v̂| over its steps), ``heading_change`` (degrees, positive to the left (counter-clockwise): the unwrapped
    heading atan2(v̂y, v̂x) at its end minus at its start) and ``mean_turn_rate`` (°/s, heading_change over its
    duration; None for a segment of no duration); with ``epoch`` (the UTC instant of t = 0) ``start_utc`` and
    ``end_utc`` (ISO 8601)."""
    vx, vy = means[:, layout.index("vx")], means[:, layout.index("vy")]
    speed, heading = np.hypot(vx, vy), np.degrees(np.unwrap(np.arctan2(vy, vx)))
    out = []
    for segment in segments:
        first, last = np.searchsorted(times, segment["start"]), np.searchsorted(times, segment["end"])
        steps = slice(first, max(last, first + 1))  # its own steps (the last segment: to the last step)
        change = float(heading[min(last, len(times) - 1)] - heading[first])
        duration = segment["end"] - segment["start"]
        extra = {
            "mean_speed": float(np.mean(speed[steps])),
            "heading_change": change,
            "mean_turn_rate": change / duration if duration > 0 else None,
        }
        if epoch is not None:
            extra |= {key + "_utc": utc_text(epoch, segment[key]) for key in ("start", "end")}
        out.append(segment | extra)
    return out


def utc_text(epoch, seconds: float) -> str:
    """ISO 8601 UTC of ``epoch`` + ``seconds`` (to the microsecond)."""
    return (epoch + timedelta(seconds=float(seconds))).astimezone(UTC).isoformat().replace("+00:00", "Z")


def segments_of(times: np.ndarray, modes: Sequence[str], radii: Sequence[float | None]) -> list[dict]:
    """Runs of equal (mode, radius) over the steps: start = time of the first step, end = time of the next run's
    first step (the last run ends at the last time)."""
    out: list[dict] = []
    for k, (m, r) in enumerate(zip(modes, radii)):
        if out and out[-1]["mode"] == m and out[-1]["radius"] == r:
            continue
        if out:
            out[-1]["end"] = float(times[k])
        out.append({"start": float(times[k]), "end": float(times[-1]), "mode": m, "radius": r})
    return out


def output_name(identifier: str) -> str:
    """The file stem of an object's outputs (``<stem>.rrd``, ``<stem>.npz``): the id with characters other than
    letters, digits, ``.``, ``_``, ``-`` replaced by ``_`` (a leading ``.`` gets a ``_`` before it)."""
    name = re.sub(r"[^A-Za-z0-9._-]", "_", identifier) or "track"
    return "_" + name if name.startswith(".") else name


def track_one(
    track: Track,
    config: dict,
    out: Path | None = None,
    registry=None,
    *,
    origin: Sequence[float] | None = None,
    projection: str = "enu",
    epoch=None,
    smooth: bool = False,
    lag: float | None = None,
    record: bool = True,
    run=None,
) -> dict:
    """Run the configured estimator on one track (``run``: its causal run, computed already — :func:`track_file`
    runs the objects of a file as one batch, :func:`run_objects`); write ``out/<id>.rrd`` (unless ``record`` is
    False) and ``.npz`` (when ``out`` is given); return the object's summary entry ``{"id", "output", "segments",
    "decisions"}`` (``output`` the file stem of its ``.rrd`` and ``.npz``, :func:`output_name`).

    ``origin`` (lat°, lon°, h m) and ``projection``: the tangent plane the track was projected to (the
    :class:`~hybridtrack.io.track_files.TrackFile`'s); given, the recording gets the map view and the altitude is the
    height above the origin's height (else the altitude column as read).  ``epoch`` (the UTC instant of t = 0, for
    files of ISO time stamps): the recording gets a ``utc`` timeline and the segments their UTC start and end.
    ``smooth`` (fixed interval) or ``lag`` (seconds, fixed lag): the outputs are the algorithm's smoothed run
    (its ``smooth(run, lag)``, e.g. the multiple-model mode smoother), recorded beside the causal one as
    ``<name>_smoothed``."""
    from hybridtrack.recording import RerunRecorder
    from hybridtrack.recording.recorder import log_mode

    estimator, sensor, models = build_tracker(config, registry)
    layout = estimator.layout
    xy = np.asarray(track.positions[:, :2], dtype=float)
    name = output_name(track.id)
    heights = None
    if track.positions.shape[1] == 3:
        heights = np.asarray(track.positions[:, 2], dtype=float)
        if origin is not None:  # the geodetic height above the origin's (the ENU up also holds the Earth's curvature)
            heights = unproject(track.positions, origin=origin, projection=projection)[:, 2] - (list(origin) + [0.0])[2]
    altitude = filter_altitude(track.times, heights, **config["altitude"]) if heights is not None else None
    recording = out is not None and record
    recorder = RerunRecorder(out / f"{name}.rrd", {"object": track.id, "config": config}, epoch=epoch) if recording else None
    with recorder if recorder is not None else contextlib.nullcontext():  # a RerunRecorder closes on exit
        measured = measurements_of(track, config)
        if run is None:
            run = estimator.run(measured, track_prior(track, config, layout), times=track.times)
        if recorder is not None:
            record_run(estimator, run, recorder, measured)
        _check_finite(run, track)
        if smooth or lag is not None:
            run = estimator.smooth(run, lag)
            _check_finite(run, track)
            if recorder is not None:
                recorder.log_result(run, name=f"{estimator.name}_smoothed", sensors=(), measurements={})
        est_xy = run.means[:, [layout.index("x"), layout.index("y")]]
        geo = (None, None)
        if origin is not None:  # with heights, the ENU up of the filtered height: ĥ + (u − h) of the fix (the curvature)
            estimated_enu = est_xy if heights is None else np.column_stack([est_xy, altitude[0][:, 0] + track.positions[:, 2] - heights])
            geo = tuple(unproject(p, origin=origin, projection=projection)[:, :2] for p in (track.positions, estimated_enu))
        if recorder is not None:
            in_3d = (None, None) if heights is None else (np.column_stack([xy, heights]), np.column_stack([est_xy, altitude[0][:, 0]]))
            record_track(recorder, estimator.name, run.times, *in_3d, *geo)
        modes, radii = _step_modes(models, run, layout, config["segments"])
        if recorder is not None and config["segments"]["by"] == "motion":  # the summary's modes: lanes, the path's colours
            names = list(dict.fromkeys(modes))
            followed = SimpleNamespace(mode=np.array([names.index(m) for m in modes]), modes=tuple(names), times=run.times)
            log_mode(recorder, estimator.name, np.arange(len(modes)), followed, series="segment")
    if getattr(estimator, "detector", None) is not None:
        by_label = dict(zip(run.modes, models))
        decisions = [{"time": float(d.time), "mode": _summary_mode(by_label[d.mode])[0]} for d in run.decisions]
    else:
        changes = np.array(modes) if config["segments"]["by"] == "motion" else run.mode
        switches = np.flatnonzero(changes[1:] != changes[:-1]) + 1
        decisions = [{"time": float(run.times[k]), "mode": modes[k]} for k in switches]
    if out is not None:
        np.savez(
            out / f"{name}.npz",
            times=np.asarray(run.times, dtype=float),
            means=run.means,
            covariances=run.covs,
            modes=np.array(modes),
            radii=np.array([np.nan if r is None else r for r in radii]),
            layout=np.array(layout),
            positions=xy,
            **({} if geo[1] is None else {"lat_lon": geo[1]}),
            **({} if altitude is None else {"altitude_mean": altitude[0], "altitude_var": altitude[1], "altitude": heights}),
        )
    if epoch is not None:
        decisions = [d | {"time_utc": utc_text(epoch, d["time"])} for d in decisions]
    segments = describe_segments(segments_of(run.times, modes, radii), np.asarray(run.times, dtype=float), run.means, layout, epoch)
    return {"id": track.id, "output": name, "segments": segments, "decisions": decisions}


#: objects per batch of :func:`run_objects` (its memory grows with objects × the longest's reports)
BATCH_OBJECTS = 128


def run_objects(estimator, tracks: Sequence[Track], config: dict) -> list:
    """The estimator's causal runs of ``tracks``, the objects of a file stacked as runs of one bank
    (:func:`~hybridtrack.algorithms.bank_runs.run_ragged`, :data:`BATCH_OBJECTS` at a time, objects of similar
    length together), each equal to its run alone; a batch that raises (one object's arithmetic failing) gives
    None for its objects, which :func:`track_one` then runs alone, so that the failure is that object's own."""
    runs = [None] * len(tracks)
    order = sorted(range(len(tracks)), key=lambda i: len(tracks[i]))
    for first in range(0, len(order), BATCH_OBJECTS):
        chosen = order[first : first + BATCH_OBJECTS]
        batch = [tracks[i] for i in chosen]
        try:
            measured = [measurements_of(t, config) for t in batch]
            priors = [track_prior(t, config, estimator.layout) for t in batch]
            results = run_ragged(estimator, measured, priors, [t.times for t in batch])
        except Exception:  # each object of the batch then runs alone and reports its own failure
            continue
        for i, result in zip(chosen, results):
            runs[i] = result
    return runs


def _check_finite(run, track: Track) -> None:
    """A FloatingPointError naming the first report whose estimate (mean or covariance) is not finite."""
    finite = np.isfinite(run.means).all(axis=1) & np.isfinite(run.covs).all(axis=(1, 2))
    if not finite.all():
        k = int(np.argmin(finite))
        raise FloatingPointError(
            f"the estimate is not finite from the report of line {int(track.lines[k])} (t = {float(track.times[k]):g} s) on"
        )


def track_file(
    path: str | os.PathLike,
    config: str | os.PathLike | Mapping[str, Any],
    out: str | os.PathLike,
    ids: Iterable[str] | None = None,
    *,
    progress: bool = False,
    registry=None,
    smooth: bool = False,
    lag: float | None = None,
    strict: bool = False,
    geojson: bool = False,
) -> dict:
    """Track every object of ``path`` (or those in ``ids``) with ``config`` (a TOML path or a mapping; module
    docstring) and write ``out/<id>.rrd``, ``out/<id>.npz`` and ``out/summary.json``; returns the summary.

    Objects with fewer than ``min_reports`` reports (or none left: every row dropped by the reader) are skipped and
    listed under ``"skipped"``; an object whose tracking fails is listed there too, with ``"failed": true`` and the
    reason naming the object, the file and its lines, its partial outputs removed, and the other objects go on.
    An id not in the file is a ConfigError.  ``strict``: any problem of the reader (but the file's own
    "not available" codes) is a ConfigError listing them, before anything is tracked.  ``progress`` shows a tqdm
    bar over the objects (on stderr).  ``smooth`` / ``lag`` (seconds): fixed-interval / fixed-lag smoothing of
    recorded files (:func:`track_one`); a ConfigError for an algorithm without a smoother, for both at once and
    for a negative lag.  ``geojson``: also ``out/tracks.geojson``, each object's estimated track and its segments
    as LineStrings (:func:`hybridtrack.apps.geojson.tracks_geojson`); for a file in x/y metres (no latitude/longitude,
    no origin) a ConfigError, after reading the file and before anything is tracked."""
    from tqdm.auto import tqdm

    cfg = load_config(config, registry)
    if smooth and lag is not None:
        raise ConfigError("--smooth and --lag: give one (--smooth: fixed interval; --lag SECONDS: fixed lag)")
    if lag is not None and not (math.isfinite(lag) and lag >= 0):
        raise ConfigError(f"--lag {lag!r}: expected a number of seconds ≥ 0")
    estimator = build_tracker(cfg, registry)[0]  # the configuration's faults stop here, before any object
    if (smooth or lag is not None) and not callable(getattr(estimator, "smooth", None)):
        raise ConfigError(
            f"--smooth/--lag: algorithm {cfg['estimator']['algorithm']!r} has no smoother (the multiple-model algorithms imm, gpb1, gpb2 have)"
        )
    if not Path(path).is_file():
        raise FileNotFoundError(2, "no such position file", str(path))
    try:
        data = read_tracks(path, **cfg["reader"], warn=False)
    except TypeError as error:
        raise ConfigError(f"[reader]: {error}") from None
    if geojson and data.origin is None:
        raise ConfigError(
            f"--geojson needs latitude/longitude positions: {path} was read as x/y metres (no origin); give [reader] lat and lon columns"
        )
    faults = [p for p in data.problems if p.kind not in NOT_FAULTS]
    if strict and faults:
        raise ConfigError(f"--strict: {path}: {len(faults)} row problem(s): " + "; ".join(problem_summary(faults)))
    chosen = list(data.tracks) if ids is None else list(dict.fromkeys(ids))
    emptied = list(dict.fromkeys(p.id for p in data.problems if p.id is not None and p.id not in data.tracks))
    missing = [i for i in chosen if i not in data.tracks and i not in emptied]
    if missing:
        raise ConfigError(f"--id {missing[0]!r}: no such object in {path} ({len(data.tracks)} objects)")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    objects, skipped = [], []
    for key in emptied if ids is None else [i for i in chosen if i in emptied]:
        kinds = problem_summary([p for p in data.problems if p.id == key])
        skipped.append({"id": key, "reason": f"no report left: every row dropped ({'; '.join(kinds)})"})
    present = [i for i in chosen if i in data.tracks]
    for key in present:
        if len(data.tracks[key]) < cfg["min_reports"]:
            skipped.append({"id": key, "reason": f"{len(data.tracks[key])} reports < min_reports {cfg['min_reports']}"})
    keys = [key for key in present if len(data.tracks[key]) >= cfg["min_reports"]]
    runs = run_objects(estimator, [data.tracks[key] for key in keys], cfg)
    for key, run in tqdm(list(zip(keys, runs)), desc="objects", unit="object", disable=not progress, dynamic_ncols=True):
        track = data.tracks[key]
        options = dict(origin=data.origin, projection=data.projection or "enu", epoch=data.epoch, smooth=smooth, lag=lag, run=run)
        try:
            objects.append(track_one(track, cfg, out, registry, **options))
        except ConfigError:
            raise
        except Exception as error:  # one object never sinks the file: reported, its outputs removed
            for suffix in (".rrd", ".npz"):
                (out / f"{output_name(key)}{suffix}").unlink(missing_ok=True)
            where = f"{path}: object {key!r} (lines {int(track.lines.min())}–{int(track.lines.max())})"
            skipped.append({"id": key, "reason": f"{where}: tracking failed: {type(error).__name__}: {error}", "failed": True})
    summary = {
        "objects": objects,
        "skipped": skipped,
        "epoch_utc": None if data.epoch is None else utc_text(data.epoch, 0.0),
        "origin": None if data.origin is None else dict(zip(("lat", "lon", "h"), data.origin)),
        "max_speed": cfg["speed_limit"],
        "problem_counts": {kind: n for kind, n, _ in problem_kinds(data.problems)},
        "problems": [attrs.asdict(problem) for problem in data.problems],
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    if geojson:
        collection = tracks_geojson(summary, out)
        (out / "tracks.geojson").write_text(json.dumps(collection, allow_nan=False) + "\n", encoding="utf-8")
    return summary


def segments_frame(summary: Mapping[str, Any] | str | os.PathLike):
    """The segments of every object of a :func:`track_file` summary (the dict, or the path of ``summary.json``) as a
    :class:`pandas.DataFrame`: one row per segment, objects and their segments in order, a column ``id`` (the
    object's) and one per segment key (``start``, ``end``, ``mode``, ``radius``, ``mean_speed``, ``heading_change``,
    ``mean_turn_rate``, and for files of ISO time stamps ``start_utc``, ``end_utc`` as ISO 8601 text).  A summary
    without objects gives no rows (with those columns but the UTC ones).  A ValueError for a summary without an
    ``"objects"`` list; an ImportError (with the ``pip install`` line) without pandas."""
    from hybridtrack.engine.results import import_pandas

    pd = import_pandas("segments_frame")
    if isinstance(summary, (str, os.PathLike)):
        summary = json.loads(Path(summary).read_text(encoding="utf-8"))
    objects = summary.get("objects") if isinstance(summary, Mapping) else None
    if not isinstance(objects, list):
        got = f"keys {sorted(summary)}" if isinstance(summary, Mapping) else type(summary).__name__
        raise ValueError(f"summary: expected track_file's summary, a mapping with an 'objects' list, got {got}")
    rows = [{"id": entry["id"], **segment} for entry in objects for segment in entry["segments"]]
    plain = ["id", "start", "end", "mode", "radius", "mean_speed", "heading_change", "mean_turn_rate"]
    return pd.DataFrame(rows, columns=list(dict.fromkeys(key for row in rows for key in row)) or plain)


def problem_summary(problems) -> list[str]:
    """One text per problem kind, most common first: ``"3 bad_time (dropped); first: FILE:LINE: …"``."""
    return [f"{n} {kind} ({first.action}); first: {first.message}" for kind, n, first in problem_kinds(problems)]
