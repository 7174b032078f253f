"""``hybridtrack simulate``: a schedule's hybrid trajectory and its measurements to .npz and .rrd.

The schedule is a TOML file of ``[[segment]]`` tables (``mode``, ``steps``,
optional ``radius``, ``acceleration``) or, by default, Table 1 of seed 001.
Any registered motion model is a mode, nonlinear ones such as ``ship_turn``
(layout x, y, vx, vy, ω) included.  One position sensor ``sensor`` measures
(x, y) with R = r·I.  The .npz holds the trajectory (``states``, ``layout``,
``steps``, ``times``, ``segment``, the schedule rows, ``tau``) and the
measurements as ``z_<sensor>`` (steps × m).

``--x0`` is the initial state in the first mode's layout; by default x = y = 0,
vx = 0, vy = 2 (the other components 0) in that layout.  ``--process-noise q``
sets Q = q·I for the modes that take a ``noise_cov`` (default 1e-3); giving it
for a schedule with a mode that has its own noise parameters (``ship_turn``)
is an error rather than a silently ignored option.

Outputs are written to temporary files next to their targets and renamed when
everything succeeded: a failed run leaves no partial output, and an existing
file is only replaced by a complete one.  ``--npz`` is written to exactly the
path given (numpy would append ``.npz`` to other names).
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

from hybridtrack.cli import UsageError, integer_option, number_option
from hybridtrack.core.hookspecs import hookimpl

#: the default initial state, by component name (converted to the first mode's layout)
DEFAULT_X0 = {"x": 0.0, "vx": 0.0, "y": 0.0, "vy": 2.0}
DEFAULT_PROCESS_NOISE = 1e-3


_finite = number_option(lambda v: True, "a finite number")
_positive = number_option(lambda v: v > 0, "a positive finite number")
_non_negative = number_option(lambda v: v >= 0, "a finite number ≥ 0")
_seed = integer_option(0, "a non-negative integer")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--schedule", metavar="FILE.toml", help="schedule table (default: Table 1 of seed 001)")
    parser.add_argument("--x0", type=_finite, nargs="+", help="initial state in the first mode's layout (default: vy = 2, the rest 0)")
    parser.add_argument("--tau", type=_positive, default=0.1, help="sampling period in seconds (default 0.1)")
    parser.add_argument(
        "--process-noise", type=_non_negative, metavar="Q", help=f"Q = q·I for modes taking noise_cov (default {DEFAULT_PROCESS_NOISE:g})"
    )
    parser.add_argument("--measurement-noise", type=_positive, default=0.01, metavar="R", help="R = r·I (default 0.01)")
    parser.add_argument("--no-noise", action="store_true", help="noise-free trajectory")
    parser.add_argument("--seed", type=_seed, default=0, help="random seed, an integer ≥ 0 (default 0)")
    parser.add_argument("--npz", default="simulation.npz", help="output arrays (default simulation.npz)")
    parser.add_argument("--rrd", default="simulation.rrd", help="output recording (default simulation.rrd)")
    parser.add_argument("--no-record", action="store_true", help="write no recording")


def _load_schedule(path: str | None):
    from hybridtrack.engine.schedule import SEED001_TABLE1, Schedule

    if path is None:
        return SEED001_TABLE1
    try:
        return Schedule.from_toml(path)
    except FileNotFoundError:
        raise UsageError(f"--schedule {path}: no such file") from None
    except IsADirectoryError:
        raise UsageError(f"--schedule {path}: is a directory, expected a TOML file") from None
    except OSError as error:
        raise UsageError(f"--schedule {path}: cannot read ({error.strerror or error})") from None
    except UnicodeDecodeError as error:
        raise UsageError(f"--schedule {path}: not UTF-8 text ({error.reason} at byte {error.start})") from None
    except ValueError as error:  # TOMLDecodeError, a bad row, no [[segment]] tables
        message = str(error)
        raise UsageError(message if message.startswith(str(path)) else f"--schedule {path}: {message}") from None


def _output(option: str, path: str):
    """The checked target of ``option`` and a fresh temporary file in its folder (renamed onto it on success)."""
    target = Path(path)
    if not path or target.is_dir():
        raise UsageError(f"{option} {path!r}: expected a file name, got a directory")
    folder = target.parent
    if not folder.is_dir():
        raise UsageError(f"{option} {path}: folder {str(folder)!r} does not exist")
    try:
        handle, temporary = tempfile.mkstemp(dir=folder, prefix=f".{target.name}.", suffix=".partial")
    except OSError as error:
        raise UsageError(f"{option} {path}: cannot write in folder {str(folder)!r} ({error.strerror or error})") from None
    os.close(handle)
    return target, Path(temporary)


def _models(args, schedule, registry):
    import numpy as np

    from hybridtrack.engine.simulate import build_models, takes_keyword

    for i, segment in enumerate(schedule.segments):
        try:
            factory = registry.get("motion_model", segment.mode)
        except KeyError as error:
            raise UsageError(f"--schedule {args.schedule or '(built-in)'}: row {i}: {error}") from None
        if args.process_noise is not None and not takes_keyword(factory, "noise_cov"):
            raise UsageError(
                f"--process-noise {args.process_noise:g}: motion model {segment.mode!r} (schedule row {i}) takes no noise_cov;"
                " it sets its own process noise"
            )
    q = DEFAULT_PROCESS_NOISE if args.process_noise is None else args.process_noise
    try:
        return build_models(schedule, registry, q * np.eye(2), noise_cov_where_taken=True)
    except ValueError as error:
        raise UsageError(f"--schedule {args.schedule or '(built-in)'}: {error}") from None


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from hybridtrack.core.interfaces import convert_layout
    from hybridtrack.core.plugins import get_registry, resolve
    from hybridtrack.engine.simulate import simulate
    from hybridtrack.recording import check_recordable_times, log_measurements, open_recorder

    schedule = _load_schedule(args.schedule)
    registry = get_registry()
    models = _models(args, schedule, registry)
    layout = models[0].layout
    if args.x0 is None:
        x0 = convert_layout(np.array(list(DEFAULT_X0.values())), tuple(DEFAULT_X0), layout)
    elif len(args.x0) != len(layout):
        raise UsageError(
            f"--x0: expected {len(layout)} numbers (the layout {', '.join(layout)} of the first mode"
            f" {schedule.segments[0].mode!r}), got {len(args.x0)}"
        )
    else:
        x0 = np.array(args.x0)
    if not args.no_record:
        try:
            check_recordable_times(schedule.total_steps * args.tau, f"--tau {args.tau:g} over {schedule.total_steps} steps (the last time)")
        except ValueError as error:
            raise UsageError(str(error)) from None
        if os.path.abspath(args.rrd) == os.path.abspath(args.npz):
            raise UsageError(f"--npz and --rrd: both name {args.npz!r}; give two different files")
    sensor = resolve("sensor", ("position", {"name": "sensor", "noise_cov": args.measurement_noise * np.eye(2)}), registry)

    configuration = {key: value for key, value in vars(args).items() if key not in ("run", "npz", "rrd", "no_record")}
    configuration["x0"] = [float(v) for v in x0]
    outputs = []
    try:
        outputs.append(_output("--npz", args.npz))
        if not args.no_record:
            outputs.append(_output("--rrd", args.rrd))
        with open_recorder(None if args.no_record else outputs[1][1], {"command": "simulate", **configuration}) as recorder:
            try:
                with np.errstate(over="ignore", invalid="ignore"):  # an overflow is reported below, once
                    truth, z = simulate(
                        schedule,
                        x0,
                        args.tau,
                        [sensor],
                        seed=args.seed,
                        recorder=recorder,
                        process_noise=not args.no_noise,
                        models=models,
                    )
                log_measurements(recorder, [sensor], z, truth.steps, truth.times)
            except (ValueError, FloatingPointError) as error:  # e.g. a state that overflows from a huge --x0
                raise UsageError(f"the simulation from --x0 {' '.join(f'{v:g}' for v in x0)} failed: {error}") from None
        with open(outputs[0][1], "wb") as handle:  # a file object: numpy appends nothing to the name
            truth.save_npz(handle, **{f"z_{name}": values for name, values in z.items()})
        for target, temporary in outputs:
            os.replace(temporary, target)
    finally:
        for _, temporary in outputs:
            temporary.unlink(missing_ok=True)
    segments = ", ".join(f"{s.mode}×{s.steps}" for s in schedule.segments)
    print(f"simulated {truth.states.shape[0] - 1} steps ({segments}) → {args.npz}" + ("" if args.no_record else f", {args.rrd}"))
    return 0


@hookimpl
def register_commands(commands):
    commands.add("simulate", "simulate a schedule's trajectory and measurements to .npz and .rrd", configure, run)
