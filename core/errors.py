"""Errors agrisim reports to its user.

`UserError` and its subclasses mean *bad input*: the CLI prints their message as one line and
exits with status 2 before anything is written. Anything else escaping a run is an internal
failure (exit 1).
"""

from __future__ import annotations


class UserError(Exception):
    """Bad input: an unknown name, an impossible value, an unreadable file."""


class ConfigError(UserError):
    """The configuration (TOML file or flags) does not validate."""


class PluginError(UserError):
    """A backend name is unknown, or a plugin's registration is malformed."""


class OutputError(UserError):
    """The output directory exists, cannot be created, or is not writable."""


class BackendFailure(RuntimeError):
    """A backend (built-in or a third-party plugin) raised unexpectedly during a run. The message
    names it (kind, name, distribution); the run is marked ``failed``, its finished frames stay,
    and the CLI exits 1."""


class PlanningFailed(RuntimeError):
    """The planner found no path; the message is the reason recorded for the setpoint (served by
    :mod:`agrisim.interfaces` too, beside the planner's contract)."""
