"""What the README's figure scripts share: the lab's cell with its arms at home, the camera at a
given size, the paper's hemisphere of setpoints, and each figure row's scene."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from agrisim.config import CellConfig, RoutineConfig, build_config
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.rigs.paper.cell import build_cell, hemisphere
from agrisim.plugins.rooms.lab.room import build_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.cell import Cell
from agrisim.robot.kinematics import ArmKinematics
from agrisim.scene.camera import CameraModel, preset
from agrisim.scene.model import Scene


@dataclass
class FigureViews:
    """The cell, the arms' link poses at home, the camera and the hemisphere's setpoints."""

    registry: Registry
    cell: Cell
    poses: dict[str, dict[str, np.ndarray]]
    camera: CameraModel
    setpoints: dict[str, list[Any]]

    def scene(self, plant: str, labels: str) -> Scene:
        """The lab with ``plant`` labelled as ``labels`` (plant or organs)."""
        return build_scene(self.cell, resolve_plant(self.registry, build_config({"plant": plant})), labels=labels)

    def pose(self, robot: str, index: int) -> np.ndarray:
        """``world_T_camera`` of setpoint ``index`` of ``robot``."""
        return self.setpoints[robot][index].world_T_camera


def figure_views(width: int, height: int) -> FigureViews:
    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    poses = {a.name: ArmKinematics(a).link_poses(np.array(a.home)) for a in cell.arms}
    return FigureViews(
        registry, cell, poses, preset("rpi3-wide-1080p", f"{width}x{height}"), hemisphere(cell, RoutineConfig())
    )
