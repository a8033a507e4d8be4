"""The exact pass: pixel rays traced on Dr.Jit (:mod:`.engine`: Mitsuba's Embree on the CPU,
OptiX on NVIDIA GPUs), and from the surfaces they keep the labels, leaf instances and depth of a
view, in the same kernels."""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from functools import lru_cache
from typing import Any

import drjit as dr
import numpy as np

from agrisim.errors import ConfigError
from agrisim.plugins.render.arm_visuals import arm_link_meshes
from agrisim.plugins.render.raycast import RaycastOptions, culling
from agrisim.plugins.render.raycast.engine import Engine, Surface
from agrisim.plugins.render.raycast.lights import SHADOW_TFAR, LightTable
from agrisim.plugins.render.raycast.points import PointTracer
from agrisim.robot.cell import Cell
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import Mesh, Scene

F32 = np.float32


def label_map(labels: str) -> np.ndarray:
    """Label id -> the id written (uint8, 256): every id as it is for ``labels="organs"``, else
    every non-zero id to 1 (the plant)."""
    ids = np.arange(256)
    return ids.astype(np.uint8) if labels == "organs" else (ids > 0).astype(np.uint8)


@lru_cache(maxsize=8)
def _slopes(width: int, height: int, fx: float, fy: float, cx: float, cy: float) -> tuple[np.ndarray, np.ndarray]:
    x = (np.arange(width, dtype=np.float64) - cx) / fx
    y = (np.arange(height, dtype=np.float64) - cy) / fy
    x.flags.writeable = y.flags.writeable = False  # shared by every caller of the cache
    return x, y


def pixel_slopes(camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame ray slopes of a pinhole's pixel centres: x of each column, y of each row
    (``K^-1 [u, v, 1] = (x[u], y[v], 1)``)."""
    if not camera.pinhole:
        raise ValueError("pixel_slopes: a lens's rays are not separable (CameraModel.rays gives them)")
    return _slopes(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy)


class SceneTracer:
    """The scene, the posed arms and a point plant traced exactly: the first surface along each
    ray that opacity and back-face culling keep, and from it labels, leaf instances and depth.
    Renderers share it (one exact pass); shading is theirs.

    The arms are ``arms`` (robot -> (link, mesh in the link frame)) when given, else the visual
    meshes of ``cell``'s URDFs; neither: no arms (``--hide-robots``). Dr.Jit runs on the
    variant ``options.variant`` names (``auto``: an NVIDIA GPU when one is usable).
    """

    def __init__(
        self,
        scene: Scene,
        cell: Cell | None,
        options: RaycastOptions,
        arms: Mapping[str, list[tuple[str, Mesh]]] | None = None,
        *,
        apart: bool = False,
    ) -> None:
        from agrisim.plugins.render.mitsuba.variant import GeometryVariant, use_variant

        self.options = options
        self.mi = mi = use_variant(options.variant, "raycast")
        if arms is None and cell is not None:
            arms = {
                a.name: [(lm.link, lm.mesh) for lm in arm_link_meshes(a.urdf, options.arm_triangles)] for a in cell.arms
            }
        geometry = GeometryVariant(mi) if apart else None
        if geometry is not None:
            self.mi = mi = geometry
        with geometry.building() if geometry is not None else contextlib.nullcontext():
            self.engine = Engine(mi, scene, arms or {}, max_layers=options.max_layers, epsilon=options.epsilon)
            self.points: PointTracer | None = None
            if scene.points is not None and len(scene.points):
                if self.engine.combined:
                    raise ConfigError(
                        "point plants are traced on the CPU only (OptiX traces one scene per kernel, and the spheres "
                        "are a scene of their own); set variant = 'llvm' for this renderer"
                    )
                self.points = PointTracer(scene.points, mi)
        self.has_instances = self.engine.has_instances or (
            self.points is not None and self.points.instances is not None
        )
        self._label_maps: dict[bytes, Any] = {}
        # what culling arm links needs: the box of the static scene, the lights' points
        static = [m.vertices for m in scene.meshes if len(m.faces)]
        if self.points is not None:
            r = float(scene.points.size or 0.0)  # (a diameter: half of it would do)
            static += [scene.points.positions - r, scene.points.positions + r]
        self._bounds = culling.box_corners(np.concatenate(static)) if static else np.zeros((0, 3))
        self._light_points = LightTable(list(scene.lights)).targets.astype(np.float64)

    @property
    def arms(self) -> bool:
        """Does the scene hold arms to pose?"""
        return bool(self.engine.links)

    def place_arms(
        self,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
        view: tuple[CameraModel, np.ndarray] | None = None,
    ) -> None:
        """Pose the arms named in ``link_poses``; the others are left out. With ``view``
        (camera, world_T_camera), the links that no ray of that view can meet (its pixel rays,
        their shadow rays) are not built nor cast (:mod:`.culling`): the images are the same,
        for rays of that view only."""
        e = self.engine
        if view is None or not e.links or e.combined:  # (OptiX casts every link: one scene per kernel)
            e.place_arms(link_poses)
            return
        camera, T = view
        poses = e.link_poses(link_poses)
        boxes = [
            None if P is None else link.corners @ P[:3, :3].T + P[:3, 3] for link, P in zip(e.links, poses, strict=True)
        ]
        # the frustum reaches as deep as anything a pixel ray can meet
        points = np.concatenate([self._bounds, *(b for b in boxes if b is not None)])
        depth = (points - np.asarray(T, np.float64)[:3, 3]) @ np.asarray(T, np.float64)[:3, 2]
        far = max(float(depth.max()), self.options.near) + culling.TOLERANCE
        frustum = culling.frustum_corners(camera, T, self.options.near, far)
        in_view, lit = culling.hull_planes(frustum), culling.hull_planes(np.concatenate([frustum, self._light_points]))
        seen = np.array([b is not None and not culling.outside(b, in_view) for b in boxes])
        # shadow rays leave their surface from a point moved off it by epsilon
        margin = 2 * self.options.epsilon + culling.TOLERANCE
        shading = np.array([b is not None and not culling.outside(b, lit, margin) for b in boxes])
        e.place_arms(link_poses, seen, shading)

    # --------------------------------------------------------------------- rays
    def camera_rays(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        rows: tuple[int, int] | None = None,
        offset: tuple[float, float] = (0.0, 0.0),
    ) -> tuple[Any, Any]:
        """(origins, directions) of the rays through the pixel centres (moved by ``offset``
        pixels) of ``rows`` (first, end; all by default), row-major: from the near plane, with
        directions of unit camera z, so a hit's t is its planar depth less ``near``."""
        mi = self.mi
        if not camera.pinhole:
            return self._lens_rays(camera, world_T_camera, rows or (0, camera.height), offset)
        x, y = pixel_slopes(camera)
        r0, r1 = rows or (0, camera.height)
        y = y[r0:r1]
        if offset != (0.0, 0.0):
            x, y = x + offset[0] / camera.fx, y + offset[1] / camera.fy
        T = np.asarray(world_T_camera, np.float64)
        R, c = T[:3, :3], T[:3, 3]
        # direction j of pixel (u, v) = X_j[u] + Y_j[v], each term rounded to float32 first
        X = np.concatenate([(x * R[j, 0]).astype(F32) for j in range(3)])
        Y = np.concatenate([(y * R[j, 1] + R[j, 2]).astype(F32) for j in range(3)])
        W, H = len(x), len(y)
        k = dr.arange(mi.UInt32, W * H)
        wide, high = dr.opaque(mi.UInt32, W), dr.opaque(mi.UInt32, H)  # opaque: one kernel for every image size
        v = k // wide
        u = k - v * wide
        Xd, Yd = mi.Float(X), mi.Float(Y)
        d = mi.Vector3f(
            *(dr.gather(mi.Float, Xd, u + j * wide) + dr.gather(mi.Float, Yd, v + j * high) for j in range(3))
        )
        near = dr.opaque(mi.Float, self.options.near)
        o = mi.Point3f(*(d[j] * near + dr.opaque(mi.Float, c[j]) for j in range(3)))
        return o, d

    def _lens_rays(
        self, camera: CameraModel, world_T_camera: np.ndarray, rows: tuple[int, int], offset: tuple[float, float]
    ) -> tuple[Any, Any]:
        """:meth:`camera_rays` through a lens: each pixel's slopes from the lens's inverse, solved
        in the kernel in double precision (any sub-pixel offset costs nothing on the host)."""
        mi = self.mi
        F64 = dr.float64_array_t(mi.Float)
        k = dr.arange(mi.UInt32, camera.width * (rows[1] - rows[0]))
        wide = dr.opaque(mi.UInt32, camera.width)
        v = k // wide
        u = k - v * wide
        x, y = camera.rays(
            F64(u) + dr.opaque(F64, offset[0]), F64(v) + dr.opaque(F64, rows[0] + offset[1])
        )  # opaque: one kernel for every batch and offset
        T = np.asarray(world_T_camera, np.float64)
        R, c = T[:3, :3], T[:3, 3]
        # opaque: one kernel for every pose (as literals each view's rotation compiled its own)
        r = [[dr.opaque(F64, float(R[j, i])) for i in range(3)] for j in range(3)]
        d = mi.Vector3f(*(mi.Float(x * r[j][0] + y * r[j][1] + r[j][2]) for j in range(3)))
        near = dr.opaque(mi.Float, self.options.near)
        o = mi.Point3f(*(d[j] * near + dr.opaque(mi.Float, c[j]) for j in range(3)))
        return o, d

    # ------------------------------------------------------------------ tracing
    def trace(self, o: Any, d: Any, raw: bool = False) -> Surface:
        """The surface each ray keeps (see :meth:`Engine.trace`); a point plant's spheres
        (opaque) win where they are nearer."""
        s = self.engine.trace(o, d, raw)
        if self.points is None:
            return s
        mi = self.mi
        t, index = self.points.cast_dr(o, d)
        nearer = t < s.t
        if raw:
            first = t < s.raw_t
            s.raw_point = dr.select(first, index, -1)
            s.raw_face = dr.select(first, -1, s.raw_face)
        s.t = dr.select(nearer, t, s.t)
        s.face = dr.select(nearer, -1, s.face)
        s.point = dr.select(nearer, index, mi.Int32(-1))
        return s

    def occluded(self, o: Any, seg: Any, active: Any = True) -> Any:
        """Bool: is each shadow ray (origin, segment to the light) blocked before
        ``SHADOW_TFAR`` of its segment? Cut-out texels let light through."""
        blocked = self.engine.occluded(o, seg, active)
        if self.points is not None:
            blocked |= self.points.occluded_dr(o, seg, SHADOW_TFAR, active & ~blocked)
        return blocked

    # ------------------------------------------------------------- annotations
    def _label_map(self, table: np.ndarray) -> Any:
        key = table.tobytes()
        if key not in self._label_maps:
            self._label_maps[key] = self.mi.UInt32(table.astype(np.uint32))
        return self._label_maps[key]

    def annotate(self, s: Surface, repopa: bool, table: np.ndarray) -> tuple[Any, Any, Any]:
        """(labels, depth, instances) of the surfaces ``s`` (Dr.Jit: UInt32 with ``table``
        applied, Float planar depth in m, 0 where nothing is hit; UInt32 leaf instances, None
        when the scene numbers none): from the kept surfaces, or with ``repopa`` from the first
        surface of any opacity (the trace must have been ``raw``)."""
        mi, e = self.mi, self.engine
        depth = dr.select(s.hit, s.t + self.options.near, 0.0)
        face = s.raw_face if repopa else s.face
        b = s.raw_b if repopa else s.b
        p0, p1 = e.plant_faces
        on_plant = (face >= p0) & (face < p1)
        mat = e.material(face, on_plant)
        uv = e.uv(face, b, on_plant)
        lab = e.m.label(uv, mat, on_plant)
        if repopa:  # the whole card is plant: unlabelled cut-out texels take the material's organ
            cut = on_plant & (lab == 0) & ~e.m.opaque(uv, mat, on_plant)
            lab = dr.select(cut, dr.gather(mi.UInt32, e.m.fallback, mat, cut), lab)
        lmap = self._label_map(table)
        labels = dr.select(on_plant, dr.gather(mi.UInt32, lmap, lab, on_plant), 0)
        instances = None
        if self.has_instances:
            inst = dr.gather(mi.UInt32, e.face_inst, mi.UInt32(dr.maximum(face, 0)), on_plant)
            instances = dr.select(on_plant & (lab > 0), inst, 0)
        point = s.raw_point if repopa else s.point
        if point is not None:
            pts = self.points
            on = point >= 0
            lab_p = dr.gather(mi.UInt32, pts.labels, mi.UInt32(dr.maximum(point, 0)), on)
            labels = dr.select(on, dr.gather(mi.UInt32, lmap, lab_p, on), labels)
            if instances is not None:
                inst_p = (
                    0
                    if pts.instances is None
                    else dr.gather(mi.UInt32, pts.instances, mi.UInt32(dr.maximum(point, 0)), on)
                )
                instances = dr.select(on, dr.select(lab_p > 0, inst_p, 0), instances)
        return labels, depth, instances

    def exact(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        *,
        seg_mode: str,
        label_map: np.ndarray,
        pixels_per_batch: int = 1 << 23,
    ) -> dict[str, np.ndarray]:
        """The exact images of one view, for renderers that shade by other means: ``labels``,
        ``depth`` (planar, m; 0 where nothing is hit) and ``instances`` (when the plant numbers
        its leaves) and ``plants`` (a bench's) from rays through the pixel centres, what the raycast renderer gives (the
        same rays, traced by the same code). Place the arms first."""
        H, W = camera.height, camera.width
        parts: dict[str, list[np.ndarray]] = {"labels": [], "depth": [], "instances": [], "plants": []}
        UInt8 = dr.uint8_array_t(self.mi.Float)
        rows = max(1, pixels_per_batch // W)
        for r0 in range(0, H, rows):  # bounded memory at any resolution
            r1 = min(r0 + rows, H)
            o, d = self.camera_rays(camera, world_T_camera, (r0, r1))
            s = self.trace(o, d, raw=seg_mode == "repopa")
            labels, depth, instances = self.annotate(s, seg_mode == "repopa", label_map)
            labels = UInt8(labels)  # (the host only copies)
            dr.eval(labels, depth, instances)
            parts["labels"].append(np.asarray(labels).reshape(r1 - r0, W))
            parts["depth"].append(np.asarray(depth).reshape(r1 - r0, W))
            if instances is not None:
                self.add_ids(np.asarray(instances).reshape(r1 - r0, W), parts)
        return {k: v[0] if len(v) == 1 else np.concatenate(v) for k, v in parts.items() if v}

    def add_ids(self, ids: np.ndarray, parts: dict[str, list[np.ndarray]]) -> None:
        """Append a batch of :meth:`annotate`'s instance ids to ``parts``: the leaf instances,
        and a bench's plants (the ids' high 16 bits, :class:`.engine.SceneEngine`)."""
        if self.engine.has_plants:
            parts["plants"].append((ids >> 16).astype(np.uint16))
        if self.engine.leaf_instances:
            parts["instances"].append((ids & 0xFFFF).astype(np.uint16))

    def close(self) -> None:
        """Drop the Mitsuba scenes."""
        self.engine = None  # type: ignore[assignment]
        self.points = None
