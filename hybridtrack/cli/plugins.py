"""``hybridtrack plugins``: the installed plugins and the components each provides.

The table shows plugin, distribution, version, kind, name and the first line
of the component's docstring; ``--json`` prints one object per component with
exactly the keys of :data:`JSON_KEYS`.  Loading problems (a plugin that failed
to import, a rejected component) go to stderr, one line each; the exit status
is 0 even then, since the listing itself worked.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings

from hybridtrack.core.hookspecs import hookimpl

JSON_KEYS = ("plugin", "distribution", "version", "kind", "name")


def rows(loaded) -> list[dict]:
    """One dict per component (the JSON keys plus ``summary``), plugins in load order, then kind and name."""
    order = {info.name: i for i, info in enumerate(loaded.plugins)}
    entries = sorted(loaded.registry.entries(), key=lambda e: (order.get(e.plugin, len(order)), e.kind, e.name))
    return [{key: getattr(e, key) for key in (*JSON_KEYS, "summary")} for e in entries]


def table(loaded) -> str:
    """The listing as aligned text; a plugin with no component still gets a line."""
    components = rows(loaded)
    lines = []
    for info in loaded.plugins:
        mine = [row for row in components if row["plugin"] == info.name]
        head = [info.name, info.distribution or "-", info.version or "-"]
        if not mine:
            lines.append(head + ["-", "-", "(no components)"])
        for row in mine:
            lines.append(head + [row["kind"], row["name"], row["summary"]])
    header = [*JSON_KEYS, "summary"]
    widths = [max(len(str(line[i])) for line in [header] + lines) for i in range(len(header) - 1)]

    def render(line):
        return "  ".join(str(cell).ljust(width) for cell, width in zip(line, widths)) + "  " + line[-1]

    return "\n".join([render(header), render(["-" * w for w in widths] + ["-------"])] + [render(line).rstrip() for line in lines])


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print a JSON list, one object per component")


def run(args: argparse.Namespace) -> int:
    from hybridtrack.cli import builtin_plugins
    from hybridtrack.core.plugins import load_plugins

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the problems are printed below, once each
        loaded = load_plugins(builtins=builtin_plugins())  # with the commands, whose clashes are problems too
    for problem in loaded.problems:
        print(f"warning: {problem}", file=sys.stderr)
    if args.json:
        print(json.dumps([{key: row[key] for key in JSON_KEYS} for row in rows(loaded)], indent=2))
    else:
        print(table(loaded))
    return 0


@hookimpl
def register_commands(commands):
    commands.add("plugins", "list the installed plugins and the components they provide", configure, run)
