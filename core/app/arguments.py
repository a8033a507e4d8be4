"""The ``agrisim`` command line's grammar: the top-level parser and a subparser for each
installed command (:class:`agrisim.commands.Command`, from the ``agrisim_commands`` hook), and
the one-line failure every command exits with.

Bad flags exit with status 2 and one line (no usage dump).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from typing import Any, NoReturn

from agrisim.commands import Command
from agrisim.errors import UserError

__all__ = ["PROG", "Parser", "build_parser", "fail", "installed_commands"]

PROG = "agrisim"


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump), exit status 2."""

    def error(self, message: str) -> NoReturn:
        fail(message)


def fail(message: str, status: int = 2) -> NoReturn:
    """Exit with ``status`` after one line on stderr: ``agrisim: error: <message>``."""
    sys.stderr.write(f"{PROG}: error: {message}\n")
    raise SystemExit(status)


def installed_commands() -> dict[str, Command]:
    """Every command by name: agrisim's own (its distribution's entry points, loaded whatever
    ``AGRISIM_LOAD_PLUGINS`` says, as pytest's built-ins are) in the order they give, then the
    other installed plugins' by name. A name added twice is an error naming both plugins."""
    from agrisim.registry import make_plugin_manager, with_own_plugins

    pm = make_plugin_manager()
    own = with_own_plugins(pm)
    impls: list[Any] = pm.hook.agrisim_commands.get_hookimpls()
    added = [(c, "agrisim") for p in own for i in impls if i.plugin is p for c in i.function()]
    others = [(c, i.plugin_name) for i in impls if not any(i.plugin is p for p in own) for c in i.function()]
    added += sorted(others, key=lambda x: x[0].name)
    found: dict[str, tuple[Command, str]] = {}
    for command, plugin in added:
        if command.name in found:
            raise UserError(f"the command {command.name!r} is added by both {found[command.name][1]} and {plugin}")
        found[command.name] = (command, plugin)
    return {name: command for name, (command, _) in found.items()}


def build_parser(commands: Iterable[Command] | None = None) -> argparse.ArgumentParser:
    """The parser of every subcommand (default: the installed commands)."""
    from agrisim.version import __version__

    p = Parser(prog=PROG, description="Robot arms photographing plants: simulate, annotate, reconstruct.")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for command in installed_commands().values() if commands is None else commands:
        command.add_arguments(sub.add_parser(command.name, help=command.help, description=command.description))
    return p
