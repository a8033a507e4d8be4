"""The names of the geometric planners the installed OMPL bindings expose (imports OMPL)."""

from __future__ import annotations

from ompl import base as ob
from ompl import geometric as og


def available_planners() -> list[str]:
    """Names of the OMPL geometric planners these bindings expose."""
    return sorted(
        name
        for name in dir(og)
        if isinstance(getattr(og, name), type)
        and issubclass(getattr(og, name), ob.Planner)
        and name not in ("Planner",)
    )
