"""What the sensors that cast their own rays share: the scene traced exactly as the renderer
traces it (:class:`~agrisim.plugins.render.raycast.tracing.SceneTracer`, on the process's
Dr.Jit variant), the materials' near-infrared reflectance as a Dr.Jit table, and a view's
measurement: the device's own image, moved onto the colour camera's pixels (:mod:`.align`)."""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping
from typing import Any

import numpy as np

from agrisim.config import RenderConfig
from agrisim.interfaces import DepthSensor, Frame, SensorGeometry
from agrisim.plugins.sensors.nir import nir_reflectance
from agrisim.robot.cell import Cell
from agrisim.scene.camera import CameraModel, view_seed
from agrisim.scene.model import Scene


class TracedSensor(DepthSensor):
    """A depth sensor whose imager (``camera``, at ``camera_T_sensor`` in the colour camera's
    frame: set by the subclass) sees the scene through rays it casts itself."""

    camera: CameraModel
    camera_T_sensor: np.ndarray

    def __init__(self, scene: Scene, cell: Cell | None, settings: RenderConfig, options: Any) -> None:
        super().__init__(scene, cell, settings, options)
        from agrisim.plugins.render.raycast import RaycastOptions
        from agrisim.plugins.render.raycast.tracing import SceneTracer
        from agrisim.plugins.sensors.variant import sensor_variant

        arms = None if settings.hide_robots or not scene.arms else scene.arms
        self.tracer = SceneTracer(
            scene,
            None if settings.hide_robots else cell,
            RaycastOptions(variant=sensor_variant(options.variant)),
            arms=arms,
        )
        mi = self.tracer.mi
        self._nir = mi.Float(np.array([nir_reflectance(m) for m in self.tracer.engine.mats.materials], np.float32))

    def geometry(self, camera: CameraModel) -> SensorGeometry:
        return SensorGeometry(self.camera, self.camera_T_sensor)

    @abstractmethod
    def measure_native(
        self, world_T_camera: np.ndarray, link_poses: Mapping[str, Mapping[str, np.ndarray]], seed: int
    ) -> np.ndarray:
        """The device's own depth image (float32 planar metres on ``camera``, 0 = none) with the
        colour camera at ``world_T_camera``; ``seed`` seeds its noise."""

    def measure(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
        frame: Frame,
    ) -> np.ndarray:
        from agrisim.plugins.sensors.align import align_to_colour

        seed = view_seed(camera, np.asarray(world_T_camera, np.float64), self.options.seed)
        native = self.measure_native(world_T_camera, link_poses, seed)
        return align_to_colour(native, self.camera, camera, self.camera_T_sensor)

    def close(self) -> None:
        self.tracer.close()
