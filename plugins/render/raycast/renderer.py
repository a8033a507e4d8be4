"""The raycast renderer: pixel rays, shading of the traced surfaces with soft shadows, tone
mapping, tiles on threads (tracing is :mod:`.tracing`; see the package)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from agrisim.config import RenderConfig
from agrisim.interfaces import CameraModel, Frame, Renderer
from agrisim.plugins.render.raycast import RaycastOptions, kernels
from agrisim.plugins.render.raycast.arm_meshes import arm_link_meshes
from agrisim.plugins.render.raycast.lights import LightTable, chunks
from agrisim.plugins.render.raycast.tracing import Hits, SceneTracer, camera_rays, label_map, pixel_slopes
from agrisim.scene.cell import Cell
from agrisim.scene.camera import view_seed
from agrisim.scene.colour import ENCODE_STEPS, LINEAR_TO_SRGB8, srgb_to_linear
from agrisim.scene.model import Mesh, Scene

F32 = np.float32



class RaycastRenderer(Renderer):
    """Embree ray casting through Open3D: exact depth and labels, alpha-tested cards, soft shadows."""

    def __init__(self, scene: Scene, cell: Cell, settings: RenderConfig, options: RaycastOptions) -> None:
        super().__init__(scene, cell, settings, options)
        self.seg_mode = settings.seg_mode
        self.shadow_samples = self.options.shadow_samples
        self.supersample = self.options.supersample
        self.hide_robots = settings.hide_robots
        self.label_map = label_map(settings.labels)
        self.tracer = SceneTracer(scene, None if self.hide_robots else cell, options)
        self.lights = LightTable(scene.lights)
        if self.tracer.points is not None:  # linear albedo of every point, for shading
            self.point_albedo = srgb_to_linear(self.tracer.points.points.colors / 255.0).astype(F32)

    # -------------------------------------------------------------------------- shading
    def _shade(self, rays: np.ndarray, hits: Hits, rng: np.random.Generator, samples: int) -> np.ndarray:
        """Linear radiance (K x 3) of the kept surfaces (0 where nothing was hit)."""
        k = len(rays)
        sel = np.flatnonzero(hits.hit)
        if not len(sel):
            return np.zeros((k, 3), F32)
        every = len(sel) == k
        pick = (lambda a: a) if every else (lambda a: np.take(a, sel, axis=0))  # noqa: E731 - no copy if all hit
        face, t, mat, uv, rays = pick(hits.face), pick(hits.t), pick(hits.mat), pick(hits.uv), pick(rays)
        point = pick(hits.point) if hits.point is not None else None
        m = len(face)
        lights = self.lights
        bilinear = self.options.texture_filter == "bilinear"
        eps = F32(self.options.epsilon)
        albedo = np.empty((m, 3), F32)
        w = np.empty((lights.n, m), F32)  # unshadowed irradiance of each light
        origins = np.empty((3, m), F32) if samples > 0 and lights.n else None  # of shadow rays
        # Per-point work in chunks of some thousand points, whose scratch arrays stay in cache.
        # Points and normals as rows (3 x chunk): the layout LightTable works in.
        for c in chunks(m):
            self.tracer.mats.albedo(uv[c], mat[c], bilinear, out=albedo[c])
            on_point = np.flatnonzero(point[c] >= 0) if point is not None else ()
            if len(on_point):  # spheres: the point's own colour
                albedo[c][on_point] = self.point_albedo[point[c][on_point]]
            if not lights.n:
                continue
            p, n = np.empty((3, c.stop - c.start), F32), np.empty((3, c.stop - c.start), F32)
            kernels.surface_frames(rays[c], t[c], face[c], self.tracer.face_normal, p, n)  # n: the side seen
            if len(on_point):  # a sphere's normal at the hit (its outside: the side seen)
                n[:, on_point] = self.tracer.points.normals(point[c][on_point], p[:, on_point])
            # shadow rays start off the surface, towards the side seen
            lights.weights(p, n, out=w[:, c], origins=origins[:, c] if origins is not None else None, eps=eps)
        irradiance = lights.irradiance(w, origins, samples, rng, self.tracer.occluded, self.options.adaptive_after)
        irradiance += F32(self.options.ambient)
        for c in range(3):  # channel by channel: irradiance comes as rows
            albedo[:, c] *= irradiance[c]
        if every:
            return albedo
        out = np.zeros((k, 3), F32)
        out[sel] = albedo
        return out

    # --------------------------------------------------------------------------- render
    def _tile(
        self, T: np.ndarray, x: np.ndarray, y: np.ndarray, camera: CameraModel, rng: np.random.Generator, out: dict
    ) -> None:
        """Render the pixels of columns ``x`` and rows ``y`` (camera-frame slopes) into ``out``."""
        rays = camera_rays(x, y, T, self.options.near)
        hits = self.tracer.trace(rays, raw=self.seg_mode == "repopa")
        hit = hits.hit
        self.tracer.annotate(hits, self.seg_mode == "repopa", self.label_map, out)
        s, n = self.supersample, self.shadow_samples
        if s == 1:
            linear = self._shade(rays, hits, rng, n)
        else:
            linear = np.zeros((len(rays), 3), F32)
            count = np.zeros(len(rays), np.int32)
            n_sub = math.ceil(n / (s * s)) if n > 0 else 0
            for i in range(s):
                for j in range(s):
                    du, dv = ((j + 0.5) / s - 0.5) / camera.fx, ((i + 0.5) / s - 0.5) / camera.fy
                    sub = camera_rays(x + du, y + dv, T, self.options.near)
                    sub_hits = self.tracer.trace(sub, raw=False)
                    linear += self._shade(sub, sub_hits, rng, n_sub)
                    count += sub_hits.hit
            hit = count > 0
            linear *= F32(1.0 / (s * s))
        kernels.encode_srgb8(
            linear, out["rgb"], F32(self.options.exposure), self.options.tonemap == "reinhard", F32(ENCODE_STEPS), LINEAR_TO_SRGB8
        )
        if not hit.all():
            out["rgb"][~hit] = np.asarray(self.options.background, np.uint8)

    def render(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> Frame:
        H, W = camera.height, camera.width
        if self.tracer.arms:
            self.tracer.place_arms(link_poses)
        T = np.asarray(world_T_camera, np.float64)
        x, y = pixel_slopes(camera)
        n_pix = H * W
        images = {
            "rgb": np.empty((n_pix, 3), np.uint8),
            "labels": np.zeros(n_pix, np.uint8),
            "depth": np.empty(n_pix, F32),
        }
        if self.tracer.has_instances:
            images["instances"] = np.zeros(n_pix, np.uint16)
        # Tiles of whole rows; each has its own random stream spawned from the view's seed, so
        # results do not depend on the order (or thread) tiles run in.
        rows = max(1, self.options.tile_pixels // W)
        starts = list(range(0, H, rows))
        streams = np.random.SeedSequence(view_seed(camera, T, self.options.seed)).spawn(len(starts))

        def run(i: int) -> None:
            r0, r1 = starts[i], min(starts[i] + rows, H)
            views = {k: v[r0 * W : r1 * W] for k, v in images.items()}
            self._tile(T, x, y[r0:r1], camera, np.random.default_rng(streams[i]), views)

        workers = self.options.workers or (os.cpu_count() or 1)
        if workers > 1 and len(starts) > 1:
            with ThreadPoolExecutor(min(workers, len(starts))) as pool:
                list(pool.map(run, range(len(starts))))
        else:
            for i in range(len(starts)):
                run(i)
        return Frame(
            rgb=images["rgb"].reshape(H, W, 3),
            labels=images["labels"].reshape(H, W),
            depth=images["depth"].reshape(H, W),
            instances=images["instances"].reshape(H, W) if "instances" in images else None,
        )

    def arm_meshes(self) -> dict[str, list[tuple[str, Mesh]]]:
        if self.hide_robots:
            return {}
        return {arm.name: [(lm.link, lm.mesh) for lm in arm_link_meshes(arm.urdf, self.options.arm_triangles)] for arm in self.cell.arms}

    def close(self) -> None:
        self.tracer.close()
