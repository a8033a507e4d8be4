"""The OMPL planner: its bindings, the process-wide seed, and planning in an arm's joint space (see the package)."""

from __future__ import annotations

import numpy as np
from ompl import base as ob  # noqa: E402, I001  (after agrisim imports: keeps the import order stable)
from ompl import geometric as og  # noqa: E402
from ompl import util as ou  # noqa: E402

from agrisim.interfaces import Planner, PlanningFailed, Validity
from agrisim.plugins.native_output import silence_native_output_at_exit
from agrisim.plugins.planners.ompl_planner import OmplOptions
from agrisim.plugins.planners.ompl_planner.names import available_planners  # noqa: F401 - part of the backend's API
from agrisim.robot.segments import path_is_valid, require_within_limits, segment_is_valid

_seeded = False


def _seed_once(seed: int) -> None:
    # OMPL takes a global seed only before its first random generator exists.
    global _seeded
    if not _seeded:
        ou.RNG.setSeed((seed & 0x7FFFFFFF) + 1)  # OMPL refuses 0
        _seeded = True


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
        # the space holds the start where the arm stands: a simulated arm that stopped at a
        # joint's limit may sit a hair beyond it, and OMPL drops a start outside its bounds
        low, high = np.minimum(lower, start), np.maximum(upper, start)
        for i in range(dof):
            bounds.setLow(i, float(low[i]))
            bounds.setHigh(i, float(high[i]))
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
