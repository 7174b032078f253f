"""The ``hybridtrack`` command line: ``hybridtrack <command> [options]``.

Sub-commands come through the plugin hook ``register_commands`` (:mod:`hybridtrack.core.commands`).  The
built-in ones are one module each, listed in :data:`COMMAND_MODULES` and loaded before the entry-point plugins
(so their names stay theirs, and disabling plugins never removes them).  ``hybridtrack --version`` is answered
before any plugin is loaded, so it stays fast.

``main(argv)`` returns the exit status instead of exiting, so tests call it in
process; the console script ``hybridtrack`` is ``sys.exit(main())``.  Run so, on the process's own command line
(``argv`` None), it freezes the garbage collector's objects (``gc.freeze``) once the plugins are loaded and again
before it returns: the modules live until the process exits, so the collector's full passes need not scan them
again (a tracked file's run gains ~0.2 s), nor do the interpreter's final ones (~0.5 s at exit after
``hybridtrack track`` with numba, rerun and pandas loaded).  A call with ``argv`` (a test, a notebook) leaves the
collector alone.

Errors: a user error (bad option value, missing or unreadable file, bad
schedule) is one line ``hybridtrack <command>: error: <message>`` on stderr
naming the option or file, with exit status 2 and no traceback.  Commands
raise :class:`UsageError` for these; argparse's own errors are printed the
same way; an OSError about a file (not found, permission, a directory) that
reaches :func:`main` is too.  Any other exception is a bug and keeps its
traceback.  A closed output pipe (``hybridtrack plugins | head``) ends the
command quietly with status 141 (128 + SIGPIPE, as a shell reports for
``yes | head``).  Output that the console's encoding cannot represent is
replaced by ``?`` instead of raising UnicodeEncodeError.
"""

from __future__ import annotations

import argparse
import codecs
import contextlib
import gc
import importlib
import math
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from hybridtrack.core.commands import Command, UsageError

__all__ = [
    "Command",
    "UsageError",
    "build_parser",
    "check_output_file",
    "check_output_folder",
    "commands",
    "integer_option",
    "main",
    "number_option",
]

#: the built-in command modules (each with a ``register_commands`` hook), in the order ``--help`` lists them
COMMAND_MODULES: tuple[str, ...] = (
    "hybridtrack.cli.plugins",
    "hybridtrack.cli.simulate",
    "hybridtrack.cli.inspect",
    "hybridtrack.cli.run",
    "hybridtrack.cli.track",
    "hybridtrack.cli.fit",
)


#: exit status of a user error (argparse's too) and of a closed output pipe
USAGE_ERROR_STATUS = 2
BROKEN_PIPE_STATUS = 141

#: OSErrors about a file the user named: one line and status 2 (other OSErrors: one line and status 1)
_USER_FILE_ERRORS = (FileNotFoundError, PermissionError, IsADirectoryError, NotADirectoryError, FileExistsError)


def _option(convert: Callable[[str], float], check: Callable[[float], bool], expected: str) -> Callable[[str], float]:
    def parse(text: str):
        with contextlib.suppress(ValueError):  # not a number
            if check(value := convert(text)):
                return value
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")

    return parse


def integer_option(minimum: int, expected: str) -> Callable[[str], int]:
    """An argparse ``type``: an integer ≥ ``minimum``, else an error saying ``expected``."""
    return _option(int, lambda value: value >= minimum, expected)


def number_option(check: Callable[[float], bool], expected: str) -> Callable[[str], float]:
    """An argparse ``type``: a finite float passing ``check``, else an error saying ``expected``."""
    return _option(float, lambda value: math.isfinite(value) and check(value), expected)


def check_output_folder(option: str, path: str | os.PathLike) -> None:
    """A UsageError unless ``path`` (the value of ``option``) can be a folder: an existing folder, or a new one
    whose nearest existing ancestor is a folder (``--out PATH: is a file; expected a folder``)."""
    path = Path(path)
    for ancestor in (path, *path.parents):
        if ancestor.exists():
            if not ancestor.is_dir():
                what = "is a file" if ancestor == path else f"{ancestor} is a file"
                raise UsageError(f"{option} {path}: {what}; expected a folder")
            return


def check_output_file(option: str, path: str | os.PathLike, what: str = "a file") -> None:
    """A UsageError unless ``path`` (the value of ``option``) can be written as a file: not a folder, in an
    existing folder (``what`` says which file is expected)."""
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"{option} {path}: is a folder; expected {what}")
    if not path.parent.is_dir():
        raise UsageError(f"{option} {path}: folder {str(path.parent)!r} does not exist; expected {what} in an existing folder")


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line (``prog: error: message``) with status 2."""

    def error(self, message: str):
        self.exit(USAGE_ERROR_STATUS, f"{self.prog}: error: {_one_line(message)} (see {self.prog} --help)\n")


def _one_line(message: object) -> str:
    return " ".join(str(message).split())


def _tolerate_console_encoding() -> None:
    """Replace characters stdout/stderr cannot encode (e.g. ψ on an ASCII or latin-1 console) instead of raising."""
    for stream in (sys.stdout, sys.stderr):
        try:
            utf = codecs.lookup(getattr(stream, "encoding", None) or "utf-8").name.startswith("utf")
        except LookupError:
            utf = False
        if not utf and getattr(stream, "errors", "strict") == "strict":
            with contextlib.suppress(AttributeError, ValueError, OSError):  # no reconfigure, or not any more
                stream.reconfigure(errors="replace")


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at devnull so the interpreter's final flush does not fail again
    (the recipe of the Python docs, "Note on SIGPIPE")."""
    with contextlib.suppress(OSError, ValueError, AttributeError):  # no real file descriptor (e.g. captured in a test)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def builtin_plugins() -> list:
    """The modules of :data:`COMMAND_MODULES`, the command line's own plugins."""
    return [importlib.import_module(name) for name in COMMAND_MODULES]


def commands() -> dict[str, Command]:
    """Name → :class:`Command`: the built-in ones, then those the installed plugins add through ``register_commands``.

    Loading problems are not shown here (``hybridtrack plugins`` lists them, and
    a command that builds components warns as the registry loads).
    """
    from hybridtrack.core.plugins import load_plugins

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_plugins(builtins=builtin_plugins()).commands


def _asks_version(argv: Sequence[str]) -> bool:
    """Whether ``--version`` (or a prefix argparse accepts, ``--vers``) comes before any command or ``--help``."""
    for arg in argv:
        if not arg.startswith("--") or "=" in arg or "--help".startswith(arg):
            return False
        if len(arg) > 2 and "--version".startswith(arg):
            return True
    return False


def build_parser(available: dict[str, Command] | None = None) -> argparse.ArgumentParser:
    from hybridtrack import __version__

    parser = _Parser(
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
    """Run the command line on ``argv`` (default ``sys.argv[1:]``) and return the exit status (errors: module docstring)."""
    _tolerate_console_encoding()
    as_program = argv is None  # the process's own command line: it exits when this returns (module docstring)
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser({} if _asks_version(argv) else None)  # --version: no plugin loaded
    if as_program:
        gc.freeze()  # the modules and plugins loaded so far: out of the collector's full passes
    try:
        return _run(parser, argv)
    finally:
        if as_program:
            gc.freeze()  # what the command loaded: out of the interpreter's final collections


def _run(parser: argparse.ArgumentParser, argv: list[str]) -> int:
    """:func:`main` once the parser is built: the command's exit status."""
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exit_:  # --help, --version and usage errors
            sys.stdout.flush()
            return int(exit_.code or 0)
        if args.command is None:
            parser.print_help(sys.stderr)
            return USAGE_ERROR_STATUS
        prog = f"{parser.prog} {args.command}"
        try:
            status = int(args.run(args) or 0)
        except UsageError as error:
            print(f"{prog}: error: {_one_line(error)}", file=sys.stderr)
            return USAGE_ERROR_STATUS
        except OSError as error:
            if isinstance(error, BrokenPipeError) or error.filename is None:
                raise
            print(f"{prog}: error: {error.filename}: {_one_line(error.strerror or error)}", file=sys.stderr)
            return USAGE_ERROR_STATUS if isinstance(error, _USER_FILE_ERRORS) else 1
        sys.stdout.flush()  # a closed pipe shows up here, not at the interpreter's exit
        return status
    except BrokenPipeError:
        _silence_stdout()
        return BROKEN_PIPE_STATUS


if __name__ == "__main__":
    sys.exit(main())
