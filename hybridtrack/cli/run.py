"""``hybridtrack run EXPERIMENT``: a seeded, resumable Monte Carlo campaign (:mod:`hybridtrack.apps.experiment`).

EXPERIMENT is a registered name (``demo_rmse``), a script ``path/to/foo.py``
defining ``EXPERIMENT``, or NAME for ``experiments/NAME.py`` in the working
directory.  Prints the mean (and standard deviation) of every result over the
runs, or with ``--json`` the same as JSON.  The options, the exit statuses
(0, 1 a run failed, 2 a user error, 130 Ctrl-C), the recordings and the
storage: docs/experiments.md.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from hybridtrack.cli import check_output_folder, integer_option, number_option
from hybridtrack.core.hookspecs import hookimpl

_positive = integer_option(1, "a positive integer")
_non_negative = integer_option(0, "a non-negative integer")
_seconds = number_option(lambda v: v > 0, "a positive number of seconds")


_run_index = integer_option(0, "non-negative run indices separated by commas (3,17,40)")


def _run_list(text: str) -> list[int]:
    """``"3,17,40"`` → [3, 17, 40]."""
    return [_run_index(part) for part in text.split(",")]


def _parameter(text: str) -> tuple[str, Any]:
    """``"key=value"`` → (key, value), the value parsed as JSON when it parses (numbers, lists, true/false), else text."""
    key, separator, value = text.partition("=")
    if not separator or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def configure(parser: argparse.ArgumentParser) -> None:
    from hybridtrack.apps.experiment.executors import EXECUTORS

    parser.add_argument("experiment", metavar="EXPERIMENT", help="registered name, experiments/NAME.py, or a script path")
    parser.add_argument("--n", type=_positive, default=100, help="number of runs (default 100)")
    parser.add_argument("--executor", choices=EXECUTORS, default="process", help="where runs execute (default process)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address for --executor dask (tcp://HOST:PORT)")
    parser.add_argument("--workers", type=_positive, help="processes for --executor process (default: CPU count)")
    parser.add_argument("--chunk", type=_positive, help="runs per stored chunk (default: about 4 chunks per worker, ≤ 25)")
    parser.add_argument("--out", metavar="DIR", help="result folder (default runs/EXPERIMENT)")
    parser.add_argument("--seed", type=_non_negative, default=0, help="campaign seed; run i uses child i of SeedSequence(seed)")
    parser.add_argument(
        "--param", type=_parameter, action="append", metavar="KEY=VALUE", help="override an experiment parameter (repeatable)"
    )
    parser.add_argument(
        "--set-aside",
        action="store_true",
        help="move damaged or foreign files of --out into DIR/set_aside/ and recompute their runs instead of stopping",
    )
    parser.add_argument(
        "--connect-timeout",
        type=_seconds,
        default=10.0,
        metavar="SECONDS",
        help="how long --executor dask waits for the scheduler (default 10)",
    )
    record = parser.add_mutually_exclusive_group()
    record.add_argument(
        "--record", type=_positive, metavar="K", help="record K runs spread evenly over the run indices (first and last included)"
    )
    record.add_argument("--record-runs", type=_run_list, metavar="I,J,…", help="record the runs with these indices")
    parser.add_argument("--record-dir", metavar="DIR", help="where the run recordings go (default OUT/recordings)")
    parser.add_argument(
        "--summary-recording", action="store_true", help="write OUT/summary.rrd: every result as a series over the run index"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def run(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    import numpy as np

    from hybridtrack.apps.experiment.campaign import Campaign, CampaignInterrupted, RunFailed
    from hybridtrack.apps.experiment.definition import UnknownExperiment
    from hybridtrack.apps.experiment.recordings import (
        accepts_recorder,
        check_run_indices,
        choose_runs,
        record_runs,
        write_summary_recording,
    )
    from hybridtrack.apps.experiment.store import CampaignLocked

    out = Path(args.out) if args.out else Path("runs") / Path(args.experiment).stem
    check_output_folder("--out", out)
    try:
        if args.executor == "dask" and not args.scheduler:
            raise ValueError("--executor dask needs --scheduler ADDRESS")
        campaign = Campaign(
            args.experiment,
            args.n,
            out,
            seed=args.seed,
            parameters=dict(args.param or []),
            executor=args.executor,
            scheduler=args.scheduler,
            workers=args.workers,
            chunk_size=args.chunk,
            progress=not args.no_progress,
            set_aside=args.set_aside,
            connect_timeout=args.connect_timeout,
        )
        chosen = choose_runs(args.n, args.record) if args.record else check_run_indices(args.record_runs or [], args.n)
        if chosen and not accepts_recorder(campaign.experiment):
            raise TypeError(
                f"--record: experiment {campaign.experiment.name!r} cannot record its runs "
                "(its run_one takes no 'recorder' keyword argument)"
            )
        result = campaign.run()
        recorded = {}
        if chosen:
            folder = Path(args.record_dir) if args.record_dir else result.out / "recordings"
            recorded = record_runs(campaign.experiment, chosen, folder, seed=campaign.seed, parameters=campaign.parameters)
            for index, (path, replayed) in recorded.items():  # result.arrays hold runs 0 … n−1 in order
                if any(
                    not np.allclose(values, result.arrays[name][index], rtol=1e-9, atol=0, equal_nan=True)
                    for name, values in replayed.items()
                ):
                    print(
                        f"hybridtrack run: warning: the recording of run {index} ({path}) gives other results than the "
                        "stored run: the experiment draws randomness outside the generator it is given",
                        file=sys.stderr,
                    )
        summary_path = None
        if args.summary_recording:
            summary_path = result.out / "summary.rrd"
            configuration = {"experiment": result.experiment, "n": result.n, "seed": campaign.seed, "parameters": campaign.parameters}
            write_summary_recording(result.arrays, summary_path, configuration)
    except (CampaignInterrupted, RunFailed) as error:
        print(f"hybridtrack run: {error}", file=sys.stderr)
        return 130 if isinstance(error, CampaignInterrupted) else 1
    except (UnknownExperiment, CampaignLocked, ValueError, TypeError, OSError) as error:
        # CampaignMismatch and CorruptResults are ValueErrors; OSError: --out unusable, scheduler unreachable
        print("hybridtrack run: " + " ".join(str(error).split("\n")), file=sys.stderr)
        return 2
    for original, moved, reason in result.set_aside:
        print(f"hybridtrack run: set aside {original} as {moved} ({reason})", file=sys.stderr)
    summary = {
        "experiment": result.experiment,
        "n": result.n,
        "out": str(result.out),
        "computed": result.computed,
        "reused": result.reused,
        "seed": campaign.seed,
        "parameters": campaign.parameters,
        "results": result.summary(),
        "recordings": {str(index): str(path) for index, (path, _) in recorded.items()},
        "summary_recording": None if summary_path is None else str(summary_path),
    }
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(f"{result.experiment}: {result.n} runs in {result.out} ({result.computed} computed, {result.reused} already stored)")
    for name, stats in summary["results"].items():
        if "shape" in stats:
            mean = ", ".join(f"{v:.6g}" for v in np.ravel(stats["mean"]))
            print(f"  {name:<20} mean per run over {stats['shape']}: [{mean}]")
        else:
            print(f"  {name:<20} mean {stats['mean']:.6g}  (sd {stats['std']:.3g})")
    for index, (path, _) in recorded.items():
        print(f"  run {index} recorded in {path} (open it: rerun {path})")
    if summary_path is not None:
        print(f"  summary recording (every result over the run index): {summary_path}")
    return 0


@hookimpl
def register_commands(commands):
    commands.add("run", "run a seeded, resumable Monte Carlo campaign of an experiment", configure, run)
