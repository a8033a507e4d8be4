"""The raycast renderer: a view is the exact pass (:mod:`.tracing`) and its shading
(:mod:`.shading`) on the same Dr.Jit arrays, evaluated together: a few kernels, on the CPU or
the GPU (see the package)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import drjit as dr
import numpy as np

from agrisim.config import RenderConfig
from agrisim.interfaces import CameraModel, Frame, Renderer
from agrisim.plugins.render.arm_visuals import arm_link_meshes
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.lights import LightTable
from agrisim.plugins.render.raycast.shading import Shader
from agrisim.plugins.render.raycast.tracing import SceneTracer, label_map
from agrisim.robot.cell import Cell
from agrisim.scene.camera import view_seed
from agrisim.scene.colour import srgb_to_linear
from agrisim.scene.model import Mesh, Scene

F32 = np.float32


class RaycastRenderer(Renderer):
    """Exact ray tracing on Dr.Jit (Embree on the CPU, OptiX on NVIDIA GPUs): exact depth and
    labels, alpha-tested cards, soft shadows."""

    def __init__(self, scene: Scene, cell: Cell, settings: RenderConfig, options: RaycastOptions) -> None:
        super().__init__(scene, cell, settings, options)
        self.seg_mode = settings.seg_mode
        self.hide_robots = settings.hide_robots
        self.label_map = label_map(settings.labels)
        # The arms: none with --hide-robots; a saved run's own (agrisim render); else the cell's.
        arms = None if self.hide_robots or not scene.arms else scene.arms
        self.tracer = SceneTracer(scene, None if self.hide_robots else cell, options, arms=arms)
        self.lights = LightTable(scene.lights)
        o = self.options
        self.shader = Shader(
            self.tracer, self.lights, ambient=o.ambient, bilinear=o.texture_filter == "bilinear", epsilon=o.epsilon
        )
        self.background = [int(c) for c in o.background]
        # the radiance that the background's sRGB encodes to at the run's exposure
        self.background_radiance = self.tracer.mi.Color3f(
            *(float(c) for c in srgb_to_linear(np.asarray(o.background) / 255.0) / o.exposure)
        )

    def _rgb(self, camera: CameraModel, T: np.ndarray, rows: tuple[int, int], o, d, s, seed: int):  # noqa: ANN001, ANN202
        """(UInt32 8-bit sRGB of the pixels of ``rows`` (r | g << 8 | b << 16), whose centre rays
        (``o``, ``d``) kept the surfaces ``s``; their Color3f linear radiance and whether each hit)."""
        mi, opts = self.tracer.mi, self.options
        n_pix = camera.width * (rows[1] - rows[0])
        pixel = dr.arange(mi.UInt32, n_pix) + dr.opaque(mi.UInt32, rows[0] * camera.width)
        state = dr.opaque(mi.UInt64, seed)
        ss, n = opts.supersample, opts.shadow_samples

        def stream(sequence):  # noqa: ANN001, ANN202 - seeded by the pixel's index in the image, not in the batch
            rng = mi.PCG32(n_pix)
            rng.seed(state + sequence, sequence)
            return rng

        if ss == 1:
            rng = stream(mi.UInt64(pixel))
            linear = self.shader.radiance(o, d, s, n, rng, opts.adaptive_after)
            hit = s.hit
        else:  # the mean of ss x ss rays per pixel, each with its own random stream
            linear = mi.Color3f(0.0)
            hit = mi.Bool(False)
            n_sub = math.ceil(n / (ss * ss)) if n > 0 else 0
            stride = camera.width * camera.height
            for i in range(ss):
                for j in range(ss):
                    offset = ((j + 0.5) / ss - 0.5, (i + 0.5) / ss - 0.5)
                    so, sd = self.tracer.camera_rays(camera, T, rows, offset)
                    sub = self.tracer.trace(so, sd)
                    rng = stream(mi.UInt64(pixel) + mi.UInt64(stride * (i * ss + j + 1)))
                    linear += self.shader.radiance(so, sd, sub, n_sub, rng, opts.adaptive_after)
                    hit |= sub.hit
            linear *= 1.0 / (ss * ss)
        levels = self.shader.encode(linear, float(opts.exposure), opts.tonemap == "reinhard")
        r, g, b = (dr.select(hit, levels[c], self.background[c]) for c in range(3))
        return r | (g << 8) | (b << 16), linear, hit

    def render(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> Frame:
        H, W = camera.height, camera.width
        tracer = self.tracer
        T = np.asarray(world_T_camera, np.float64)
        if tracer.arms:
            tracer.place_arms(link_poses, (camera, T))
        seed = view_seed(camera, T, self.options.seed)
        repopa = self.seg_mode == "repopa"
        parts: dict[str, list[np.ndarray]] = {
            "rgb": [],
            "labels": [],
            "depth": [],
            "instances": [],
            "radiance": [],
            "plants": [],
        }
        keep = self.options.radiance
        step = max(1, self.options.batch_pixels // W)
        UInt8 = dr.uint8_array_t(tracer.mi.Float)
        for r0 in range(0, H, step):  # bounded memory at any resolution; results do not depend on it
            rows = (r0, min(r0 + step, H))
            o, d = tracer.camera_rays(camera, T, rows)
            s = tracer.trace(o, d, raw=repopa)
            labels, depth, instances = tracer.annotate(s, repopa, self.label_map)
            packed, linear, hit = self._rgb(camera, T, rows, o, d, s, seed)
            labels = UInt8(labels)
            if keep:  # the pixels that hit nothing: the background's radiance
                linear = dr.select(hit, linear, self.background_radiance)
                dr.eval(packed, labels, depth, instances, linear)
            else:
                dr.eval(packed, labels, depth, instances)
            # RGB as bytes by a second, small kernel (scattered from the big one, the shading ran
            # once per channel)
            n = dr.width(packed)
            rgb = dr.zeros(UInt8, 3 * n)
            k = dr.arange(tracer.mi.UInt32, n) * 3
            for c in range(3):
                dr.scatter(rgb, UInt8((packed >> (8 * c)) & 255), k + c)
            dr.eval(rgb)
            # every image in its final type on the device: the host only copies
            h = rows[1] - rows[0]
            parts["rgb"].append(np.asarray(rgb).reshape(h, W, 3))
            parts["labels"].append(np.asarray(labels).reshape(h, W))
            parts["depth"].append(np.asarray(depth).reshape(h, W))
            if keep:
                parts["radiance"].append(np.stack([np.asarray(linear[c]) for c in range(3)], -1).reshape(h, W, 3))
            if instances is not None:
                tracer.add_ids(np.asarray(instances).reshape(h, W), parts)
        images = {k: (v[0] if len(v) == 1 else np.concatenate(v)) if v else None for k, v in parts.items()}
        return Frame(**images)

    def render_rgb(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> tuple[np.ndarray, np.ndarray | None]:
        # the labels and depth come with the RGB at little cost: one pass draws all three
        frame = self.render(camera, world_T_camera, link_poses)
        return frame.rgb, frame.radiance

    def arm_meshes(self) -> dict[str, list[tuple[str, Mesh]]]:
        if self.hide_robots:
            return {}
        if self.scene.arms:
            return self.scene.arms
        return {
            arm.name: [(lm.link, lm.mesh) for lm in arm_link_meshes(arm.urdf, self.options.arm_triangles)]
            for arm in self.cell.arms
        }

    def close(self) -> None:
        self.tracer.close()
