"""What the GPU benches read of a saved run carried to a GPU machine: the scene, the cameras,
the run's render settings, as ``agrisim render`` reads them, without its check that the run's
own images are there (a carried run leaves them behind)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.config import RenderConfig, build_config
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json
from agrisim.files.scene_glb import read_scene
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import Scene


@dataclass
class SavedRun:
    run: dict[str, Any]
    """run.json"""
    cameras: dict[str, Any]
    """cameras.json"""
    settings: RenderConfig
    scene: Scene
    camera: CameraModel


def saved_run(run_dir: Path) -> SavedRun:
    """The run in ``run_dir`` (scene/lab.glb, cameras.json, run.json)."""
    run = json.loads((run_dir / layout.RUN_JSON).read_text())
    cameras = json.loads((run_dir / layout.CAMERAS_JSON).read_text())
    saved = {k: v for k, v in run["config"].items() if k not in ("output", "renderer")}
    return SavedRun(
        run,
        cameras,
        build_config(saved).render,
        read_scene(run_dir / layout.SCENE_GLB),
        camera_from_json(cameras["intrinsics"]),
    )


def frame_pose(run_dir: Path, frame: str) -> tuple[np.ndarray, dict[str, dict[str, np.ndarray]]]:
    """Where ``frame`` of the run in ``run_dir`` was taken: world_T_camera and the arms' link
    poses it was rendered with."""
    cameras = json.loads((run_dir / layout.CAMERAS_JSON).read_text())
    T = np.asarray(cameras["frames"][frame]["world_T_camera"], np.float64)
    doc = json.loads(layout.link_poses(run_dir, frame).read_text())
    return T, {r: {k: np.asarray(v) for k, v in links.items()} for r, links in doc.items()}
