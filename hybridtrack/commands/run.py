"""``hybridtrack run EXPERIMENT``: a seeded, resumable Monte Carlo campaign.

EXPERIMENT is a registered name (``demo_rmse``), a script ``path/to/foo.py``
defining ``EXPERIMENT``, or NAME for ``experiments/NAME.py`` in the working
directory.  Results go to ``--out`` (default ``runs/EXPERIMENT``) chunk by
chunk; running the same command again after an interruption computes only the
missing runs.  Prints the mean (and standard deviation) of every result over
the runs, or with ``--json`` the same as JSON.
"""

from __future__ import annotations

import argparse

from hybridtrack.cli import Command


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _non_negative(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    from hybridtrack.experiment.executors import EXECUTORS

    parser.add_argument("experiment", metavar="EXPERIMENT", help="registered name, experiments/NAME.py, or a script path")
    parser.add_argument("--n", type=_positive, default=100, help="number of runs (default 100)")
    parser.add_argument("--executor", choices=EXECUTORS, default="process", help="where runs execute (default process)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address for --executor dask (tcp://HOST:PORT)")
    parser.add_argument("--workers", type=_positive, help="processes for --executor process (default: CPU count)")
    parser.add_argument("--chunk", type=_positive, help="runs per stored chunk (default: about 4 chunks per worker, ≤ 25)")
    parser.add_argument("--out", metavar="DIR", help="result folder (default runs/EXPERIMENT)")
    parser.add_argument("--seed", type=_non_negative, default=0, help="campaign seed; run i uses child i of SeedSequence(seed)")
    parser.add_argument("--param", action="append", metavar="KEY=VALUE", help="override an experiment parameter (repeatable)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def run(args: argparse.Namespace) -> int:
    import json
    import sys
    from pathlib import Path

    import numpy as np

    from hybridtrack.experiment.campaign import Campaign, RunFailed, campaign_parameters
    from hybridtrack.experiment.definition import UnknownExperiment
    from hybridtrack.experiment.store import CampaignMismatch, CorruptResults

    if args.executor == "dask" and not args.scheduler:
        print("hybridtrack run: --executor dask needs --scheduler ADDRESS", file=sys.stderr)
        return 2
    try:
        parameters = campaign_parameters(args.param)
        campaign = Campaign(
            args.experiment,
            args.n,
            args.out or Path("runs") / Path(args.experiment).stem,
            seed=args.seed,
            parameters=parameters,
            executor=args.executor,
            scheduler=args.scheduler,
            workers=args.workers,
            chunk_size=args.chunk,
            progress=not args.no_progress,
        )
        result = campaign.run()
    except (UnknownExperiment, CampaignMismatch, ValueError) as error:
        print(f"hybridtrack run: {error}", file=sys.stderr)
        return 2
    except (RunFailed, CorruptResults) as error:
        print(f"hybridtrack run: {error}", file=sys.stderr)
        return 1
    summary = {
        "experiment": result.experiment,
        "n": result.n,
        "out": str(result.out),
        "computed": result.computed,
        "reused": result.reused,
        "seed": campaign.seed,
        "parameters": campaign.parameters,
        "results": result.summary(),
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
    return 0


COMMAND = Command("run", "run a seeded, resumable Monte Carlo campaign of an experiment", configure, run)
