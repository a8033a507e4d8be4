"""The ``ompl`` planner: any OMPL geometric planner by name (default RRTConnect).

As in the paper's ROS set-up: 2 s of planning time per attempt, 5 attempts, then OMPL's path
simplification. Collision checking is agrisim's validity callable (the physics backend's
query), at the motion resolution the episode asks for.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, field_validator

from agrisim import BackendSpec, Options, hookimpl
from agrisim.interfaces import Planner, PlanningFailed, Validity
from agrisim.robot.segments import path_is_valid, require_within_limits, segment_is_valid
from agrisim.util.native_output import silence_native_output_at_exit

from ompl import base as ob  # noqa: E402  (after agrisim imports: keeps the import order stable)
from ompl import geometric as og
from ompl import util as ou


def available_planners() -> list[str]:
    """Names of the OMPL geometric planners these bindings expose."""
    return sorted(
        name
        for name in dir(og)
        if isinstance(getattr(og, name), type)
        and issubclass(getattr(og, name), ob.Planner)
        and name not in ("Planner",)
    )


_seeded = False


def _seed_once(seed: int) -> None:
    # OMPL takes a global seed only before its first random generator exists.
    global _seeded
    if not _seeded:
        ou.RNG.setSeed((seed & 0x7FFFFFFF) + 1)  # OMPL refuses 0
        _seeded = True


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
        names = available_planners()
        if v not in names:
            raise ValueError(f"unknown OMPL planner {v!r}; available: {', '.join(names)}")
        return v


class OmplPlanner(Planner):
    """Plans in the arm's joint space (a real vector space bounded by the joint limits)."""

    def __init__(self, options: OmplOptions) -> None:
        super().__init__(options)
        ou.setLogLevel(ou.LogLevel.LOG_WARN)
        _seed_once(options.seed)
        silence_native_output_at_exit()  # nanobind's leak report at interpreter exit

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
        require_within_limits(goal, lower, upper)
        if self.options.try_direct and segment_is_valid(start, goal, is_valid, resolution):
            return np.array([start, goal])
        if not is_valid(start):
            raise PlanningFailed("the start configuration is in collision")
        if not is_valid(goal):
            raise PlanningFailed("the goal configuration is in collision")
        dof = len(start)
        space = ob.RealVectorStateSpace(dof)
        bounds = ob.RealVectorBounds(dof)
        for i in range(dof):
            bounds.setLow(i, float(lower[i]))
            bounds.setHigh(i, float(upper[i]))
        space.setBounds(bounds)
        ss = og.SimpleSetup(space)
        ss.setStateValidityChecker(lambda s: bool(is_valid(np.array([s[i] for i in range(dof)]))))
        si = ss.getSpaceInformation()
        # OMPL measures the resolution as a fraction of the space's extent (L2 metric).
        search = max(self.options.search_resolution, resolution)
        si.setStateValidityCheckingResolution(search / space.getMaximumExtent())
        ss.setPlanner(getattr(og, self.options.algorithm)(si))
        a, b = space.allocState(), space.allocState()
        for i in range(dof):
            a[i], b[i] = float(start[i]), float(goal[i])
        ss.setStartAndGoalStates(a, b)
        ss.setup()
        last = "no attempt"
        for _ in range(self.options.attempts):
            ss.clear()
            status = ss.solve(self.options.time)
            if not ss.haveExactSolutionPath():
                last = str(status)
                continue
            if self.options.simplify:
                ss.simplifySolution(self.options.time)
            path = ss.getSolutionPath()
            waypoints = np.array([[path.getState(k)[i] for i in range(dof)] for k in range(path.getStateCount())])
            waypoints[0], waypoints[-1] = start, goal
            # OMPL searched at a coarse step; agrisim's guarantee is the motion resolution.
            if path_is_valid(waypoints, is_valid, resolution):
                return waypoints
            last = "paths found collide at the motion resolution"
        raise PlanningFailed(
            f"{self.options.algorithm} found no path in {self.options.attempts} x {self.options.time:g} s ({last})"
        )


@hookimpl
def agrisim_planners() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="ompl",
            factory=OmplPlanner,
            description="any OMPL geometric planner by name (default RRTConnect), 2 s x 5 attempts, simplified",
            options_model=OmplOptions,
            limits=f"geometric planners: {', '.join(available_planners())}",
        )
    ]
