"""Policies that choose the next view among a :class:`~agrisim.plugins.apps.nextview.env.PlantViewEnv`'s
candidates (discrete actions), for ``agrisim nextview``'s benchmark:

- ``paper``: the paper's 100 setpoints in its order (each step's setpoint of each arm in turn);
- ``random``: a candidate not yet taken, uniformly;
- ``oracle``: greedy on the true surface (the candidate that would add the most of it, from a
  look at every candidate with the arms left out, taken once per episode): an upper bound no
  camera-only planner can beat step for step;
- ``volumetric``: uses only what the views measured: the candidate whose rays would reach the
  most unknown voxels of the map before an occupied one (Isler et al. 2016; Delmerico et al.
  2018), the voxel map of :mod:`agrisim.plugins.apps.nextview.occupancy`;
- ``volumetric-motion``: the same gain discounted by the move, ``gain * exp(-distance /
  MOTION_SCALE_M)`` with ``distance`` from where that arm's camera is now (Bircher et al.
  2016's discount), so that near views win ties and the arms travel less;
- ``surface``, ``surface-motion``: the volumetric gain plus the plant voxels the view would
  meet whose facing side no view has seen yet (the map keeps each plant voxel's measured normal
  and the sides seen): a leaf's underside counts, as in the reward.

Every policy skips candidates already taken or found out of reach.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from agrisim.plugins.apps.nextview.env import PlantViewEnv

#: the distance over which ``volumetric-motion`` discounts a view's gain by 1/e, m
MOTION_SCALE_M = 0.4


class Policy:
    """Chooses candidate indices: :meth:`reset` at an episode's start, then :meth:`act` each
    step, then :meth:`observe` with the step's info."""

    name = "policy"

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)

    def reset(self, env: PlantViewEnv) -> None:
        self.taken: set[int] = set()
        self.unreachable: set[int] = set()

    def open(self, env: PlantViewEnv) -> list[int]:
        """The candidates neither taken nor found out of reach."""
        return [i for i in range(len(env.candidates)) if i not in self.taken and i not in self.unreachable]

    def act(self, env: PlantViewEnv, obs: dict[str, np.ndarray]) -> int:
        raise NotImplementedError

    def observe(self, action: int, info: dict[str, Any]) -> None:
        self.taken.add(action)
        if not info["reached"]:
            self.unreachable.add(action)


class Paper(Policy):
    name = "paper"

    def act(self, env: PlantViewEnv, obs: dict[str, np.ndarray]) -> int:
        return min(self.open(env))


class Random(Policy):
    name = "random"

    def act(self, env: PlantViewEnv, obs: dict[str, np.ndarray]) -> int:
        return int(self.rng.choice(self.open(env)))


class Oracle(Policy):
    name = "oracle"

    def reset(self, env: PlantViewEnv) -> None:
        super().reset(env)
        # each candidate's view of the truth, looked at once; what it would add is then
        # recounted each step against what is seen by then
        self.sees = [env.coverage.visible(env.look_from(sp.world_T_camera)) for sp in env.candidates]

    def act(self, env: PlantViewEnv, obs: dict[str, np.ndarray]) -> int:
        return max(self.open(env), key=lambda i: env.coverage.gain(*self.sees[i]))


class Volumetric(Policy):
    name = "volumetric"

    def score(self, env: PlantViewEnv, i: int) -> float:
        return float(env.voxels.information_gain(env.camera, env.candidates[i].world_T_camera))

    def act(self, env: PlantViewEnv, obs: dict[str, np.ndarray]) -> int:
        return max(self.open(env), key=lambda i: self.score(env, i))


def _discount(env: PlantViewEnv, i: int) -> float:
    """``exp(-d / MOTION_SCALE_M)``, ``d`` the candidate's distance from its arm's camera now."""
    sp = env.candidates[i]
    distance = float(np.linalg.norm(sp.world_T_camera[:3, 3] - env.camera_position(sp.robot)))
    return float(np.exp(-distance / MOTION_SCALE_M))


class VolumetricMotion(Volumetric):
    name = "volumetric-motion"

    def score(self, env: PlantViewEnv, i: int) -> float:
        return super().score(env, i) * _discount(env, i)


class Surface(Volumetric):
    name = "surface"

    def score(self, env: PlantViewEnv, i: int) -> float:
        return float(env.voxels.information_gain(env.camera, env.candidates[i].world_T_camera, surface=True))


class SurfaceMotion(Surface):
    name = "surface-motion"

    def score(self, env: PlantViewEnv, i: int) -> float:
        return super().score(env, i) * _discount(env, i)


POLICIES: dict[str, Callable[[int], Policy]] = {
    p.name: p for p in (Paper, Random, Oracle, Volumetric, VolumetricMotion, Surface, SurfaceMotion)
}
