"""``hybridtrack inspect FILE.rrd [--json]``: what a recording holds, offline, without a viewer.

Prints the application and recording id, the run configuration, the entity
paths, the step range, the decision events and the final estimates
(:class:`hybridtrack.inspection.RecordingFile`).
"""

from __future__ import annotations

import argparse
import json
import sys

from hybridtrack.cli import Command


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE.rrd")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def run(args: argparse.Namespace) -> int:
    from hybridtrack.inspection import RecordingFile, format_summary

    try:
        summary = RecordingFile(args.file).summary()
    except (FileNotFoundError, ValueError) as error:
        print(f"hybridtrack inspect: {error}", file=sys.stderr)
        return 1
    print(json.dumps(summary, indent=2) if args.json else format_summary(summary))
    return 0


COMMAND = Command("inspect", "summarize a recording (.rrd) offline", configure, run)
