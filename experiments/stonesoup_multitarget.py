"""Stone Soup 1.9.1 multi-target trackers built from its own tutorials' components (issue 23, item 7c).

:func:`run_stonesoup` feeds plain arrays of unlabelled (x, y) detections, grouped in scans, to one Stone Soup
tracker and returns, per scan, every track the tracker holds (``tracker.tracks`` after the step) as numpy rows.

Components (Stone Soup documentation: tutorials "9 - Initiators & Deleters", "10 - Tracking in simulation:
bringing all components together", "8 - Joint probabilistic data association tutorial", the example "Comparing
Efficient Hypothesis Management (EHM) with probability associators" and the demo "Tracking AIS Reports Using
Stone Soup"):

* motion: ``CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])``, state
  [x, vx, y, vy], q = ``noise_density``; per axis F = [[1, τ], [0, 1]], Q = q [[τ³/3, τ²/2], [τ²/2, τ]] (the
  continuous white-noise acceleration model, Bar-Shalom, Li & Kirubarajan 2001, §6.2.2);
* measurement: ``LinearGaussian(4, (0, 2), σ² I)``: z = H x + w, H picks x and y, R = σ² I;
* filter: ``KalmanPredictor``, ``KalmanUpdater`` (x⁻ = F x, P⁻ = F P Fᵀ + Q; S = H P⁻ Hᵀ + R, K = P⁻ Hᵀ S⁻¹);
* association:

  - ``"gnn"``: ``GNNWith2DAssignment(DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=3))``
    (tutorials 9 and 10): the 2-D assignment minimising the summed Mahalanobis distances
    d = √(νᵀ S⁻¹ ν), a missed detection costing ``missed_distance``;
  - ``"nn"``: ``NearestNeighbour`` over the same hypothesiser (the AIS demo): greedy, the best remaining
    track-detection pair (smallest distance) is fixed first, each detection used once;
  - ``"jpda"`` / ``"jpda_ehm"``: ``JPDA`` (exhaustive enumeration of the joint events) / ``JPDAwithEHM``
    (Maskell, Briers & Wright 2004, efficient hypothesis management) over
    ``PDAHypothesiser(predictor, updater, clutter_spatial_density=λ, prob_detect=P_D, prob_gate=P_G)`` (tutorial 8,
    the EHM example), run by ``MultiTargetMixtureTracker``: each track's posterior is the Gaussian mixture of its
    association hypotheses reduced to one Gaussian (Bar-Shalom, Daum & Huang 2009);

* initiation: ``MultiMeasurementInitiator(prior_state=GaussianState(0, diag(σ², v², σ², v²)), measurement_model,
  deleter=UpdateTimeStepsDeleter(2), data_associator=GNNWith2DAssignment(distance hypothesiser), updater,
  min_points=3)`` (tutorial 10's ``min_points = 3``; the position entries of the prior are replaced by the
  detection and R).  The same GNN initiator serves every method (the EHM example's initiator
  is GNN-based too: ``GlobalNearestNeighbour`` over its ``PDAHypothesiser``).  Tentative tracks stay
  inside the initiator; the tracker's ``tracks`` are the confirmed ones;
* deletion, option ``deleter``:

  - ``"covariance"`` (default, tutorials 9 and 10): ``CovarianceBasedDeleter(covariance_threshold)`` on the trace
    of the whole state covariance, as the tutorials.  Tutorial 10 deletes at trace 2 with R = 0.25 I, i.e. at
    8 σ²; the default ``covariance_threshold`` is that same multiple, 8 σ² (m², the velocity variances, in
    m²/s², adding to it as in the tutorial);
  - ``"time"`` (the AIS demo): ``UpdateTimeDeleter(timedelta(seconds=time_since_update))``, default 600 s (the
    demo's 10 minutes): a track is deleted when no detection has updated it for that long.  On 1 s scans that
    keeps a lost track for 600 scans: pass a ``time_since_update`` suited to the scans.

Options (``**options`` of :func:`run_stonesoup`, all keyword): ``deleter``, ``covariance_threshold`` (m²,
default 8 σ²), ``time_since_update`` (s, default 600), ``velocity_sigma`` v (m/s, default √10: the AIS demo's
velocity variance 10), ``min_points`` (3), ``missed_distance`` (3), ``initiator_steps`` (the initiator's
``UpdateTimeStepsDeleter``, 2), ``prob_gate`` (JPDA's P_G, 0.95, Stone Soup's default).

Detections are built before the clock starts (``Detection(z, timestamp, measurement_model)``, timestamps
2016-01-01 + scan time), then a generator yields ``(timestamp, set of detections)`` per scan (empty scans
included) as the tracker's detector; :attr:`StoneSoupRun.seconds` is the wall time of the tracker's steps only
(``next(tracker)``; building detections and collecting rows are outside it).
"""

from __future__ import annotations

import datetime
import math
import time
from dataclasses import dataclass

import numpy as np

METHODS = ("gnn", "nn", "jpda", "jpda_ehm")
DELETERS = ("covariance", "time")
ORIGIN = datetime.datetime(2016, 1, 1)
DEFAULTS = {
    "deleter": "covariance",
    "covariance_threshold": None,  # None: 8 σ² (tutorial 10's limit 2 at R = 0.25 I)
    "time_since_update": 600.0,
    "velocity_sigma": math.sqrt(10.0),
    "min_points": 3,
    "missed_distance": 3.0,
    "initiator_steps": 2,
    "prob_gate": 0.95,
}
COVARIANCE_MULTIPLE = 8.0


@dataclass
class StoneSoupRun:
    """Rows (one per scan per track held by the tracker after that scan) and the run's counts."""

    time: np.ndarray
    track_id: np.ndarray
    x: np.ndarray
    y: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    tracks_created: int
    seconds: float
    detections: int


def _positive(name: str, value, *, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise ValueError(f"{name}: expected a finite number {'≥' if allow_zero else '>'} 0, got {value}")
    return value


def _count(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected an int, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name}: expected an int ≥ {minimum}, got {value}")
    return int(value)


def _inputs(scan_times, scan, z):
    """Check the arrays; returns (scan_times (K,), scan (N,) int, z (N, 2))."""
    scan_times = np.asarray(scan_times, dtype=float)
    if scan_times.ndim != 1 or scan_times.size == 0:
        raise ValueError(f"scan_times: expected a non-empty (K,) array, got shape {scan_times.shape}")
    if not np.all(np.isfinite(scan_times)) or np.any(np.diff(scan_times) <= 0):
        raise ValueError("scan_times: expected finite, strictly increasing seconds")
    scan = np.asarray(scan)
    if scan.ndim != 1 or (scan.size and not np.issubdtype(scan.dtype, np.integer)):
        raise ValueError(f"scan: expected a (N,) integer array, got shape {scan.shape} dtype {scan.dtype}")
    scan = scan.astype(np.int64)
    if scan.size and (scan.min() < 0 or scan.max() >= scan_times.size):
        raise ValueError(f"scan: expected indices in [0, {scan_times.size}), got [{scan.min()}, {scan.max()}]")
    z = np.asarray(z, dtype=float)
    if z.shape != (scan.size, 2):
        raise ValueError(f"z: expected shape ({scan.size}, 2) (one x, y per entry of scan), got {z.shape}")
    if not np.all(np.isfinite(z)):
        raise ValueError("z: expected finite x, y")
    return scan_times, scan, z


def _options(options: dict, sigma: float) -> dict:
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"run_stonesoup: unknown option(s) {unknown}; expected some of {sorted(DEFAULTS)}")
    chosen = {**DEFAULTS, **options}
    if chosen["deleter"] not in DELETERS:
        raise ValueError(f"deleter: expected one of {DELETERS}, got {chosen['deleter']!r}")
    if chosen["covariance_threshold"] is None:
        chosen["covariance_threshold"] = COVARIANCE_MULTIPLE * sigma**2
    for name in ("covariance_threshold", "time_since_update", "velocity_sigma", "missed_distance"):
        chosen[name] = _positive(name, chosen[name])
    chosen["min_points"] = _count("min_points", chosen["min_points"], 1)
    chosen["initiator_steps"] = _count("initiator_steps", chosen["initiator_steps"], 1)
    chosen["prob_gate"] = _positive("prob_gate", chosen["prob_gate"])
    if chosen["prob_gate"] >= 1:
        raise ValueError(f"prob_gate: expected a probability in (0, 1), got {chosen['prob_gate']}")
    return chosen


def build_tracker(
    detector, *, method: str, sigma: float, noise_density: float, detection_probability: float, clutter_density: float, **options
):
    """The Stone Soup tracker for ``method`` (components in the module docstring), reading ``detector``.

    Returns ``(tracker, measurement_model)``; options are checked and defaulted as in :func:`run_stonesoup`.
    """
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment, NearestNeighbour
    from stonesoup.dataassociator.probability import JPDA, JPDAwithEHM
    from stonesoup.deleter.error import CovarianceBasedDeleter
    from stonesoup.deleter.time import UpdateTimeDeleter, UpdateTimeStepsDeleter
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    sigma = _positive("sigma", sigma)
    noise_density = _positive("noise_density", noise_density)
    detection_probability = _positive("detection_probability", detection_probability)
    if detection_probability > 1:
        raise ValueError(f"detection_probability: expected a probability in (0, 1], got {detection_probability}")
    clutter_density = _positive("clutter_density", clutter_density, allow_zero=not method.startswith("jpda"))
    chosen = _options(options, sigma)

    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(noise_density), ConstantVelocity(noise_density)])
    measurement = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * sigma**2)
    predictor, updater = KalmanPredictor(transition), KalmanUpdater(measurement)
    distance = DistanceHypothesiser(predictor, updater, measure=Mahalanobis(), missed_distance=chosen["missed_distance"])
    v2 = chosen["velocity_sigma"] ** 2
    initiator = MultiMeasurementInitiator(
        prior_state=GaussianState(np.zeros((4, 1)), np.diag([sigma**2, v2, sigma**2, v2])),
        measurement_model=measurement,
        deleter=UpdateTimeStepsDeleter(chosen["initiator_steps"]),
        data_associator=GNNWith2DAssignment(distance),
        updater=updater,
        min_points=chosen["min_points"],
    )
    if chosen["deleter"] == "covariance":
        deleter = CovarianceBasedDeleter(covar_trace_thresh=chosen["covariance_threshold"])
    else:
        deleter = UpdateTimeDeleter(datetime.timedelta(seconds=chosen["time_since_update"]))
    if method in ("gnn", "nn"):
        associator = (GNNWith2DAssignment if method == "gnn" else NearestNeighbour)(distance)
        tracker_class = MultiTargetTracker
    else:
        probability = PDAHypothesiser(
            predictor=predictor,
            updater=updater,
            clutter_spatial_density=clutter_density,
            prob_detect=detection_probability,
            prob_gate=chosen["prob_gate"],
        )
        associator = (JPDA if method == "jpda" else JPDAwithEHM)(probability)
        tracker_class = MultiTargetMixtureTracker
    tracker = tracker_class(initiator=initiator, deleter=deleter, detector=detector, data_associator=associator, updater=updater)
    return tracker, measurement


def _feeder(scans: list):
    """The tracker's detector: yields the prepared ``(timestamp, set of Detection)`` of each scan in turn."""
    yield from scans


def run_stonesoup(
    scan_times,
    scan,
    z,
    *,
    method: str,
    sigma: float,
    noise_density: float,
    detection_probability: float,
    clutter_density: float,
    max_scans: int | None = None,
    **options,
) -> StoneSoupRun:
    """Run one Stone Soup tracker over the scans; one row per scan per track in ``tracker.tracks`` after the step.

    scan_times (K,) seconds, strictly increasing; scan (N,) scan index of each detection; z (N, 2) x, y in metres.
    ``method`` is ``"gnn"``, ``"nn"``, ``"jpda"`` or ``"jpda_ehm"``; ``clutter_density`` λ (detections per m² per
    scan) and ``detection_probability`` P_D are used by the JPDA hypothesiser only (λ must then be > 0).
    ``max_scans`` keeps the first scans only (``None``: all).  ``options``: see the module docstring.
    Track ids are 0, 1, … in order of confirmation (within a scan, by the new track's x then y).
    """
    from stonesoup.types.detection import Detection

    scan_times, scan, z = _inputs(scan_times, scan, z)
    kept = scan_times.size if max_scans is None else min(_count("max_scans", max_scans, 1), scan_times.size)
    feed: list = []
    tracker, measurement = build_tracker(
        _feeder(feed),
        method=method,
        sigma=sigma,
        noise_density=noise_density,
        detection_probability=detection_probability,
        clutter_density=clutter_density,
        **options,
    )
    stamps = [ORIGIN + datetime.timedelta(seconds=float(t)) for t in scan_times[:kept]]
    order = np.argsort(scan, kind="stable")
    starts = np.searchsorted(scan[order], np.arange(kept + 1))
    for k in range(kept):
        rows = order[starts[k] : starts[k + 1]]
        feed.append((stamps[k], {Detection(z[i].reshape(2, 1), timestamp=stamps[k], measurement_model=measurement) for i in rows}))
    detections = int(starts[kept])

    ids: dict[str, int] = {}
    out_k, out_id, out_state = [], [], []
    seconds = 0.0
    steps = iter(tracker)
    for k in range(kept):
        start = time.perf_counter()
        _, tracks = next(steps)
        seconds += time.perf_counter() - start
        states = {track.id: np.asarray(track.state_vector, dtype=float).ravel() for track in tracks}
        for new in sorted((i for i in states if i not in ids), key=lambda i: (states[i][0], states[i][2])):
            ids[new] = len(ids)
        for track_id in sorted(states, key=ids.__getitem__):
            out_k.append(k)
            out_id.append(ids[track_id])
            out_state.append(states[track_id])

    state = np.asarray(out_state, dtype=float).reshape(-1, 4)
    return StoneSoupRun(
        time=scan_times[np.asarray(out_k, dtype=np.int64)],
        track_id=np.asarray(out_id, dtype=np.int64),
        x=state[:, 0].copy(),
        y=state[:, 2].copy(),
        vx=state[:, 1].copy(),
        vy=state[:, 3].copy(),
        tracks_created=len(ids),
        seconds=seconds,
        detections=detections,
    )
