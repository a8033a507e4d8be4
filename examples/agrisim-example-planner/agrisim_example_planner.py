"""``waypoint``: an example third-party planner for agrisim.

Tries the straight joint-space line first. When something is in the way (the plant, the other
arm), it goes through a *retracted* configuration instead: the shoulder lifted towards upright
and the elbow folded, so the forearm and camera come in close to the arm's own base and pass
over whatever blocked the line. Each segment is collision-checked with
:func:`agrisim.robot.segments.segment_is_valid`, at the resolution the episode asks for.

Two detours are tried at growing retraction, the shortest first:

* one via configuration: the start-goal midpoint, retracted;
* retract at the start, swing across retracted, extend at the goal (three segments).

The plugin is registered through the ``agrisim`` entry-point group in its ``pyproject.toml``::

    [project.entry-points.agrisim]
    example-planner = "agrisim_example_planner"
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.interfaces import Planner, PlanningFailed, Validity
from agrisim.robot.segments import require_within_limits, segment_is_valid

__version__ = "0.1.0"


class WaypointOptions(Options):
    """Options of the ``waypoint`` planner (``[planner.waypoint]`` in a config file).

    ``agrisim.Options`` refuses unknown keys and true/false for numbers; the docstring under
    each field becomes its description (``agrisim plugins --options``, the JSON schema)."""

    retract: float = Field(1.0, gt=0.0, le=math.pi)
    """Largest move of the shoulder-lift and elbow joints towards the retracted pose, rad."""
    levels: int = Field(3, ge=1, le=20)
    """Retraction levels tried, evenly up to ``retract`` (the smallest detour that is free wins)."""
    lift_joint: int = Field(1, ge=0)
    """Index of the shoulder-lift joint (UR arms: 1)."""
    elbow_joint: int = Field(2, ge=0)
    """Index of the elbow joint (UR arms: 2)."""
    retracted_lift: float = Field(-math.pi / 2, ge=-2 * math.pi, le=2 * math.pi)
    """Shoulder-lift angle of the retracted pose, rad (UR arms: -pi/2, upper arm upright)."""
    retracted_elbow: float = Field(2.5, ge=0.0, le=2 * math.pi)
    """Elbow bend of the retracted pose, rad; the sign of the arm's current bend is kept."""


def _towards(value: float, target: float, step: float) -> float:
    """``value`` moved towards ``target`` by at most ``step``."""
    return value + float(np.clip(target - value, -step, step))


class WaypointPlanner(Planner):
    """Straight line if free, otherwise through a retracted intermediate configuration."""

    options: WaypointOptions

    def retracted(self, q: np.ndarray, amount: float, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """``q`` with the shoulder lifted and the elbow folded by up to ``amount`` rad each."""
        o = self.options
        out = np.array(q, float)
        out[o.lift_joint] = _towards(out[o.lift_joint], o.retracted_lift, amount)
        sign = 1.0 if out[o.elbow_joint] >= 0.0 else -1.0
        out[o.elbow_joint] = _towards(out[o.elbow_joint], sign * o.retracted_elbow, amount)
        return np.clip(out, lower, upper)

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
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        o = self.options
        if max(o.lift_joint, o.elbow_joint) >= len(start):
            raise PlanningFailed(f"the arm has {len(start)} joints; lift/elbow joint index out of range")
        require_within_limits(goal, lower, upper)
        if not is_valid(goal):
            raise PlanningFailed("the goal configuration is in collision")
        if segment_is_valid(start, goal, is_valid, resolution):
            return np.array([start, goal])
        for level in range(1, o.levels + 1):
            amount = o.retract * level / o.levels
            mid = self.retracted((start + goal) / 2.0, amount, lower, upper)
            up_start = self.retracted(start, amount, lower, upper)
            up_goal = self.retracted(goal, amount, lower, upper)
            for path in ([start, mid, goal], [start, up_start, up_goal, goal]):
                if all(segment_is_valid(a, b, is_valid, resolution) for a, b in itertools.pairwise(path)):
                    return np.array(path)
        raise PlanningFailed(
            f"straight line blocked and no retracted detour (up to {o.retract:g} rad in {o.levels} levels) is free"
        )


@hookimpl
def agrisim_planners() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="waypoint",
            factory=WaypointPlanner,
            description="straight line, else a detour through a retracted arm pose (example plugin)",
            options_model=WaypointOptions,
            limits="no search: fails when neither the line nor a retracted detour is free",
        )
    ]
