"""``hybridtrack track`` on unlabelled detections: a configuration with an ``[association]`` table.

The file's rows are detections without identities (``time,x,y`` or latitude/longitude; no ``id`` in
``[reader]``), grouped into scans by a scan column (``[association] scan``) or a time window (``scan_window``
seconds; :func:`~hybridtrack.io.detection_files.read_detections`).  Two stages:

1. the multi-target tracker (:class:`~hybridtrack.algorithms.multitarget.tracker.MultiTargetTracker`): GNN or
   JPDA over tracks, or MHT (:class:`~hybridtrack.algorithms.multitarget.mht.MHTTracker`, ``method = "mht"``:
   the ``hypotheses`` best global hypotheses, ``mht_scans``-scan pruning), each track a constant-velocity Kalman
   filter (``motion = "cv"``) or the IMM of ``[estimator]`` (``motion = "modes"``), confirmed and deleted by
   M-of-N or the track score;
2. per confirmed track, the configured ``[estimator]`` on the detections the track took, exactly as ``track``
   runs a labelled object (:func:`~hybridtrack.apps.tracking.run_objects`, :func:`~hybridtrack.apps.tracking.track_one`):
   its segments and decisions per track id in ``summary.json``.

Outputs: ``OUT/tracks.csv`` (``time,track_id,x,y,vx,vy,mode`` and ``lat,lon`` for latitude/longitude files: one
row per scan for every confirmed track alive at that scan, coasting ones included; ``time`` the scan's time in
seconds after the file's earliest time stamp; ``mode`` the track's segment at that time), ``OUT/summary.json`` (one
object per confirmed track) and ``OUT/tracks.rrd`` (every track in the 3-D and map views, coloured by id; births
and deletions as events).
"""

from __future__ import annotations

import inspect
import json
import math
from pathlib import Path

import attrs
import numpy as np

from hybridtrack.algorithms.multiple_model import MultipleModelEstimator
from hybridtrack.algorithms.multitarget.management import MofN, TrackScore
from hybridtrack.algorithms.multitarget.mht import MHTTracker
from hybridtrack.algorithms.multitarget.tracker import ASSOCIATIONS, INITIATIONS, MultiTargetTracker
from hybridtrack.apps.association_keys import ASSOCIATION_DEFAULTS
from hybridtrack.apps.tracking import ConfigError, build_tracker, load_config, run_objects, track_one, utc_text
from hybridtrack.core.plugins import resolve
from hybridtrack.io.detection_files import read_detections
from hybridtrack.io.track_files import Track, problem_kinds, unproject

MANAGEMENTS = ("m_of_n", "score")
#: ``[association] method``: the tracker's associations and multiple hypothesis tracking
METHODS = (*ASSOCIATIONS, "mht")
MOTIONS = ("cv", "modes")
#: ``[reader]`` keys of the reported course and speed: with ``[measurement] speed_sigma``/``course_sigma`` the tracks
#: measure the velocity each detection reports (its gate, its update, a new track's start)
_VELOCITY_KEYS = ("course", "speed", "speed_unit", "course_not_available", "speed_not_available")


def association_settings(config: dict, where: str = "config") -> dict:
    """The checked ``[association]`` table, defaults filled (a ConfigError naming the key otherwise)."""
    table = dict(config["association"])
    out = {key: table.get(key, default) for key, default in ASSOCIATION_DEFAULTS.items()}
    choices = {"method": METHODS, "motion": MOTIONS, "initiation": INITIATIONS, "management": MANAGEMENTS}
    for key, allowed in choices.items():
        if out[key] not in allowed:
            raise ConfigError(f"{where}: [association] {key} = {out[key]!r}; expected one of {list(allowed)}")
    if (out["scan_window"] is None) == (out["scan"] is None):
        raise ConfigError(
            f"{where}: [association] scan_window (seconds) or scan (the scan column): give one, got "
            f"scan_window = {out['scan_window']!r}, scan = {out['scan']!r}"
        )
    for key in (
        "scan_window",
        "clutter_density",
        "birth_density",
        "max_speed",
        "velocity_sigma",
        "noise_density",
        "deletion_drop",
        "max_coast",
        "reacquire_window",
    ):
        value = out[key]
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0)
        ):
            raise ConfigError(f"{where}: [association] {key} = {value!r}; expected a positive number")
    for key in ("detection_probability", "gate_probability", "false_track_probability", "track_loss_probability", "duplicate_probability"):
        value = out[key]
        if key == "duplicate_probability" and value is None:
            continue
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not 0 < value <= (1 if key == "detection_probability" else 0.999999)
        ):
            raise ConfigError(f"{where}: [association] {key} = {value!r}; expected a probability in (0, 1)")
    for key in ("confirm_hits", "confirm_scans", "delete_misses", "updates_per_scan", "hypotheses", "mht_scans", "duplicate_scans"):
        if isinstance(out[key], bool) or not isinstance(out[key], int) or out[key] < 1:
            raise ConfigError(f"{where}: [association] {key} = {out[key]!r}; expected a positive integer")
    reader = config["reader"]
    if reader.get("id") is not None:
        raise ConfigError(
            f"{where}: [reader] id = {reader['id']!r} with [association]: unlabelled detections have no id column "
            "(the association decides identities); leave it (or the preset) out of [reader]"
        )
    given = [key for key in _VELOCITY_KEYS[:2] if reader.get(key) is not None]
    if given and "speed_sigma" not in config["measurement"]:
        raise ConfigError(
            f"{where}: [reader] {given[0]} = {reader[given[0]]!r} with [association]: the reported course and speed are measured only"
            " with [measurement] speed_sigma (m/s) and course_sigma (degrees); give them, or leave course and speed out of [reader]"
        )
    if out["max_speed"] is None:
        out["max_speed"] = float(config["speed_limit"]["max_speed"])
    for key in ("duplicate_probability", "reacquire_window"):
        if out["method"] == "mht" and out[key] is not None:
            raise ConfigError(f"{where}: [association] {key} is for method = 'gnn' or 'jpda', not 'mht'")
    return out


def build_multitarget(config: dict, settings: dict, registry=None, built=None) -> MultiTargetTracker:
    """The tracker of a checked configuration: its per-track filter (``motion``), management and association
    (``method = "mht"``: an :class:`MHTTracker`, a subclass; ``built``: :func:`~hybridtrack.apps.tracking.build_tracker`'s
    result for ``config``, when the caller has it)."""
    estimator = (build_tracker(config, registry) if built is None else built)[0]
    if settings["motion"] == "modes":
        if not isinstance(estimator, MultipleModelEstimator):
            raise ConfigError(
                f"[association] motion = 'modes' runs [estimator]'s IMM per track; [estimator] algorithm = {config['estimator']['algorithm']!r} is not one"
                " (imm, gpb1, gpb2); use motion = 'cv' and [estimator] for the per-track segments"
            )
        per_track = estimator
    else:
        est = config["estimator"]
        density = settings["noise_density"] or est.get("noise_density")
        noise = {"noise_density": density} if density is not None else {"noise_cov": est["process_noise"] ** 2 * np.eye(2)}
        straight = resolve("motion_model", ("straight", noise), registry)
        per_track = MultipleModelEstimator([straight], [[1.0]], sensors=estimator.network.sensors, name="cv", registry=registry)
    if settings["management"] == "m_of_n":
        management = MofN(settings["confirm_hits"], settings["confirm_scans"], settings["delete_misses"], settings["max_coast"])
    else:
        management = TrackScore(
            settings["false_track_probability"], settings["track_loss_probability"], settings["deletion_drop"], settings["max_coast"]
        )
    mht = settings["method"] == "mht"
    try:
        return (MHTTracker if mht else MultiTargetTracker)(
            per_track,
            association=settings["method"],
            **({"hypotheses": settings["hypotheses"], "scans": settings["mht_scans"]} if mht else {}),
            management=management,
            detection_probability=settings["detection_probability"],
            clutter_density=settings["clutter_density"],
            birth_density=settings["birth_density"],
            gate_probability=settings["gate_probability"],
            initiation=settings["initiation"],
            max_speed=settings["max_speed"],
            velocity_sigma=settings["velocity_sigma"],
            updates_per_scan=settings["updates_per_scan"],
            seed_window=settings["seed_window"],
            **({} if mht else {key: settings[key] for key in ("duplicate_probability", "duplicate_scans", "reacquire_window")}),
        )
    except (TypeError, ValueError) as error:
        raise ConfigError(f"[association]: {error}") from None


def reported_course_speed(velocity, rows) -> dict:
    """``course`` (degrees clockwise from north, in [0, 360)) and ``speed`` (m/s) of the reported velocities
    (east, north) at ``rows``, for a :class:`~hybridtrack.io.track_files.Track` (None without velocities)."""
    if velocity is None:
        return {"course": None, "speed": None}
    v = velocity[rows]
    return {"course": np.degrees(np.arctan2(v[:, 0], v[:, 1])) % 360.0, "speed": np.hypot(v[:, 0], v[:, 1])}


def _reader_options(config: dict, settings: dict) -> dict:
    wanted = set(inspect.signature(read_detections).parameters) - {"source", "scan", "scan_window"}
    options = {key: value for key, value in config["reader"].items() if key in wanted}
    return options | {"scan": settings["scan"], "scan_window": settings["scan_window"]}


def _track_modes(result, objects: dict) -> list[str]:
    """The mode of each row of ``tracks.csv``: the segment of its track at its time (the last one after the track's
    last detection), else the per-track filter's most probable mode."""
    modes = [result.modes[m] for m in result.mode.tolist()]
    for track_id, entry in objects.items():
        segments = entry["segments"]
        if not segments:
            continue
        rows = np.flatnonzero(result.track_id == track_id)
        starts = np.array([s["start"] for s in segments])
        at = np.clip(np.searchsorted(starts, result.time[rows], side="right") - 1, 0, len(segments) - 1)
        for row, i in zip(rows.tolist(), at.tolist()):
            modes[row] = segments[i]["mode"]
    return modes


def write_tracks_csv(path: Path, result, modes, lat_lon=None) -> None:
    """``tracks.csv``: ``time,track_id,x,y,vx,vy,mode`` (and ``lat,lon``), one row per scan per confirmed track."""
    layout = result.layout
    columns = [result.means[:, layout.index(c)] for c in ("x", "y", "vx", "vy")]
    header = "time,track_id,x,y,vx,vy,mode" + (",lat,lon" if lat_lon is not None else "")
    lines = [header]
    for q in range(result.time.size):
        values = [f"{result.time[q]:.3f}", str(int(result.track_id[q]))] + [f"{c[q]:.3f}" for c in columns] + [modes[q]]
        if lat_lon is not None:
            values += [f"{lat_lon[q, 0]:.7f}", f"{lat_lon[q, 1]:.7f}"]
        lines.append(",".join(values))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def track_detections(path, config, out, *, registry=None, smooth: bool = False, lag: float | None = None, record: bool = True) -> dict:
    """Track the unlabelled detections of ``path`` with ``config`` (a TOML path, a mapping, or
    :func:`~hybridtrack.apps.tracking.load_config`'s checked result; module docstring); returns the summary.
    ``smooth`` / ``lag``: the per-track segments from the smoothed runs; ``record``: write ``tracks.rrd``."""
    if not (isinstance(config, dict) and "unlabelled" in config):
        config = load_config(config, registry)
    if not config["unlabelled"]:
        raise ConfigError(
            "track_detections: the configuration has no [association] table (a labelled file: hybridtrack.apps.tracking.track_file)"
        )
    settings = association_settings(config)
    built = build_tracker(config, registry)  # the per-track [estimator]: the association's modes and the segments
    tracker = build_multitarget(config, settings, registry, built)
    try:
        data = read_detections(path, **_reader_options(config, settings))
    except TypeError as error:
        raise ConfigError(f"[reader]: {error}") from None
    result = tracker.run(data.detections)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    detections = data.detections
    lines = np.asarray(data.lines)
    tracks = [
        Track(
            id=str(history.id),
            times=detections.times[history.detections],
            positions=detections.z[history.detections],
            lines=lines[history.detections],
            **reported_course_speed(detections.velocity, history.detections),
        )
        for history in result.tracks
    ]
    long_enough = [t for t in tracks if len(t) >= max(config["min_reports"], 2) and np.all(np.diff(t.times) > 0)]
    runs = run_objects(built[0], long_enough, config)
    options = dict(origin=data.origin, projection=data.projection or "enu", epoch=data.epoch, smooth=smooth, lag=lag)
    per_track = {int(t.id): track_one(t, config, None, registry, **options, run=run, tracker=built) for t, run in zip(long_enough, runs)}
    objects = []
    for history in result.tracks:
        entry = per_track.get(history.id, {"id": str(history.id), "segments": [], "decisions": []})
        times = {"born": history.born, "confirmed": history.confirmed, "deleted": history.deleted}
        entry = {"id": str(history.id), "detections": int(history.detections.size), **times} | {
            k: v for k, v in entry.items() if k in ("segments", "decisions")
        }
        if data.epoch is not None:
            entry |= {f"{k}_utc": None if v is None else utc_text(data.epoch, v) for k, v in times.items()}
        objects.append(entry)
    modes = _track_modes(result, {int(o["id"]): o for o in objects})
    lat_lon = None
    if data.origin is not None and result.time.size:
        lat_lon = unproject(result.positions(), origin=data.origin, projection=data.projection or "enu")[:, :2]
    write_tracks_csv(out / "tracks.csv", result, modes, lat_lon)
    if record:
        from hybridtrack.recording import RerunRecorder
        from hybridtrack.recording.multitarget import record_multitarget

        with RerunRecorder(out / "tracks.rrd", {"file": str(path), "config": config}, epoch=data.epoch) as recorder:
            record_multitarget(recorder, result, detections, lat_lon)
    summary = {
        "objects": objects,
        "skipped": [],
        "association": settings,
        "scans": int(detections.scan_times.size),
        "detections": int(detections.z.shape[0]),
        "tracks_started": int(result.started),
        "epoch_utc": None if data.epoch is None else utc_text(data.epoch, 0.0),
        "origin": None if data.origin is None else dict(zip(("lat", "lon", "h"), data.origin)),
        "max_speed": config["speed_limit"],
        "problem_counts": {kind: n for kind, n, _ in problem_kinds(data.problems)},
        "problems": [attrs.asdict(problem) for problem in data.problems],
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n", encoding="utf-8")
    return summary
