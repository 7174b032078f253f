"""The ``hybridtrack`` command line: ``hybridtrack <command> [options]``.

Each sub-command is a :class:`Command` (name, one-line help, a function adding
its arguments to a sub-parser, a function running it) living in its own module
under :mod:`hybridtrack.commands`.  Adding one is: write the module with a
``COMMAND = Command(...)`` and list the module in :data:`COMMAND_MODULES`.
Modules are imported only when the parser is built, and a command's heavy
imports belong inside its ``run`` function, so ``hybridtrack --version`` stays
fast.

``main(argv)`` returns the exit status instead of exiting, so tests call it in
process; the console script ``hybridtrack`` is ``sys.exit(main())``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence

import attrs

#: modules defining a ``COMMAND``, in the order ``--help`` lists them
COMMAND_MODULES: tuple[str, ...] = (
    "hybridtrack.commands.plugins",
    "hybridtrack.commands.simulate",
    "hybridtrack.commands.inspect",
    "hybridtrack.commands.run",
)


@attrs.frozen
class Command:
    """A sub-command: ``configure(parser)`` adds its arguments, ``run(args)`` returns the exit status."""

    name: str
    help: str
    configure: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


def commands() -> dict[str, Command]:
    """Name → :class:`Command` for every module in :data:`COMMAND_MODULES`."""
    found: dict[str, Command] = {}
    for module_name in COMMAND_MODULES:
        command = importlib.import_module(module_name).COMMAND
        if command.name in found:
            raise RuntimeError(f"command {command.name!r} defined twice ({module_name})")
        found[command.name] = command
    return found


def build_parser(available: dict[str, Command] | None = None) -> argparse.ArgumentParser:
    from hybridtrack import __version__

    parser = argparse.ArgumentParser(
        prog="hybridtrack",
        description="Estimation of hybrid (mode-switching) motion: plugins, simulations, detectors.",
    )
    parser.add_argument("--version", action="version", version=f"hybridtrack {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    for command in (commands() if available is None else available).values():
        sub_parser = sub.add_parser(command.name, help=command.help, description=command.help)
        command.configure(sub_parser)
        sub_parser.set_defaults(run=command.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line on ``argv`` (default ``sys.argv[1:]``) and return the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # --help, --version and usage errors
        return int(exit_.code or 0)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    return int(args.run(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
