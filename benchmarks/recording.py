"""Recording overhead: a 21-filter, 360-step adaptive run with and without a Rerun recording.

The adaptive estimator of seed 001 (Algorithm 1: at every switch a bank of
2n+1 = 21 filters, straight + left and right turns of radii 1…10, pairwise SPRT)
runs on the Table 1 trajectory; the same run is timed with ``recorder=None``
and with a :class:`~hybridtrack.recording.RerunRecorder` writing a file, in the
same process, median of ``--repeats`` (≥ 5).  Target: ≤ 20 % overhead.

    python benchmarks/recording.py --json recording.json
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from hybridtrack import SEED001_TABLE1, Gaussian
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import RerunRecorder
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
Q = np.diag([1e-3, 1e-3])


def one_run(truth, z, sensors, path: Path | None) -> float:
    start = time.perf_counter()
    recorder = RerunRecorder(path, {"benchmark": "recording"}) if path else None
    try:
        adaptive = KnownSwitchAdaptive(sensors=sensors, tau=0.1, r_min=1.0, r_max=10.0, n=10, noise_cov=Q)
        adaptive.run(z, Gaussian(X0, np.eye(4)), SEED001_TABLE1, recorder=recorder, truth=truth)
    finally:
        if recorder is not None:
            recorder.close()
    return time.perf_counter() - start


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="PATH", help="write the results here")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    if args.repeats < 5:
        parser.error("--repeats must be at least 5")
    sensors = [PositionSensor(name="sensor", noise_cov=0.1 * np.eye(2))]
    truth, z = simulate(SEED001_TABLE1, X0, 0.1, sensors, seed=1, noise_cov=Q)
    with tempfile.TemporaryDirectory() as folder:
        one_run(truth, z, sensors, None)  # warm-up: imports, plugin loading
        one_run(truth, z, sensors, Path(folder) / "warm.rrd")
        plain, recorded = [], []
        for i in range(args.repeats):  # interleaved, so drift hits both alike
            plain.append(one_run(truth, z, sensors, None))
            recorded.append(one_run(truth, z, sensors, Path(folder) / f"run{i}.rrd"))
        size = (Path(folder) / "run0.rrd").stat().st_size
    result = {
        "case": {
            "filters": 21,
            "steps": 360,
            "what": "KnownSwitchAdaptive (seed 001 Algorithm 1, 2n+1 = 21 filters) on the Table 1 trajectory, everything it records",
        },
        "repeats": args.repeats,
        "median_s_without_recording": statistics.median(plain),
        "median_s_with_recording": statistics.median(recorded),
        "overhead": statistics.median(recorded) / statistics.median(plain) - 1,
        "target_overhead": 0.20,
        "file_bytes": size,
        "machine": platform.machine(),
        "python": platform.python_version(),
    }
    print(json.dumps(result, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
