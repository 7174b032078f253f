"""``hybridtrack track`` on a whole file beside Stone Soup 1.9.1 running one constant-velocity Kalman filter per object.

The same reports, in the same process: the file is read once (``read_tracks`` with the config's ``[reader]``), then

* **hybridtrack** — :func:`~hybridtrack.apps.tracking.track_file`, the whole command (reading, the objects stacked
  as runs of one bank, the config's full mode bank, recordings, ``.npz``, ``summary.json``), timed as a user
  meets it; and, apart, the estimator alone (:func:`~hybridtrack.apps.tracking.run_objects`);
* **Stone Soup** — per object a ``KalmanPredictor`` / ``KalmanUpdater`` over ``ConstantVelocity`` (q of the
  config's ``noise_density``, per axis) and a ``LinearGaussian`` position measurement (σ of ``[measurement]``), the
  prior at the first fix, predicted to every report's time and updated: the filtering loop only (its reading,
  recording and output are not timed, which favours it).

Each is the median of ``--repeats`` runs, interleaved.  Reports per second = the objects' reports / seconds.  Apart,
``hybridtrack track FILE --config C --out …`` runs once as a user runs it, in a child process: its wall time and
its peak resident memory (the child's ``ru_maxrss``: imports, numba's compiled kernels, rerun, every buffer).
Targets (issue 22): hybridtrack's whole command ≥ 10 × Stone Soup's reports per second, the Solent file ≤ 5 s,
peak memory ≤ 250 MB.

    python benchmarks/track.py --json docs/results/track_bench.json [--file F --config C] [--repeats 3]
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hybridtrack.apps.tracking import build_tracker, load_config, run_objects, track_file
from hybridtrack.io.track_files import read_tracks

ROOT = Path(__file__).resolve().parents[1]
SOLENT = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"
SHIPS = ROOT / "examples" / "ships.toml"


def stone_soup_filter(tracks, sigma: float, density: float) -> float:
    """Seconds for one CV Kalman filter per track (Stone Soup), predict + update at every report."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(density), ConstantVelocity(density)])
    measurement = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * sigma**2)
    predictor, updater = KalmanPredictor(transition), KalmanUpdater(measurement)
    origin = datetime.datetime(2016, 1, 1)
    inputs = [
        (
            [origin + datetime.timedelta(seconds=float(t)) for t in track.times],
            [Detection(np.asarray(p[:2], dtype=float).reshape(2, 1), measurement_model=measurement) for p in track.positions],
        )
        for track in tracks
    ]
    start = time.perf_counter()
    for stamps, detections in inputs:
        first = detections[0].state_vector
        state = GaussianState(
            [[first[0, 0]], [0.0], [first[1, 0]], [0.0]], np.diag([sigma**2, 100.0, sigma**2, 100.0]), timestamp=stamps[0]
        )
        for stamp, detection in zip(stamps, detections):
            detection.timestamp = stamp
            prediction = predictor.predict(state, timestamp=stamp)
            state = updater.update(SingleHypothesis(prediction, detection))
    return time.perf_counter() - start


def command_memory(path: Path, config: Path, folder: Path) -> dict:
    """Wall seconds and peak RSS (bytes) of ``hybridtrack track`` in a child process (the first child this process
    waits for: ``RUSAGE_CHILDREN`` is the largest of them)."""
    entry = "import sys; from hybridtrack.cli import main; sys.exit(main())"  # the console script's own entry point
    command = [sys.executable, "-c", entry, "track", str(path), "--config", str(config), "--out", str(folder)]
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    seconds = time.perf_counter() - start
    return {
        "command": "hybridtrack track FILE --config CONFIG --out OUT",
        "seconds": seconds,
        "max_rss_bytes": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024,  # Linux: kB
    }


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="PATH", help="write the results here")
    parser.add_argument("--file", type=Path, default=SOLENT)
    parser.add_argument("--config", type=Path, default=SHIPS)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    config = load_config(args.config)
    data = read_tracks(args.file, **config["reader"], warn=False)
    tracks = [t for t in data.tracks.values() if len(t) >= config["min_reports"]]
    reports = sum(len(t) for t in tracks)
    estimator = build_tracker(config)[0]
    density = config["estimator"].get("noise_density", 0.001)
    whole, alone, stone = [], [], []
    with tempfile.TemporaryDirectory() as folder:
        command = command_memory(args.file, args.config, Path(folder) / "command")
        run_objects(estimator, tracks[:2], config)  # warm-up: imports, plugin loading
        for i in range(args.repeats):  # interleaved, so drift hits all alike
            start = time.perf_counter()
            track_file(args.file, args.config, Path(folder) / f"out{i}")
            whole.append(time.perf_counter() - start)
            start = time.perf_counter()
            run_objects(estimator, tracks, config)
            alone.append(time.perf_counter() - start)
            stone.append(stone_soup_filter(tracks, config["measurement"]["sigma"], density))
    seconds = {"track_file": statistics.median(whole), "estimator": statistics.median(alone), "stonesoup": statistics.median(stone)}
    result = {
        "file": str(args.file.relative_to(ROOT) if args.file.is_relative_to(ROOT) else args.file),
        "config": str(args.config.relative_to(ROOT) if args.config.is_relative_to(ROOT) else args.config),
        "objects": len(tracks),
        "reports": reports,
        "repeats": args.repeats,
        "hybridtrack": {
            "what": f"track_file: reading, {config['estimator']['algorithm']} over {len(config['estimator']['modes'])} modes,"
            " recordings, npz, summary",
            "seconds": seconds["track_file"],
            "reports_per_second": reports / seconds["track_file"],
            "estimator_seconds": seconds["estimator"],
            "estimator_reports_per_second": reports / seconds["estimator"],
        },
        "stonesoup": {
            "what": "one ConstantVelocity Kalman filter per object, predict + update per report (the loop only)",
            "seconds": seconds["stonesoup"],
            "reports_per_second": reports / seconds["stonesoup"],
        },
        "command": command,
        "ratio": seconds["stonesoup"] / seconds["track_file"],
        "estimator_ratio": seconds["stonesoup"] / seconds["estimator"],
        "targets": {"ratio": 10.0, "seconds": 5.0, "max_rss_bytes": 250e6},
        "machine": platform.machine(),
        "python": platform.python_version(),
    }
    print(json.dumps(result, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
