"""Sub-commands of the ``hybridtrack`` command line, added by plugins through ``register_commands(commands)``
(an example: ``docs/plugins.md`` §5).

``configure(parser)`` adds the command's arguments to its argparse sub-parser; ``run(args)`` does the work and
returns the exit status (None is 0).  Heavy imports belong inside ``run``, so that ``hybridtrack --version`` stays
fast.  A user error is raised as :class:`UsageError`: one line on stderr, status 2.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import attrs


class UsageError(Exception):
    """A user error a command reports: printed as ``hybridtrack <command>: error: <message>``, exit status 2.

    The message names the option or file, the value and what is expected.
    """


@attrs.frozen
class Command:
    """A sub-command: ``configure(parser)`` adds its arguments, ``run(args)`` returns the exit status."""

    name: str
    help: str
    configure: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int | None]
    plugin: str | None = None


def _raise(error: Exception) -> None:
    raise error


@attrs.define
class Commands:
    """What ``register_commands`` receives: ``commands.add(name, help, configure, run)``.

    ``found`` (name → :class:`Command`) is shared by the plugins in load order:
    a name already taken is rejected (``on_error``; default: raised) and the
    first command keeps it.
    """

    found: dict[str, Command] = attrs.field(factory=dict)
    plugin: str | None = None
    on_error: Callable[[Exception], None] = _raise

    def add(self, name: str, help: str, configure: Callable, run: Callable) -> None:
        if not isinstance(name, str) or not name or name.startswith("-") or name != name.strip():
            self.on_error(ValueError(f"plugin {self.plugin!r}: a command name must be a non-empty word, got {name!r}"))
        elif name in self.found:
            self.on_error(ValueError(f"command {name!r} of plugin {self.plugin!r} is already added by plugin {self.found[name].plugin!r}"))
        elif not (callable(configure) and callable(run)):
            self.on_error(ValueError(f"plugin {self.plugin!r}: command {name!r} needs callable configure and run"))
        else:
            self.found[name] = Command(name, help, configure, run, self.plugin)
