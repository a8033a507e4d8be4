"""What the GPU benches read of a saved run carried to a GPU machine: the scene, the cameras,
the run's render settings, as ``agrisim render`` reads them, without its check that the run's
own images are there (a carried run leaves them behind)."""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.config import ImagerConfig, RenderConfig, build_config
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json, capture_order
from agrisim.interfaces import Imager, View, view_key
from agrisim.plugins.apps.render import RenderPlan
from agrisim.plugins.formats.scene_glb import read_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.scene.camera import CameraModel, preset
from agrisim.scene.model import Scene
from agrisim.validation import open_imager


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


def drawn_views(
    run: Path, renderer: str, overrides: dict, camera_preset: str | None = None, imager: str | None = None
) -> list[View]:
    """Every frame of ``run`` drawn again: RGB, labels and depth as a run would store them;
    through another camera (``camera_preset``, at the run's image size) and an imager
    (``imager``: each arm's camera auto-exposing from view to view in capture order), where
    named, than the run's."""
    plan = RenderPlan(run, renderer, overrides, Path(tempfile.mkdtemp()) / "unused", overwrite=False)
    if imager is not None:
        plan.config = plan.config.model_copy(update={"imager": ImagerConfig(model=imager)})
    draw, camera = plan.renderer()
    if camera_preset is not None:
        camera = preset(camera_preset, f"{camera.width}x{camera.height}")
    pipelines: dict[str, Imager | None] = {}
    registry = Registry(make_plugin_manager())
    views = []
    start = time.perf_counter()
    try:
        order = capture_order(json.loads((run / layout.RUN_JSON).read_text()), plan.frames)
        for frame in order:
            T = np.asarray(plan.cameras["frames"][frame]["world_T_camera"], np.float64)
            images = draw.render(camera, T, {})
            robot = frame.split("_")[0]
            if robot not in pipelines:
                pipelines[robot] = open_imager(registry, plan.config.imager, plan.config.seed)
            shooter = pipelines[robot]
            if shooter is not None and images.radiance is not None:
                images.rgb = shooter.shoot(images.radiance, view_key(frame)).rgb
                images.radiance = None
            views.append(View(frame, camera, T, images.stored()))
    finally:
        draw.close()
    seconds = time.perf_counter() - start
    through = f" through {camera_preset}" if camera_preset else ""
    shot = f", shot by {imager}" if imager else ""
    print(
        f"{len(views)} views {camera.width}x{camera.height} drawn by {renderer}{through}{shot} in {seconds:.1f} s",
        flush=True,
    )
    return views
