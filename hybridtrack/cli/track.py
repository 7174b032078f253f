"""``hybridtrack track FILE --config CONFIG.toml --out DIR [--id ID …] [--smooth | --lag SECONDS]``: track every object of a position file.

Runs the estimator configured in CONFIG (checked by :mod:`hybridtrack.apps.tracking`) on each object of FILE
(or the objects named by ``--id``, repeatable) and writes ``DIR/<id>.rrd``, ``DIR/<id>.npz`` and
``DIR/summary.json`` (the configuration schema and the outputs: ``docs/real_data.md``).  A progress bar over
the objects goes to stderr (``--no-progress`` to hide it).  ``--smooth`` (fixed interval) and ``--lag SECONDS``
(fixed lag) give the smoothed run of a multiple-model algorithm instead of the causal one.

Exit status: 0 done; 2 a user error, one line on stderr (missing file or
configuration, unknown key, bad value, unknown estimator kind or mode, an
``--id`` not in the file, an unreadable position file).
"""

from __future__ import annotations

import argparse

from hybridtrack.cli import UsageError
from hybridtrack.core.hookspecs import hookimpl


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", help="position file (CSV or .csv.gz; see docs/real_data.md)")
    parser.add_argument("--config", required=True, metavar="CONFIG.toml", help="tracker configuration (TOML)")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder (created if needed)")
    parser.add_argument("--id", action="append", dest="ids", metavar="ID", help="track only this object (repeatable)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    smoothing = parser.add_mutually_exclusive_group()
    smoothing.add_argument(
        "--smooth", action="store_true", help="fixed-interval smoothing of the recorded file (multiple-model algorithms)"
    )
    smoothing.add_argument(
        "--lag", type=float, metavar="SECONDS", help="fixed-lag smoothing: each report also uses the next SECONDS of reports"
    )


def run(args: argparse.Namespace) -> int:
    import sys

    from hybridtrack.apps.tracking import track_file

    try:
        progress = not args.no_progress and sys.stderr.isatty()
        summary = track_file(args.file, args.config, args.out, args.ids, progress=progress, smooth=args.smooth, lag=args.lag)
    except ValueError as error:  # a ConfigError names the key, the reader's structural faults name the file
        raise UsageError(str(error)) from None
    n, s = len(summary["objects"]), len(summary["skipped"])
    print(f"tracked {n} object(s), skipped {s}; results in {args.out}")
    return 0


@hookimpl
def register_commands(commands):
    commands.add("track", "track every object of a position file with a configured estimator", configure, run)
