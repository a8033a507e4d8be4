"""``agrisim/PlantView-v0``: choosing where to look next, as a Gymnasium environment.

Each step moves one arm's camera to a chosen viewpoint with the episode's own machinery (IK,
OMPL planning, Ruckig timing, physics), renders the view there and fuses it into the
reconstruction, exactly as a run's routine does (:meth:`agrisim.episode.Episode.visit`). The
reward is the true plant surface the view saw first (the share of the ground truth's samples,
:mod:`agrisim.plugins.apps.nextview.coverage`) less a cost per second of arm motion; a viewpoint the arm
cannot reach costs a penalty and moves nothing. Each episode is a run directory, so ``agrisim
recon``, ``colmap`` and the splat reconstructor work on the views it chose.

Actions are an index into a candidate set (``candidates="5x10"``: the paper's hemisphere, 2 x
50; a denser ``"LxC"`` grid of the same band), or with ``actions="continuous"`` a point
``(azimuth, polar angle, radius, arm)`` around the plant (radians from +x and from the zenith,
metres from the hemisphere's centre; arm < 0.5 is the first). Observations: the new view's RGB,
depth (m) and labels, every arm's joints, and the voxel map of what the views saw
(:mod:`agrisim.plugins.apps.nextview.occupancy`: unknown, free, occupied, plant).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agrisim.config import build_config, merge
from agrisim.episode import Episode
from agrisim.evaluation.metrics import GroundTruth
from agrisim.evaluation.views import View
from agrisim.plugins.apps.nextview.coverage import SurfaceCoverage
from agrisim.plugins.apps.nextview.occupancy import VoxelMap
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.cell import soil_pose
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.setpoints import Setpoint
from agrisim.scene.transforms import look_at
from agrisim.validation import check_run, open_rig

#: the continuous action's radius range, m
RADIUS_M = (0.3, 0.8)


class PlantViewEnv(gym.Env[dict[str, np.ndarray], Any]):
    """Where to look next at a plant, with the real arms (see the module).

    Args:
        plant: a species (``agrisim plants``) or a plant file.
        candidates: the discrete actions' viewpoints, ``"LxC"`` levels x columns an arm on the
            paper's band of the hemisphere (``"5x10"``: its 100 setpoints).
        actions: ``"discrete"`` (an index into the candidates) or ``"continuous"``.
        resolution: the camera's image size, ``"WxH"``.
        renderer: any renderer backend (``raycast`` by default).
        max_views: steps an episode lasts (truncation).
        target_coverage: the episode ends (terminates) once this share of the surface is seen.
        coverage_weight, motion_weight, unreachable_penalty: the reward's terms: per share of
            the surface seen first, per second of arm motion, per unreachable viewpoint.
        truth_samples: samples of the true surface that coverage counts.
        grid_cells, grid_size_m: the voxel map, cells a side over a cube of this side.
        out: the directory episodes are written in (``episode_0000`` ...); a temporary one,
            removed on :meth:`close`, when None.
        record: each episode also records to Rerun (``recording.rrd`` in its directory).
        config: any further settings, by section (``{"physics": {"backend": "kinematic"}}``).
        render_mode: ``"rgb_array"``: :meth:`render` returns the last view's RGB.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self,
        plant: str = "coltsfoot",
        candidates: str = "5x10",
        actions: str = "discrete",
        resolution: str = "480x270",
        renderer: str = "raycast",
        max_views: int = 30,
        target_coverage: float | None = None,
        coverage_weight: float = 1.0,
        motion_weight: float = 0.01,
        unreachable_penalty: float = 0.05,
        truth_samples: int = 100_000,
        grid_cells: int = 80,
        grid_size_m: float = 0.5,
        out: str | Path | None = None,
        record: bool = False,
        config: dict[str, Any] | None = None,
        render_mode: str | None = None,
    ) -> None:
        if actions not in ("discrete", "continuous"):
            raise ValueError(f"actions must be 'discrete' or 'continuous', got {actions!r}")
        if max_views < 1:
            raise ValueError(f"max_views must be 1 or more, got {max_views}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.max_views, self.target_coverage = max_views, target_coverage
        self.weights = (coverage_weight, motion_weight, unreachable_penalty)
        self.truth_samples, self.record = truth_samples, record
        self.actions = actions
        base = {
            "plant": plant,
            "camera": {"resolution": resolution},
            "renderer": {"backend": renderer},
            "routine": {"setpoints": candidates},
        }
        self._base = merge(base, config or {})
        #: the settings every episode starts from (checked here, before any episode)
        self.config = build_config(self._base)
        registry = Registry(make_plugin_manager())
        checked = check_run(registry, self.config)
        self.camera = checked.camera
        rig, cell = open_rig(self.config, registry, checked.rig)  # the run's rig: its arms, its viewpoints
        self.arms = [arm.name for arm in cell.arms]
        routine = self.config.routine
        self.candidates: list[Setpoint] = [
            sp for pair in zip(*rig.setpoints(cell, routine).values(), strict=True) for sp in pair
        ]  # the paper's order: each step's setpoint of every arm in turn
        self._centre = soil_pose(cell)[:3, 3] + np.array([0.0, 0.0, routine.aim_height])
        self._sphere_centre = cell.plant_center + np.array([0.0, 0.0, routine.aim_height])
        self._grid = (grid_cells, grid_size_m)
        kins = [ArmKinematics(arm) for arm in cell.arms]
        h, w = self.camera.height, self.camera.width
        self.observation_space = spaces.Dict(  # type: ignore[assignment]
            {
                "rgb": spaces.Box(0, 255, (h, w, 3), np.uint8),
                "depth": spaces.Box(0.0, 1000.0, (h, w), np.float32),
                "labels": spaces.Box(0, 255, (h, w), np.uint8),
                "joints": spaces.Box(
                    np.stack([k.lower for k in kins]) - 1e-3, np.stack([k.upper for k in kins]) + 1e-3, dtype=np.float64
                ),
                "occupancy": spaces.Box(0, 3, (grid_cells,) * 3, np.uint8),
            }
        )
        if actions == "discrete":
            self.action_space: spaces.Space[Any] = spaces.Discrete(len(self.candidates))
        else:
            self.action_space = spaces.Box(
                np.array([-np.pi, 0.0, RADIUS_M[0], 0.0], np.float32),
                np.array([np.pi, np.pi / 2, RADIUS_M[1], 1.0], np.float32),
            )
        self._tmp = tempfile.TemporaryDirectory(prefix="agrisim-plantview-") if out is None else None
        self._root = Path(self._tmp.name if self._tmp is not None else out)  # type: ignore[arg-type]
        self._episode: Episode | None = None
        self._episodes = 0
        self._obs: dict[str, np.ndarray] | None = None
        #: seconds spent on the reward's coverage and on the voxel map (bench/nextview_speed.py)
        self.timing = {"coverage": 0.0, "map": 0.0}

    # ----------------------------------------------------------------------------- gym API

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """A new episode: the plant grown with ``options["plant_seed"]`` and the lab's clutter
        with ``options["pcg_seed"]``, both drawn from ``seed`` where not given."""
        super().reset(seed=seed)
        self._finish()
        options = options or {}
        plant_seed = int(options.get("plant_seed", self.np_random.integers(2**31)))
        pcg_seed = int(options.get("pcg_seed", self.np_random.integers(2**31)))
        out = self._root / f"episode_{self._episodes:04d}"
        while out.exists():
            self._episodes += 1
            out = self._root / f"episode_{self._episodes:04d}"
        self._episodes += 1
        layer = {"seed": plant_seed, "pcg_seed": pcg_seed, "output": {"out": str(out), "no_rrd": not self.record}}
        episode = Episode(build_config(merge(self._base, layer)))
        episode.setpoints = {arm: [] for arm in self.arms}  # filled by the views chosen
        episode.open()
        episode.start()
        self._episode = episode
        assert episode.scene is not None, "PlantView needs a renderer"
        self.coverage = SurfaceCoverage(GroundTruth.of_scene(episode.scene, self.truth_samples, plant_seed))
        self.voxels = VoxelMap.around(self._centre, self._grid[1], self._grid[0])
        self.views, self.reach_failures, self.motion_s = 0, 0, 0.0
        h, w = self.camera.height, self.camera.width
        self._obs = {
            "rgb": np.zeros((h, w, 3), np.uint8),
            "depth": np.zeros((h, w), np.float32),
            "labels": np.zeros((h, w), np.uint8),
            "joints": self._joints(),
            "occupancy": self.voxels.cells.copy(),
        }
        return self._observation(), self._info(0.0, 0.0, True, "", "")

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        assert self.action_space.contains(action), f"{action!r} ({type(action)}) invalid"
        if self._episode is None or self._obs is None:
            raise gym.error.ResetNeeded("call reset() before step(), and again after an episode ends")
        episode = self._episode
        robot, world_T_camera = self.target(action)
        target = Setpoint(robot, len(episode.setpoints[robot]), world_T_camera)
        results, views = episode.visit({robot: target})
        result = results[-1]
        gained, moved = 0.0, float(result.motion_s)
        if not result.reached:
            self.reach_failures += 1
        for view in views:
            t0 = time.perf_counter()
            gained += self.coverage.add(view)
            t1 = time.perf_counter()
            self._observe(view)
            self.timing["coverage"] += t1 - t0
            self.timing["map"] += time.perf_counter() - t1
        self.views += 1
        self.motion_s += moved
        self._obs["joints"] = self._joints()
        w_cover, w_motion, w_fail = self.weights
        reward = w_cover * gained - w_motion * moved - (0.0 if result.reached else w_fail)
        terminated = self.target_coverage is not None and self.coverage.value >= self.target_coverage
        truncated = self.views >= self.max_views and not terminated
        info = self._info(gained, moved, result.reached, result.reason, target.frame)
        if terminated or truncated:
            info["metrics"], info["run_dir"] = self._finish(), str(episode.out_dir)
        return self._observation(), float(reward), bool(terminated), bool(truncated), info

    def render(self) -> np.ndarray | None:
        return None if self._obs is None or self.render_mode is None else self._obs["rgb"]

    def close(self) -> None:
        self._finish()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    # ---------------------------------------------------------------------------- helpers

    def target(self, action: Any) -> tuple[str, np.ndarray]:
        """The arm and camera pose (``world_T_camera``) an action names."""
        if self.actions == "discrete":
            sp = self.candidates[int(action)]
            return sp.robot, sp.world_T_camera
        azimuth, polar, radius, arm = (float(a) for a in np.asarray(action, np.float64))
        direction = np.array([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
        position = self._sphere_centre - np.array([0.0, 0.0, self.config.routine.aim_height]) + radius * direction
        return self.arms[min(int(arm >= 0.5), len(self.arms) - 1)], look_at(position, self._sphere_centre)

    @property
    def episode(self) -> Episode | None:
        """The episode in progress (its run, backends and timings), None before reset()."""
        return self._episode

    def look_from(self, world_T_camera: np.ndarray) -> View:
        """The view from ``world_T_camera`` with the arms left out, taken without moving or
        writing anything (:meth:`agrisim.episode.Episode.look_from`): for policies that may
        look ahead at the truth, such as the oracle."""
        assert self._episode is not None, "call reset() first"
        return self._episode.look_from(world_T_camera)

    def camera_position(self, robot: str) -> np.ndarray:
        """Where ``robot``'s camera is now (world frame)."""
        assert self._episode is not None
        return self._episode.kinematics[robot].fk(self._episode.joint_positions(robot))[:3, 3]

    def _observation(self) -> dict[str, np.ndarray]:
        """The observation, copied: callers keep what they are given."""
        assert self._obs is not None
        return {key: value.copy() for key, value in self._obs.items()}

    def _joints(self) -> np.ndarray:
        assert self._episode is not None
        return np.stack([self._episode.joint_positions(r) for r in self.arms]).astype(np.float64)

    def _observe(self, view: View) -> None:
        assert self._obs is not None
        images = view.images
        self._obs["rgb"] = np.ascontiguousarray(images.rgb, np.uint8)
        self._obs["depth"] = np.asarray(images.depth, np.float32)
        self._obs["labels"] = np.asarray(images.labels, np.uint8)
        self.voxels.integrate(view.camera, view.world_T_camera, images.depth, images.labels)
        self._obs["occupancy"] = self.voxels.cells.copy()

    def _info(self, gained: float, moved: float, reached: bool, reason: str, frame: str) -> dict[str, Any]:
        return {
            "coverage": self.coverage.value,
            "coverage_gain": gained,
            "motion_s": moved,
            "motion_total_s": self.motion_s,
            "views": self.views,
            "reached": reached,
            "reason": reason,
            "frame": frame,
            "reach_failures": self.reach_failures,
        }

    def _finish(self) -> dict[str, Any] | None:
        """End the episode in progress, if any: its reconstruction measured and its run written.
        Returns the reconstruction's metrics (None without views)."""
        episode, self._episode = self._episode, None
        if episode is None:
            return None
        try:
            metrics = episode.finish_reconstruction() if self.views > self.reach_failures else None
        finally:
            episode.close("complete")
        return metrics
