"""Collision checking of joint-space segments, shared by every planner and by tests."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Protocol

import numpy as np

from agrisim.errors import PlanningFailed

if TYPE_CHECKING:
    from agrisim.robot.trajectory import Limits, TimedPath


class ArmsCollide(Protocol):
    """What :func:`arms_stay_apart` asks of a physics backend (its contract's method)."""

    def arms_in_collision(self, configs: Mapping[str, np.ndarray]) -> bool: ...


def require_within_limits(goal: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
    """Raise :class:`PlanningFailed` when ``goal`` lies outside the joint limits."""
    if np.any(goal < lower) or np.any(goal > upper):
        raise PlanningFailed("goal outside the joint limits")


def segment_samples(a: np.ndarray, b: np.ndarray, resolution: float) -> np.ndarray:
    """Configurations from ``a`` to ``b`` (both included) no more than ``resolution`` apart in
    any joint."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(int(np.ceil(np.max(np.abs(b - a)) / resolution)), 1)
    return a + (b - a) * np.linspace(0.0, 1.0, n + 1)[:, None]


def segment_is_valid(a: np.ndarray, b: np.ndarray, is_valid: Callable[[np.ndarray], bool], resolution: float) -> bool:
    """Is every sample of the straight segment ``a``-``b`` valid? Checks the middle first,
    where a blocked segment is most likely to fail, to stop early."""
    samples = segment_samples(a, b, resolution)
    order = _bisection_order(len(samples))
    return all(is_valid(samples[i]) for i in order)


def path_is_valid(path: np.ndarray, is_valid: Callable[[np.ndarray], bool], resolution: float) -> bool:
    """Is every segment of ``path`` valid?"""
    return all(segment_is_valid(a, b, is_valid, resolution) for a, b in zip(path[:-1], path[1:], strict=True))


def _bisection_order(n: int) -> list[int]:
    order, seen = [], set()
    stack = [(0, n - 1)]
    for end in (n - 1, 0):
        order.append(end)
        seen.add(end)
    while stack:
        lo, hi = stack.pop(0)
        mid = (lo + hi) // 2
        if mid not in seen:
            seen.add(mid)
            order.append(mid)
        if hi - lo > 1:
            stack.append((lo, mid))
            stack.append((mid, hi))
    return order


def arms_stay_apart(
    physics: ArmsCollide, moves: Mapping[str, TimedPath], limits: Mapping[str, Limits], step: float
) -> bool:
    """Do the arms' trajectories, played together, stay clear of each other? Sampled so that no
    joint moves more than ``step`` between two checks."""
    if len(moves) < 2:
        return True
    dt = step / max(float(np.max(limits[r].velocity)) for r in moves)
    horizon = max(m.duration for m in moves.values())
    robots = list(moves)
    for t in np.append(np.arange(0.0, horizon, dt), horizon):
        if physics.arms_in_collision({r: moves[r].sample(float(t))[0] for r in robots}):
            return False
    return True
