"""``hybridtrack track FILE --config CONFIG.toml --out DIR [--id ID …] [--smooth | --lag SECONDS] [--geojson]``: track every object of a position file.

Runs the estimator configured in CONFIG (checked by :mod:`hybridtrack.apps.tracking`) on each object of FILE
(or the objects named by ``--id``, repeatable) and writes ``DIR/<id>.rrd``, ``DIR/<id>.npz`` and
``DIR/summary.json`` (the configuration: ``docs/config.md``; the outputs: ``docs/real_data.md``).  A progress bar over
the objects goes to stderr (``--no-progress`` to hide it).  ``--smooth`` (fixed interval) and ``--lag SECONDS``
(fixed lag) give the smoothed run of a multiple-model algorithm instead of the causal one.  ``--geojson`` also
writes ``DIR/tracks.geojson`` (latitude/longitude files only: :func:`hybridtrack.apps.geojson.tracks_geojson`).

On stderr: the speed limit of the reader's jump check and where it comes from, the rows the reader dropped or
repaired (one line per kind, with its count and the first file line; all of them in ``summary.json``
``"problems"``), and every object that failed.  ``--strict``: any such row problem stops before tracking.

Exit status: 0 done; 1 done, but at least one object failed (listed in ``summary.json`` ``"skipped"`` with
``"failed": true``; the other objects and ``summary.json`` are written); 2 a user error, one line on stderr
(missing file or configuration, unknown key, bad value, unknown estimator kind or mode, an ``--id`` not in the
file, an unreadable position file, ``--geojson`` for a file in x/y metres, a file of which no report is left or
no object tracked — every one skipped, listed in ``summary.json`` — a row problem under ``--strict``).
"""

from __future__ import annotations

import argparse

from hybridtrack.cli import UsageError, check_output_folder
from hybridtrack.core.hookspecs import hookimpl


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file",
        metavar="FILE",
        help="position file: CSV (.csv, .csv.gz), GPX (.gpx) or raw AIS NMEA (.nmea, .ais); [reader] format for other names (docs/own_files.md)",
    )
    parser.add_argument("--config", required=True, metavar="CONFIG.toml", help="tracker configuration (TOML)")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder (created if needed)")
    parser.add_argument("--id", action="append", dest="ids", metavar="ID", help="track only this object (repeatable)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--strict", action="store_true", help="stop (exit 2) on any row the reader drops or repairs")
    parser.add_argument(
        "--geojson",
        action="store_true",
        help="also write DIR/tracks.geojson: the estimated tracks and their segments (latitude/longitude files)",
    )
    parser.add_argument(
        "--executor",
        choices=("inline", "process", "dask"),
        help="track the objects in shards on this executor (default: in this process, as one batch); dask needs --scheduler",
    )
    parser.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address for --executor dask (tcp://HOST:PORT)")
    parser.add_argument("--workers", type=int, metavar="N", help="processes for --executor process (default: CPU count)")
    parser.add_argument("--shard-objects", type=int, default=128, metavar="N", help="objects per shard with --executor (default 128)")
    smoothing = parser.add_mutually_exclusive_group()
    smoothing.add_argument(
        "--smooth", action="store_true", help="fixed-interval smoothing of the recorded file (multiple-model algorithms)"
    )
    smoothing.add_argument(
        "--lag", type=float, metavar="SECONDS", help="fixed-lag smoothing: each report also uses the next SECONDS of reports"
    )


def run(args: argparse.Namespace) -> int:
    import sys

    from hybridtrack.apps.tracking import load_config, problem_summary, track_file
    from hybridtrack.io.track_files import Problem

    check_output_folder("--out", args.out)
    try:
        progress = not args.no_progress and sys.stderr.isatty()
        options = dict(progress=progress, smooth=args.smooth, lag=args.lag, strict=args.strict, geojson=args.geojson)
        if args.executor is not None:
            if args.executor == "dask" and not args.scheduler:
                raise ValueError("--executor dask needs --scheduler ADDRESS (tcp://HOST:PORT)")
            options |= dict(executor=args.executor, scheduler=args.scheduler, workers=args.workers, shard_objects=args.shard_objects)
        config = load_config(args.config)
        if config["unlabelled"]:  # detections without identities: hybridtrack.apps.multitarget (imported only for them)
            from hybridtrack.apps.multitarget import track_detections

            given = [flag for flag, value in (("--id", args.ids), ("--executor", args.executor), ("--geojson", args.geojson)) if value]
            if given:
                raise ValueError(f"{given[0]} with [association] (unlabelled detections): not supported; leave it out")
            summary = track_detections(args.file, config, args.out, smooth=args.smooth, lag=args.lag)
        else:
            summary = track_file(args.file, args.config, args.out, args.ids, **options)
    except ValueError as error:  # a ConfigError names the key, the reader's structural faults name the file
        raise UsageError(str(error)) from None
    limit = summary["max_speed"]
    print(f"{args.file}: speed limit {limit['max_speed']:g} m/s ({limit['set_by']})", file=sys.stderr)
    if summary["problems"]:
        print(f'{args.file}: {len(summary["problems"])} row problem(s), in summary.json "problems":', file=sys.stderr)
        for text in problem_summary([Problem(**problem) for problem in summary["problems"]]):
            print(f"  {text}", file=sys.stderr)
    failed = [entry for entry in summary["skipped"] if entry.get("failed")]
    for entry in failed:
        print(entry["reason"], file=sys.stderr)
    if not summary["objects"] and not failed:  # no empty success
        reasons = "; ".join(f"{e['id']!r}: {e['reason']}" for e in summary["skipped"][:3]) + ("; …" if len(summary["skipped"]) > 3 else "")
        raise UsageError(f"{args.file}: no object tracked, every one skipped ({reasons}); see {args.out}/summary.json")
    n, s = len(summary["objects"]), len(summary["skipped"])
    print(f"tracked {n} object(s), skipped {s}" + (f" ({len(failed)} failed)" if failed else "") + f"; results in {args.out}")
    return 1 if failed else 0


@hookimpl
def register_commands(commands):
    commands.add("track", "track every object of a position file with a configured estimator", configure, run)
