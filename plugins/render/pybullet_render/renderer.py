"""The pybullet renderer: scenes loaded into a TinyRenderer world and drawn through getCameraImage (see the package)."""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from PIL import Image

from agrisim.config import RenderConfig
from agrisim.interfaces import CameraModel, Frame, Renderer
from agrisim.plugins.native_output import native_output_silenced
from agrisim.plugins.render import robot_meshes
from agrisim.plugins.render.pybullet_render import PybulletRenderOptions
from agrisim.robot.cell import Cell
from agrisim.scene.model import Mesh, Scene
from agrisim.scene.transforms import quat_xyzw

with native_output_silenced():
    import pybullet as pb
    from pybullet_utils.bullet_client import BulletClient


#: triangles per pybullet visual shape (its mesh buffers are bounded)
CHUNK = 20000


def opengl_projection(camera: CameraModel, near: float, far: float) -> list[float]:
    """The OpenGL projection (column-major) equivalent to the OpenCV intrinsics ``camera``,
    principal point included (pixel centres at integer coordinates map to NDC pixel centres)."""
    W, H = camera.width, camera.height
    P = np.zeros((4, 4))
    P[0, 0] = 2 * camera.fx / W
    P[0, 2] = 1 - 2 * (camera.cx + 0.5) / W
    P[1, 1] = 2 * camera.fy / H
    P[1, 2] = 2 * (camera.cy + 0.5) / H - 1
    P[2, 2] = -(far + near) / (far - near)
    P[2, 3] = -2 * far * near / (far - near)
    P[3, 2] = -1
    return P.T.flatten().tolist()


def opengl_view(world_T_camera: np.ndarray) -> list[float]:
    """OpenGL view matrix (column-major) of an OpenCV ``world_T_camera``: y and z flip."""
    camera_T_world = np.linalg.inv(world_T_camera)
    return (np.diag([1.0, -1.0, -1.0, 1.0]) @ camera_T_world).T.flatten().tolist()


class PybulletRenderer(Renderer):
    """TinyRenderer in its own DIRECT pybullet world holding the scene and the arms' visuals."""

    def __init__(self, scene: Scene, cell: Cell, settings: RenderConfig, options: PybulletRenderOptions) -> None:
        super().__init__(scene, cell, settings, options)
        self._tmp = tempfile.TemporaryDirectory(prefix="agrisim-tinyrenderer-")
        with native_output_silenced():
            self.client = BulletClient(connection_mode=pb.DIRECT)
        self.plant_bodies: set[int] = set()
        for mesh in scene.meshes:
            bodies = self._add_mesh(mesh)
            if mesh.name == scene.plant:
                self.plant_bodies.update(bodies)
        self.arm_visuals: list[tuple[str, str, np.ndarray, int]] = []
        if not settings.hide_robots:
            for arm in cell.arms:
                for links in robot_meshes.link_visuals(arm.urdf).values():
                    for v in links:
                        if v.kind == "mesh" and v.filename:
                            with native_output_silenced():
                                shape = self.client.createVisualShape(
                                    pb.GEOM_MESH,
                                    fileName=v.filename,
                                    meshScale=list(v.scale),
                                    rgbaColor=list(v.rgba or (0.7, 0.7, 0.72, 1.0)),
                                )
                        elif v.kind == "box" and v.size:
                            shape = self.client.createVisualShape(
                                pb.GEOM_BOX, halfExtents=[s / 2 for s in v.size], rgbaColor=[0.15, 0.15, 0.15, 1]
                            )
                        else:
                            continue
                        body = self.client.createMultiBody(baseVisualShapeIndex=shape)
                        self.arm_visuals.append((arm.name, v.link, v.link_T_visual, body))
        self.light = self._light_direction()

    def _light_direction(self) -> list[float]:
        # TinyRenderer has one directional light: point it from the scene's lights on average.
        lights = self.scene.lights
        if not lights:
            return [0.0, 0.0, 1.0]
        d = -np.mean([np.asarray(light.direction, float) for light in lights], axis=0)
        n = np.linalg.norm(d)
        return (d / n).tolist() if n > 1e-9 else [0.0, 0.0, 1.0]

    def _texture(self, albedo: np.ndarray) -> int:
        path = Path(self._tmp.name) / f"tex{len(list(Path(self._tmp.name).iterdir()))}.png"
        Image.fromarray(np.ascontiguousarray(albedo[..., :3])).save(path)
        return self.client.loadTexture(str(path))

    def _add_mesh(self, mesh: Mesh) -> list[int]:
        bodies = []
        c = self.client
        for mi, material in enumerate(mesh.materials):
            faces = mesh.faces[mesh.face_material == mi]
            if not len(faces):
                continue
            if material.double_sided:  # TinyRenderer culls back faces
                faces = np.concatenate([faces, faces[:, ::-1]])
            texture = self._texture(material.albedo) if material.albedo is not None else None
            for start in range(0, len(faces), CHUNK):
                chunk = faces[start : start + CHUNK]
                used, inverse = np.unique(chunk, return_inverse=True)
                kwargs = {}
                if mesh.uvs is not None:
                    uv = mesh.uvs[used].astype(np.float64)
                    kwargs["uvs"] = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]]).tolist()  # OpenGL v is up
                shape = c.createVisualShape(
                    pb.GEOM_MESH,
                    vertices=mesh.vertices[used].tolist(),
                    indices=inverse.reshape(-1).astype(int).tolist(),
                    rgbaColor=[*material.color[:3], 1.0],
                    **kwargs,
                )
                if shape < 0:
                    raise RuntimeError(f"pybullet refused a visual shape of mesh {mesh.name!r}")
                body = c.createMultiBody(baseVisualShapeIndex=shape)
                if texture is not None:
                    c.changeVisualShape(body, -1, textureUniqueId=texture, rgbaColor=[1, 1, 1, 1])
                bodies.append(body)
        return bodies

    def render(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> Frame:
        c = self.client
        for robot, link, link_T_visual, body in self.arm_visuals:
            T = link_poses[robot][link] @ link_T_visual
            c.resetBasePositionAndOrientation(body, T[:3, 3].tolist(), quat_xyzw(T[:3, :3]))
        o = self.options
        shadow = 1 if self.options.shadows else 0
        _, _, rgba, zbuf, seg = c.getCameraImage(
            camera.width,
            camera.height,
            viewMatrix=opengl_view(world_T_camera),
            projectionMatrix=opengl_projection(camera, o.near, o.far),
            lightDirection=self.light,
            lightAmbientCoeff=o.ambient,
            lightDiffuseCoeff=o.diffuse,
            lightSpecularCoeff=0.0,
            shadow=shadow,  # sticky between calls: always pass it
            renderer=pb.ER_TINY_RENDERER,
        )
        shape = (camera.height, camera.width)
        rgb = np.asarray(rgba, np.uint8).reshape(*shape, 4)[..., :3].copy()
        z = np.asarray(zbuf, np.float64).reshape(shape)
        depth = (o.far * o.near / (o.far - (o.far - o.near) * z)).astype(np.float32)
        depth[z >= 1.0] = 0.0
        seg = np.asarray(seg, np.int64).reshape(shape)
        labels = np.isin(seg, list(self.plant_bodies)).astype(np.uint8)
        return Frame(rgb=rgb, labels=labels, depth=depth)

    def close(self) -> None:
        try:
            self.client.disconnect()
        except pb.error:
            pass
        self._tmp.cleanup()
