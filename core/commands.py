"""The subcommands of ``agrisim``: what a plugin's ``agrisim_commands`` hook returns
(:mod:`agrisim.hookspecs`). agrisim's own commands are registered through the same hook
(:mod:`agrisim.plugins.apps.commands`), as pytest and Datasette register their built-ins."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Command:
    """One subcommand: ``agrisim NAME ...``.

    ``add_arguments(parser)`` declares its flags on the subcommand's own parser;
    ``run(args)`` does its work with the parsed flags and returns the exit status. Bad input
    raises :class:`agrisim.errors.UserError` (one line, exit status 2, as every command's)."""

    name: str
    help: str
    """One line in ``agrisim --help``."""
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]
    description: str | None = None
    """The paragraph atop ``agrisim NAME --help`` (default: none)."""
