"""``hybridtrack inspect FILE.rrd [--json]``: what a recording holds, offline, without a viewer.

Prints the application and recording id, the run configuration, the entity
paths, the step range, the decision events and the final estimates
(:class:`hybridtrack.recording.inspection.RecordingFile`, which reads the file as a stream).

Exit status: 0 for a complete file; 2 when the file is missing or not a
readable recording; 3 when it is truncated (no end-of-stream footer, e.g. the
recording process was killed): what was readable is printed as usual (``--json``:
``"truncated": true`` and ``"problem"``), plus one warning line on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys

from hybridtrack.cli import UsageError
from hybridtrack.core.hookspecs import hookimpl

EXIT_TRUNCATED = 3


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE.rrd")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def run(args: argparse.Namespace) -> int:
    from hybridtrack.recording.inspection import RecordingFile, format_summary

    try:
        summary = RecordingFile(args.file).summary()
    except (OSError, ValueError) as error:  # missing, unreadable or not a recording: a user error (status 2)
        raise UsageError(f"{error.filename}: {error.strerror}" if isinstance(error, OSError) and error.filename else str(error)) from None
    print(json.dumps(summary, indent=2) if args.json else format_summary(summary))
    if summary["truncated"]:
        print(f"hybridtrack inspect: {args.file}: truncated recording: {summary['problem']}", file=sys.stderr)
        return EXIT_TRUNCATED
    return 0


@hookimpl
def register_commands(commands):
    commands.add("inspect", "summarize a recording (.rrd) offline", configure, run)
