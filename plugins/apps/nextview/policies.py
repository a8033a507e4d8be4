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
  and the sides seen): a leaf's underside counts, as in the reward;
- ``spread-maximin``: farthest-point sampling of the views' directions about the plant (each
  view the largest smallest angle to those seen), from where the cameras were alone;
- ``spread``: a greedy cover of the sphere of surface orientations (each view the one whose
  40-degree cone adds the most orientations no view has seen), from where the cameras were alone;
- ``spread-surface``: ``spread``'s cover times the ``surface`` gain from the third view on.

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


def view_directions(env: PlantViewEnv) -> np.ndarray:
    """Each candidate's unit direction (N x 3) from the point the candidates aim at to its
    camera: the least-squares meeting point of their optical axes (on the paper's band, the
    plant's aim point), so that angles between views are angles about the plant."""
    poses = np.stack([sp.world_T_camera for sp in env.candidates])
    eyes, axes = poses[:, :3, 3], poses[:, :3, 2]  # the camera looks along its +z
    # sum over axes of (I - a a^T) (p - e) = 0: the point nearest every axis
    projectors = np.eye(3)[None] - axes[:, :, None] * axes[:, None, :]
    lhs, rhs = projectors.sum(axis=0), np.einsum("nij,nj->i", projectors, eyes)
    aim = np.linalg.lstsq(lhs, rhs, rcond=None)[0] if np.linalg.matrix_rank(lhs) == 3 else eyes.mean(axis=0)
    offsets = eyes - aim
    return offsets / np.maximum(np.linalg.norm(offsets, axis=1, keepdims=True), 1e-12)


def _travel(env: PlantViewEnv, i: int) -> float:
    """How far candidate ``i``'s arm would move its camera, m (straight line)."""
    sp = env.candidates[i]
    return float(np.linalg.norm(sp.world_T_camera[:3, 3] - env.camera_position(sp.robot)))


class SpreadMaximin(Policy):
    """Farthest-point sampling of the candidates' directions about the plant: each view the one
    whose smallest angle to the views already seen is largest, from the episode's start (the
    first: the nearest to the arms' cameras), ties (within :attr:`TIE_RAD`) to the shorter move.

    Why: at 5 or 10 views a random draw often puts two views side by side and leaves a flank
    unseen; greedy farthest-point is within a factor 2 of the best spread at every prefix
    (Gonzalez 1985), whatever the budget, and costs microseconds. It uses only where the cameras
    were. Measured (the guide): above random on average but below :class:`Spread`: on the
    paper's band the largest angle falls on the band's edges, top and bottom in turn."""

    name = "spread-maximin"
    #: angles closer than this count as equal: the shorter move wins, radians (about a degree)
    TIE_RAD = 0.02

    def reset(self, env: PlantViewEnv) -> None:
        super().reset(env)
        self.directions = view_directions(env)

    def seen(self) -> list[int]:
        """The views taken that reached their viewpoint (an unreached one saw nothing)."""
        return sorted(self.taken - self.unreachable)

    def score(self, env: PlantViewEnv, candidates: list[int]) -> np.ndarray:
        """Each candidate's smallest angle to the views seen, radians (pi with none seen)."""
        seen = self.directions[self.seen()]
        if not len(seen):
            return np.full(len(candidates), np.pi)
        return np.arccos(np.clip(self.directions[candidates] @ seen.T, -1.0, 1.0).max(axis=1))

    def tied(self, score: np.ndarray) -> np.ndarray:
        """The candidates whose score counts as the best's."""
        return score >= score.max() - self.TIE_RAD

    def act(self, env: PlantViewEnv, obs: dict[str, np.ndarray]) -> int:
        candidates = self.open(env)
        best = self.tied(self.score(env, candidates))
        return min((c for c, b in zip(candidates, best, strict=True) if b), key=lambda i: _travel(env, i))


def orientations(count: int = 2000) -> np.ndarray:
    """``count`` unit vectors spread evenly over the sphere (a Fibonacci lattice, count x 3)."""
    k = np.arange(count) + 0.5
    polar, azimuth = np.arccos(1.0 - 2.0 * k / count), np.pi * (1.0 + 5.0**0.5) * k
    return np.column_stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)])


class Spread(SpreadMaximin):
    """Greedy cover of the sphere of surface orientations: a view from direction ``d`` about the
    plant counts as seeing the orientations within :attr:`CONE_DEG` of ``d`` (2,000 spread over
    the sphere); each view the one that sees the most orientations no view has yet, ties (equal
    counts) to the shorter move; the first, the nearest to the arms' cameras.

    Why: a farthest-point rule looks at one angle only, the nearest view's; the cover counts how
    much of the sphere of directions a view would add, so a low view that opens the plant's
    underside and a flank at once beats one on the band's edge (greedy cover is within 1 - 1/e
    of the best set at every prefix, Nemhauser et al. 1978). 40 degrees won among 30-80 (ten
    species, 30-50; three, 40-80: the guide). It uses only where the cameras were, never what
    they saw."""

    name = "spread"
    #: the half-angle of the cone of orientations a view counts as seeing, degrees
    CONE_DEG = 40.0
    TIE_RAD = 0.0

    def reset(self, env: PlantViewEnv) -> None:
        super().reset(env)
        self.sees = (self.directions @ orientations().T) >= np.cos(np.radians(self.CONE_DEG))  # views x sphere
        self.covered = np.zeros(self.sees.shape[1], bool)

    def observe(self, action: int, info: dict[str, Any]) -> None:
        super().observe(action, info)
        if info["reached"]:
            self.covered |= self.sees[action]

    def score(self, env: PlantViewEnv, candidates: list[int]) -> np.ndarray:
        """The orientations each candidate would add to those seen."""
        return (self.sees[candidates] & ~self.covered).sum(axis=1).astype(np.float64)


class SpreadSurface(Spread):
    """:class:`Spread`'s cover times the ``surface`` gain (each normalised by its largest over
    the open candidates), from the :attr:`PRIOR_VIEWS`-th view on; the first views by the cover
    alone.

    Why: the first views' map knows too little for its gain to mean much (``surface`` is no
    better than random at 5 views), and the cover alone ignores what the plant is like; the
    product keeps the views spread while preferring, among spread ones, those whose rays meet
    unknown space and unseen leaf sides. 3 prior views won among 1, 3 and 5, the product over a
    rank sum and a weighted sum (the guide)."""

    name = "spread-surface"
    #: the views taken by the cover alone before the map's gain joins it
    PRIOR_VIEWS = 3

    def score(self, env: PlantViewEnv, candidates: list[int]) -> np.ndarray:
        prior = super().score(env, candidates)
        if len(self.seen()) < self.PRIOR_VIEWS:
            return prior
        gain = np.array(
            [
                env.voxels.information_gain(env.camera, env.candidates[i].world_T_camera, surface=True)
                for i in candidates
            ],
            np.float64,
        )
        return prior / max(prior.max(), 1.0) * gain / max(gain.max(), 1.0)


POLICIES: dict[str, Callable[[int], Policy]] = {
    p.name: p
    for p in (
        Paper,
        Random,
        Oracle,
        Volumetric,
        VolumetricMotion,
        Surface,
        SurfaceMotion,
        SpreadMaximin,
        Spread,
        SpreadSurface,
    )
}
