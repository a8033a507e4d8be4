"""The ``direct`` planner: the straight joint-space line, collision-checked."""

from __future__ import annotations

import numpy as np

from agrisim import BackendSpec, hookimpl
from agrisim.interfaces import Planner, PlanningFailed, Validity
from agrisim.registry import NoOptions
from agrisim.robot.segments import require_within_limits, segment_is_valid


class DirectPlanner(Planner):
    """Moves every joint in proportion from start to goal; fails if anything is in the way."""

    def plan(
        self,
        start: np.ndarray,
        goal: np.ndarray,
        is_valid: Validity,
        lower: np.ndarray,
        upper: np.ndarray,
        seed: int,
        resolution: float,
    ) -> np.ndarray:
        require_within_limits(goal, lower, upper)
        if not segment_is_valid(start, goal, is_valid, resolution):
            raise PlanningFailed("the straight joint-space line is blocked by a collision")
        return np.array([start, goal], float)


@hookimpl
def agrisim_planners() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="direct",
            factory=DirectPlanner,
            description="straight joint-space line, collision-checked; fails cleanly when blocked",
            options_model=NoOptions,
            limits="no search: any obstacle on the line fails the setpoint",
        )
    ]
