"""Peak memory of a long bank run (with and without a recording) and of ``hybridtrack inspect`` on its file.

Each case runs in its own child process (``python benchmarks/memory.py --case …``)
so that one case's memory cannot hide another's.  What is measured: the
resident set size (RSS) of the child, the whole process (numpy arrays, Python
objects, rerun's native buffers), read from ``/proc/self/status`` (Linux): the
peak ``VmHWM`` is reset through ``/proc/self/clear_refs`` just before the case
starts, and ``peak_bytes`` = VmHWM at the end − VmRSS at the start (after the
imports and the simulated measurements).

* ``run`` — a ``--steps``-step (default 100,000) 21-filter Kalman bank (straight
  + left and right turns of radii 1…10) without recording; reference: the bytes of
  the arrays the run returns (times, means, covariances, NIS, ℓ, ν); target ≤ 1.5×.
* ``run_recorded`` — the same run streamed to a Rerun file; same reference and target.
* ``inspect`` — :class:`~hybridtrack.recording.inspection.RecordingFile` and its summary (what
  ``hybridtrack inspect`` does) on that file; reference: the file size; target ≤ 2×.

    python benchmarks/memory.py --json memory.json [--steps 100000]

Output: ``{"cases": [{"name", "peak_bytes", "reference_bytes", "ratio", "target"}, …], …}``.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGETS = {"run": 1.5, "run_recorded": 1.5, "inspect": 2.0}


def _status(field: str) -> int:
    """A ``/proc/self/status`` memory field in bytes."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"/proc/self/status has no {field}")


def _start() -> int:
    Path("/proc/self/clear_refs").write_text("5")  # reset the peak (VmHWM) to the current RSS
    return _status("VmRSS")


def _bank_run(steps: int, path: str | None) -> dict:
    import numpy as np

    from hybridtrack import Gaussian, Schedule
    from hybridtrack.engine.pipeline import Pipeline
    from hybridtrack.engine.simulate import simulate
    from hybridtrack.recording import RerunRecorder
    from hybridtrack_plugins.sensors.position import PositionSensor

    x0 = np.array([0.0, 0.0, 0.0, 2.0])
    sensors = [PositionSensor(name="a")]
    _, z = simulate(Schedule.from_rows([("straight", steps - 1)]), x0, 0.1, sensors, seed=1)
    models = ["straight"] + [(turn, {"radius": float(r)}) for turn in ("left_turn", "right_turn") for r in range(1, 11)]
    recorder = RerunRecorder(path, {"benchmark": "memory"}) if path else None
    start = _start()
    clock = time.perf_counter()
    pipeline = Pipeline(
        models=models, estimator="kalman", sensors=sensors, measurements=z, prior=Gaussian(x0, np.eye(4)), tau=0.1, recorder=recorder
    )
    result = pipeline.run()
    if recorder is not None:
        recorder.close()
    peak = _status("VmHWM") - start
    reference = sum(a.nbytes for a in (result.times, result.means, result.covs, result.nis, result.loglik, result.innovations))
    return {"peak_bytes": peak, "reference_bytes": reference, "seconds": time.perf_counter() - clock}


def _inspect(path: str) -> dict:
    from hybridtrack.recording.inspection import RecordingFile

    start = _start()
    clock = time.perf_counter()
    RecordingFile(path).summary()
    return {"peak_bytes": _status("VmHWM") - start, "reference_bytes": Path(path).stat().st_size, "seconds": time.perf_counter() - clock}


def _child(case: str, steps: int, path: str) -> dict:
    """Run one case in a fresh interpreter and return its measurement."""
    out = subprocess.run(
        [sys.executable, __file__, "--case", case, "--steps", str(steps), "--file", path], capture_output=True, text=True, check=False
    )
    if out.returncode != 0:
        raise RuntimeError(f"case {case} failed:\n{out.stderr}")
    return json.loads(out.stdout.splitlines()[-1])


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="PATH", help="write the results here")
    parser.add_argument("--steps", type=int, default=100_000, help="steps of the bank run (default 100,000)")
    parser.add_argument("--case", choices=sorted(TARGETS), help=argparse.SUPPRESS)
    parser.add_argument("--file", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.steps < 2:
        parser.error(f"--steps: expected at least 2 steps, got {args.steps}")
    if args.case:  # in the child
        if args.case == "inspect":
            measured = _inspect(args.file)
        else:
            measured = _bank_run(args.steps, args.file if args.case == "run_recorded" else None)
        print(json.dumps(measured))
        return measured
    cases = []
    with tempfile.TemporaryDirectory() as folder:
        path = str(Path(folder) / "run.rrd")
        for name in ("run", "run_recorded", "inspect"):
            measured = _child(name, args.steps, path)
            ratio = measured["peak_bytes"] / measured["reference_bytes"]
            cases.append({"name": name, **measured, "ratio": ratio, "target": TARGETS[name], "met": ratio <= TARGETS[name]})
    result = {
        "cases": cases,
        "steps": args.steps,
        "filters": 21,
        "measure": "peak RSS of a child process (VmHWM after resetting it via /proc/self/clear_refs) minus its RSS at the start of the case",
        "machine": platform.machine(),
        "python": platform.python_version(),
    }
    print(json.dumps(result, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
