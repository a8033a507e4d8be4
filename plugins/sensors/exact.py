"""The exact depth sensor: what the renderer drew, on the colour camera's own pixels (the
default; every depth pixel on the true surface)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from agrisim.interfaces import DepthSensor, Frame, SensorGeometry
from agrisim.scene.camera import CameraModel


class ExactSensor(DepthSensor):
    """Measures the exact depth: ``depth/`` is its measurement, and nothing else is written."""

    def geometry(self, camera: CameraModel) -> SensorGeometry | None:
        return None

    def measure(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
        frame: Frame,
    ) -> np.ndarray | None:
        return None
