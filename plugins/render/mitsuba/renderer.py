"""The mitsuba renderer: path-traced RGB, exact labels and depth (see the package)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from agrisim.config import RenderConfig
from agrisim.interfaces import CameraModel, Frame, Renderer
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.arm_meshes import arm_link_meshes
from agrisim.plugins.render.raycast.tracing import SceneTracer
from agrisim.scene.camera import view_seed
from agrisim.scene.cell import Cell
from agrisim.scene.colour import encode_srgb8
from agrisim.scene.model import Scene

from .options import MitsubaOptions
from . import denoise
from .camera import sensor_dict
from .scene import build
from .variant import use_variant

F32 = np.float32


class MitsubaRenderer(Renderer):
    """Mitsuba 3 path tracing for RGB; labels, depth and leaf instances from the raycast
    renderer's exact pass (:class:`SceneTracer`), so they are byte for byte raycast's."""

    def __init__(self, scene: Scene, cell: Cell, settings: RenderConfig, options: MitsubaOptions) -> None:
        super().__init__(scene, cell, settings, options)
        self.mi = mi = use_variant(options.variant)
        organs = settings.labels == "organs"
        self.label_map = np.arange(256, dtype=np.uint8) if organs else (np.arange(256) > 0).astype(np.uint8)
        arms_cell = None if settings.hide_robots else cell
        self.tracer = SceneTracer(
            scene, arms_cell, RaycastOptions(near=options.near, arm_triangles=options.arm_triangles)
        )
        arms = {}
        if arms_cell is not None:
            for arm in arms_cell.arms:
                arms[arm.name] = [(lm.link, lm.mesh) for lm in arm_link_meshes(arm.urdf, options.arm_triangles)]
        integrator = {"type": options.integrator, "max_depth": int(options.max_depth)}
        self.denoise = denoise.wanted(options)
        if self.denoise:
            integrator = {"type": "aov", "aovs": denoise.AOVS, "integrator": integrator}
        parts = build(mi, scene.meshes, scene.lights, arms, options, integrator)
        self.arm_parts = parts.arms
        self.mi_scene = mi.load_dict(parts.scene)
        self.params = mi.traverse(self.mi_scene)
        self._arm_key: bytes | None = None

    def _place_arms(self, link_poses: Mapping[str, Mapping[str, np.ndarray]]) -> None:
        """Move the arms' vertices to ``link_poses`` (arms not named there vanish: their
        triangles collapse to a point, as raycast leaves them out)."""
        if not self.arm_parts:
            return
        poses = []
        for part in self.arm_parts:
            lp = link_poses.get(part.arm)
            if lp is not None and part.link not in lp:
                raise KeyError(f"link_poses[{part.arm!r}] has no pose for link {part.link!r}")
            poses.append(np.zeros((4, 4)) if lp is None else np.asarray(lp[part.link], np.float64))
        key = np.stack(poses).tobytes()
        if key == self._arm_key:
            return
        for part, T in zip(self.arm_parts, poses):
            v = part.vertices @ T[:3, :3].T + T[:3, 3]
            self.params[part.key] = self.mi.Float(np.ascontiguousarray(v, F32).ravel())
        self.params.update()
        self._arm_key = key

    def radiance(self, camera: CameraModel, world_T_camera: np.ndarray) -> np.ndarray:
        """Linear RGB radiance, H x W x 3 float32, of one view (arms where last placed)."""
        mi, o = self.mi, self.options
        sensor = sensor_dict(camera, world_T_camera, o.spp)
        sensor["to_world"] = mi.ScalarTransform4f(sensor["to_world"])
        seed = view_seed(camera, world_T_camera, o.seed) & 0xFFFFFFFF
        image = np.asarray(mi.render(self.mi_scene, sensor=mi.load_dict(sensor), spp=o.spp, seed=seed), F32)
        return denoise.denoise(image) if self.denoise else image[..., :3]

    def render(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> Frame:
        H, W = camera.height, camera.width
        if self.tracer.arms:
            self.tracer.place_arms(link_poses)
        self._place_arms(link_poses)
        exact = self.tracer.exact(camera, world_T_camera, seg_mode=self.settings.seg_mode, label_map=self.label_map)
        linear = np.ascontiguousarray(self.radiance(camera, world_T_camera)).reshape(-1, 3)
        rgb = np.empty((H * W, 3), np.uint8)
        encode_srgb8(linear, rgb, self.options.exposure, self.options.tonemap)
        return Frame(
            rgb=rgb.reshape(H, W, 3),
            labels=exact["labels"],
            depth=exact["depth"],
            instances=exact.get("instances"),
        )

    def close(self) -> None:
        self.tracer.close()
        self.params = None
        self.mi_scene = None
