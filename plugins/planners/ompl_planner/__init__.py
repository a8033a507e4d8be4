"""The ``ompl`` planner: any OMPL geometric planner by name (default RRTConnect).

As in the paper's ROS set-up: 2 s of planning time per attempt, 5 attempts, then OMPL's path
simplification. Collision checking is agrisim's validity callable (the physics backend's
query), at the motion resolution the episode asks for.
"""

from __future__ import annotations

from pydantic import Field, field_validator

from agrisim import BackendSpec, Options, hookimpl
from agrisim.kinds import lazy


class OmplOptions(Options):
    """Options of the OMPL planner."""

    algorithm: str = "RRTConnect"
    """An OMPL geometric planner by name (see ``agrisim plugins``)."""
    time: float = Field(2.0, gt=0.0, le=600.0)
    """Planning time per attempt, s (paper: 2)."""
    attempts: int = Field(5, ge=1, le=100)
    """Attempts before the setpoint is given up (paper: 5)."""
    simplify: bool = True
    """Shorten and smooth the found path with OMPL's path simplifier."""
    try_direct: bool = True
    """Return the straight line at once when it is collision-free (as most setpoints are)."""
    seed: int = Field(0, ge=0, le=2**31 - 1)
    """Seed of OMPL's global random generator (taken once per process, before any planning)."""
    search_resolution: float = Field(0.1, gt=0.0, le=1.0)
    """Joint step (rad) at which OMPL checks edges while searching. Coarser than the motion
    resolution so the search explores more in its time; the found path is then re-checked at
    the motion resolution and the attempt repeated if that fails."""

    @field_validator("algorithm")
    @classmethod
    def _known(cls, v: str) -> str:
        from agrisim.plugins.planners.ompl_planner.names import available_planners  # imports OMPL

        names = available_planners()
        if v not in names:
            raise ValueError(f"unknown OMPL planner {v!r}; available: {', '.join(names)}")
        return v


@hookimpl
def agrisim_planners() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="ompl",
            factory=lazy("agrisim.plugins.planners.ompl_planner.backend:OmplPlanner"),
            description="any OMPL geometric planner by name (default RRTConnect), 2 s x 5 attempts, simplified",
            options_model=OmplOptions,
            limits="geometric planners of the installed OMPL, by name (an unknown name is refused with the list)",
        )
    ]
