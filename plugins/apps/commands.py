"""agrisim's own commands, registered through the ``agrisim_commands`` hook as a third party's
are: this module is the ``apps`` entry point of agrisim's distribution (which
:func:`agrisim.app.arguments.installed_commands` loads whatever ``AGRISIM_LOAD_PLUGINS`` says)."""

from __future__ import annotations

from agrisim.commands import Command
from agrisim.plugins.apps import catalogue_commands, run_commands, study_commands
from agrisim.registry import hookimpl

#: the order of ``agrisim --help``
ORDER = (
    "run", "ros", "plants", "traits", "nextview", "plugins", "doctor",
    "recon", "render", "export", "colmap", "view", "compare", "sweep",
)  # fmt: skip


@hookimpl
def agrisim_commands() -> list[Command]:
    by_name = {c.name: c for m in (run_commands, catalogue_commands, study_commands) for c in m.COMMANDS}
    return [by_name[name] for name in ORDER]
