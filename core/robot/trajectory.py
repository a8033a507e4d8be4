"""Time-parametrisation of a planned joint path with Ruckig.

Each straight segment of the path becomes a rest-to-rest, jerk-limited Ruckig trajectory with
``Synchronization.Phase``, which keeps every joint in proportion and so the motion stays on the
segment the planner collision-checked. (Ruckig's own intermediate waypoints need its cloud
service; segment by segment needs nothing.)
"""

from __future__ import annotations

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

from agrisim.data import JointTrajectory


class Limits:
    """Per-joint velocity, acceleration and jerk limits."""

    def __init__(self, velocity: np.ndarray, acceleration: np.ndarray, jerk: np.ndarray) -> None:
        self.velocity = np.asarray(velocity, float)
        self.acceleration = np.asarray(acceleration, float)
        self.jerk = np.asarray(jerk, float)


class TimedPath:
    """A chain of Ruckig segments; ``sample(t)`` evaluates position, velocity, acceleration."""

    def __init__(self, segments: list[Trajectory], start: np.ndarray) -> None:
        self.segments = segments
        self.start = np.asarray(start, float)
        durations = [s.duration for s in segments]
        self.boundaries = np.concatenate([[0.0], np.cumsum(durations)])

    @property
    def duration(self) -> float:
        return float(self.boundaries[-1])

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.segments:
            z = np.zeros_like(self.start)
            return self.start.copy(), z, z.copy()
        t = min(max(t, 0.0), self.duration)
        i = min(int(np.searchsorted(self.boundaries, t, side="right")) - 1, len(self.segments) - 1)
        p, v, a = self.segments[i].at_time(t - self.boundaries[i])
        return np.array(p), np.array(v), np.array(a)

    def discretize(self, dt: float) -> JointTrajectory:
        """Samples every ``dt`` seconds, the end point included."""
        n = max(int(np.ceil(self.duration / dt)), 0)
        times = np.minimum(np.arange(n + 1) * dt, self.duration)
        q = np.empty((n + 1, len(self.start)))
        qd = np.empty_like(q)
        for k, t in enumerate(times):
            q[k], qd[k], _ = self.sample(float(t))
        return JointTrajectory(times, q, qd)


def time_parametrize(path: np.ndarray, limits: Limits) -> TimedPath:
    """Rest-to-rest, phase-synchronised Ruckig segments through the waypoints of ``path``."""
    path = np.asarray(path, float)
    dof = path.shape[1]
    otg = Ruckig(dof)
    segments = []
    for a, b in zip(path[:-1], path[1:], strict=True):
        if np.allclose(a, b, atol=1e-12):
            continue
        inp = InputParameter(dof)
        inp.current_position = a.tolist()
        inp.target_position = b.tolist()
        inp.max_velocity = limits.velocity.tolist()
        inp.max_acceleration = limits.acceleration.tolist()
        inp.max_jerk = limits.jerk.tolist()
        inp.synchronization = Synchronization.Phase
        traj = Trajectory(dof)
        result = otg.calculate(inp, traj)
        if result not in (Result.Working, Result.Finished):
            raise RuntimeError(f"ruckig could not time-parametrise a segment: {result}")
        segments.append(traj)
    return TimedPath(segments, path[0])
