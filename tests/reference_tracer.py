"""A second, independent exact pass for the agreement tests: Open3D's Embree (the engine
agrisim's renderers cast with before Dr.Jit) finds the hits, a plain numpy loop walks past
cut-out texels and culled back faces, and the core's texturing functions name the texels.

It shares nothing with ``agrisim.plugins.render.raycast`` but the scene model and
:mod:`agrisim.scene.texturing`, and it is written for clarity, not speed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from agrisim.scene import texturing
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import Material, Mesh, Scene


@dataclass
class Trace:
    """Per ray: the kept surface (mesh index, face, barycentrics, t) and, for repopa, the first
    surface of any opacity that culling keeps; -1 / inf where there is none."""

    t: np.ndarray
    mesh: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    raw_mesh: np.ndarray
    raw_face: np.ndarray
    raw_bary: np.ndarray


def _fallback(material: Material) -> int:
    """Repopa's label of an unlabelled cut-out texel: the label texture's most common non-zero id."""
    if material.labels is None:
        return int(material.label)
    counts = np.bincount(material.labels.ravel(), minlength=256)
    counts[0] = 0
    return int(counts.argmax()) if counts.any() else int(material.label)


class ReferenceTracer:
    """The static meshes of ``scene`` and ``extra`` meshes (posed arms, in the world frame)."""

    def __init__(self, scene: Scene, extra: list[Mesh] = ()) -> None:
        self.meshes = [m for m in scene.meshes if len(m.faces)] + [m for m in extra if len(m.faces)]
        self.plant = next((i for i, m in enumerate(self.meshes) if m.name == scene.plant), -1)
        self.scene = o3d.t.geometry.RaycastingScene()
        self.geometry = {}
        for i, m in enumerate(self.meshes):
            gid = self.scene.add_triangles(
                o3d.core.Tensor(m.vertices.astype(np.float32)), o3d.core.Tensor(m.faces.astype(np.uint32))
            )
            self.geometry[int(gid)] = i
        self.normals = []
        for m in self.meshes:
            a, b, c = (m.vertices[m.faces[:, k]] for k in range(3))
            n = np.cross(b - a, c - a)
            self.normals.append(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30))

    def _cast(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        r = self.scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))
        g = r["geometry_ids"].numpy()
        mesh = np.array([self.geometry.get(int(x), -1) for x in g]) if len(g) else np.zeros(0, int)
        return r["t_hit"].numpy(), mesh, r["primitive_ids"].numpy().astype(np.int64), r["primitive_uvs"].numpy()

    def _surface(self, mesh: int, face: np.ndarray, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(material index in the mesh, uv) of hits on ``mesh``."""
        m = self.meshes[mesh]
        uv = texturing.interpolate_uv(m, face, bary) if m.uvs is not None else np.zeros((len(face), 2))
        return m.face_material[face], uv

    def trace(self, rays: np.ndarray, max_layers: int = 16, eps: float = 1e-4) -> Trace:
        """Walk each ray (K x 6) past cut-out texels and culled back faces."""
        k = len(rays)
        out = Trace(
            np.full(k, np.inf),
            np.full(k, -1),
            np.full(k, -1),
            np.zeros((k, 2)),
            np.full(k, -1),
            np.full(k, -1),
            np.zeros((k, 2)),
        )
        o, d = rays[:, :3].astype(np.float64), rays[:, 3:].astype(np.float64)
        t_acc = np.zeros(k)
        todo = np.arange(k)
        for _ in range(max_layers):
            if not len(todo):
                break
            t, mesh, face, bary = self._cast(np.hstack([o[todo] + d[todo] * t_acc[todo, None], d[todo]]))
            passes = np.zeros(len(todo), bool)
            culled = np.zeros(len(todo), bool)
            for i in np.unique(mesh[mesh >= 0]):
                sel = np.flatnonzero(mesh == i)
                index, uv = self._surface(i, face[sel], bary[sel])
                for k in np.unique(index):
                    mat, these = self.meshes[i].materials[k], sel[index == k]
                    cut = ~texturing.opaque(mat, uv[index == k])
                    back = np.zeros(len(these), bool)
                    if not mat.double_sided:
                        back = np.einsum("ij,ij->i", self.normals[i][face[these]], d[todo[these]]) > 0
                    culled[these] = back
                    passes[these] = cut | back
            hit = mesh >= 0
            first = hit & ~culled & (out.raw_mesh[todo] < 0)
            out.raw_mesh[todo[first]], out.raw_face[todo[first]], out.raw_bary[todo[first]] = (
                mesh[first],
                face[first],
                bary[first],
            )
            stop = hit & ~passes
            j = todo[stop]
            out.t[j], out.mesh[j], out.face[j], out.bary[j] = t_acc[j] + t[stop], mesh[stop], face[stop], bary[stop]
            go = hit & passes
            todo_go = todo[go]
            t_acc[todo_go] += t[go] + eps / np.linalg.norm(d[todo_go], axis=1)
            todo = todo_go
        return out

    def pixels(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        u: np.ndarray,
        v: np.ndarray,
        seg_mode: str,
        near: float = 1e-3,
    ) -> dict[str, np.ndarray]:
        """Labels (organ ids), planar depth (0: miss) and leaf instances seen through image points
        (``u``, ``v``: pixel coordinates, centres at integers) by rays from the near plane."""
        d_cam = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones(np.shape(u))], -1).reshape(
            -1, 3
        )
        T = np.asarray(world_T_camera, np.float64)
        d = d_cam @ T[:3, :3].T
        tr = self.trace(np.hstack([T[:3, 3] + near * d, d]))
        depth = np.where(tr.mesh >= 0, tr.t + near, 0.0)
        repopa = seg_mode == "repopa"
        mesh, face, bary = (tr.raw_mesh, tr.raw_face, tr.raw_bary) if repopa else (tr.mesh, tr.face, tr.bary)
        labels = np.zeros(len(d), np.uint8)
        instances = np.zeros(len(d), np.uint16)
        on = np.flatnonzero(mesh == self.plant)
        if len(on):
            plant = self.meshes[self.plant]
            index, uv = self._surface(self.plant, face[on], bary[on])
            for k in np.unique(index):
                mat, these = plant.materials[k], on[index == k]
                lab = texturing.label_at(mat, uv[index == k])
                if repopa:  # the whole card is plant: unlabelled cut-out texels take the organ
                    lab = np.where((lab == 0) & ~texturing.opaque(mat, uv[index == k]), _fallback(mat), lab)
                labels[these] = lab
                if plant.face_instance is not None:
                    instances[these] = np.where(lab > 0, plant.face_instance[face[these]], 0)
        return {"labels": labels, "depth": depth.astype(np.float32), "instances": instances}

    def exact(
        self, camera: CameraModel, world_T_camera: np.ndarray, seg_mode: str, near: float = 1e-3
    ) -> dict[str, np.ndarray]:
        """:meth:`pixels` of every pixel centre, as images."""
        u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
        out = self.pixels(camera, world_T_camera, u.ravel(), v.ravel(), seg_mode, near)
        return {k: a.reshape(camera.height, camera.width) for k, a in out.items()}
