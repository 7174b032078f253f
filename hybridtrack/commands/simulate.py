"""``hybridtrack simulate``: a schedule's hybrid trajectory and its measurements to .npz and .rrd.

The schedule is a TOML file of ``[[segment]]`` tables (``mode``, ``steps``,
optional ``radius``, ``acceleration``) or, by default, Table 1 of seed 001.
One position sensor ``sensor`` measures (x, y) with R = r·I.  The .npz holds the
trajectory (``states``, ``layout``, ``steps``, ``times``, ``segment``, the
schedule rows, ``tau``) and the measurements as ``z_<sensor>`` (steps × m).
"""

from __future__ import annotations

import argparse

from hybridtrack.cli import Command


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--schedule", metavar="FILE.toml", help="schedule table (default: Table 1 of seed 001)")
    parser.add_argument("--x0", type=float, nargs="+", default=[0.0, 0.0, 0.0, 2.0], help="initial state in the first mode's layout")
    parser.add_argument("--tau", type=float, default=0.1, help="sampling period in seconds (default 0.1)")
    parser.add_argument("--process-noise", type=float, default=1e-3, metavar="Q", help="Q = q·I (default 1e-3)")
    parser.add_argument("--measurement-noise", type=float, default=0.01, metavar="R", help="R = r·I (default 0.01)")
    parser.add_argument("--no-noise", action="store_true", help="noise-free trajectory")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--npz", default="simulation.npz", help="output arrays (default simulation.npz)")
    parser.add_argument("--rrd", default="simulation.rrd", help="output recording (default simulation.rrd)")
    parser.add_argument("--no-record", action="store_true", help="write no recording")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from hybridtrack.plugins import resolve
    from hybridtrack.recording import log_measurements, open_recorder
    from hybridtrack.simulate import simulate
    from hybridtrack.types import SEED001_TABLE1, Schedule

    schedule = Schedule.from_toml(args.schedule) if args.schedule else SEED001_TABLE1
    sensor = resolve("sensor", ("position", {"name": "sensor", "noise_cov": args.measurement_noise * np.eye(2)}))
    configuration = {key: value for key, value in vars(args).items() if key not in ("run", "npz", "rrd", "no_record")}
    with open_recorder(None if args.no_record else args.rrd, {"command": "simulate", **configuration}) as recorder:
        truth, z = simulate(
            schedule,
            args.x0,
            args.tau,
            [sensor],
            seed=args.seed,
            recorder=recorder,
            process_noise=not args.no_noise,
            noise_cov=args.process_noise * np.eye(2),
        )
        log_measurements(recorder, [sensor], z, truth.steps, truth.times)
    truth.save_npz(args.npz, **{f"z_{name}": values for name, values in z.items()})
    segments = ", ".join(f"{s.mode}×{s.steps}" for s in schedule.segments)
    print(f"simulated {truth.states.shape[0] - 1} steps ({segments}) → {args.npz}" + ("" if args.no_record else f", {args.rrd}"))
    return 0


COMMAND = Command("simulate", "simulate a schedule's trajectory and measurements to .npz and .rrd", configure, run)
