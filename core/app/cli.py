"""The ``agrisim`` console script: the installed commands (agrisim's own and the plugins',
:func:`agrisim.app.arguments.installed_commands`) parsed and run.

Bad input exits with status 2 and one line naming the problem; nothing is written. Internal
failures exit 1 (``AGRISIM_DEBUG=1`` shows the traceback) with the run's partial results kept.
"""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Sequence

from agrisim.app.arguments import PROG, build_parser, fail, installed_commands
from agrisim.errors import BackendFailure, UserError


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``agrisim`` console script."""
    try:
        commands = installed_commands()
    except UserError as exc:  # a plugin that fails to load, two adding one command
        fail(str(exc))
    args = build_parser(commands.values()).parse_args(argv)
    try:
        return commands[args.command].run(args)
    except UserError as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted\n")
        return 130
    except BrokenPipeError:  # output piped into `head` and the like
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except BackendFailure as exc:  # a plugin's failure: named, the run's finished work kept
        fail(str(exc), status=1)
    except Exception as exc:  # an internal failure, not the user's input
        if os.environ.get("AGRISIM_DEBUG"):
            traceback.print_exc()
        fail(f"internal error: {type(exc).__name__}: {exc} (set AGRISIM_DEBUG=1 for the traceback)", status=1)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
