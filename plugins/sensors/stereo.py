"""Intel RealSense D4xx stereo depth, simulated from its physics: the two infrared images
rendered, matched by semi-global matching, converted and invalidated as the device does.

Devices (Intel RealSense D400 Series Product Family Datasheet: baselines, depth fields of view
at 16:9, minimum depth at the highest resolution):

========  ========  ==============  ==========  =========
device    baseline  depth FoV       projector   range
========  ========  ==============  ==========  =========
D435      50 mm     87 x 58 deg     yes         0.28-3 m
D415      55 mm     65 x 40 deg     yes         0.45-3 m
D405      18 mm     87 x 58 deg     no          0.07-0.5 m
========  ========  ==============  ==========  =========

The minimum depths are the datasheet's at 1280 x 720; at a smaller image the device measures
nearer, in proportion to the width (:func:`min_depth`: at 848 x 480, 0.19, 0.30 and 0.05 m).

The depth origin is the left imager. The right imager sits ``baseline`` to its right. The
projector of the D435 and D415 sits between the imagers, and the colour camera 15 mm to the
left imager's right (a typical factory calibration; each unit has its own). The D405 has no
projector, and its colour comes from the left imager itself.

Each imager's image is the scene's infrared radiance through its pixel centres, traced exactly
(:class:`~agrisim.plugins.render.raycast.tracing.SceneTracer`: cut-out texels and culled faces
as the renderer has them). The radiance has two parts. The passive part is the room's light on
the surface's texture: its visible albedo's luminance under a uniform ``ambient``. The active
part is the projector's dot pattern on the surface's near-infrared reflectance
(:mod:`agrisim.plugins.sensors.nir`), with the inverse-square falloff from the projector and its
incidence. A point the projector cannot see gets no dots (a shadow ray, cut-out texels letting
light through). Then shot noise and read noise, and 8 bits, as the imagers' Y8 output.

The pair is matched by OpenCV's ``StereoSGBM``, the field's semi-global matching, over the
disparities of the device's range, in 1/16 pixel. Depth is ``f b / d``. Pixels are invalidated
where matching fails: the left-right check (``disp12MaxDiff``), the uniqueness ratio, speckle
filtering, and no match at all; and where the left image has too little texture to match on
(the ASIC's texture filter: too few neighbours in a 7x7 window differ from the pixel by more
than a step; its thresholds are agrisim's, set above the imagers' noise). Depths outside the
device's range are dropped too. The depth is then moved onto the colour camera's pixels
(:mod:`.align`). Left out: the imagers' lens distortion and rolling shutter (the D415's), and
the ASIC's own post-filters.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from agrisim.config import RenderConfig
from agrisim.errors import ConfigError
from agrisim.options import Options
from agrisim.plugins.sensors.traced import TracedSensor
from agrisim.robot.cell import Cell
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import Scene


@dataclass(frozen=True)
class Device:
    """One D4xx model's published geometry."""

    name: str
    baseline_m: float
    hfov_deg: float
    vfov_deg: float
    projector: bool
    min_z_m: float
    max_z_m: float


DEVICES = {
    "d435": Device("d435", 0.050, 87.0, 58.0, True, 0.28, 3.0),
    "d415": Device("d415", 0.055, 65.0, 40.0, True, 0.45, 3.0),
    "d405": Device("d405", 0.018, 87.0, 58.0, False, 0.07, 0.5),
}
#: the image sizes the depth stream offers (848 x 480: Intel's recommended one for the D435)
RESOLUTIONS = {"1280x720": (1280, 720), "848x480": (848, 480), "640x360": (640, 360)}
#: the colour camera's offset from the left imager (x right), where it is not the left imager
COLOUR_OFFSET_M = 0.015
#: dots of the projector's pattern over its field of view (assumed: Intel publishes no count)
PATTERN_DOTS = 60_000
#: the pattern's raster, texels over the projector's field of view (its dots are Gaussian
#: spots of one texel's standard deviation)
PATTERN_SIZE = (1024, 683)
#: the projector's field of view, degrees (wider than the imagers': its dots fill their view)
PROJECTOR_FOV_DEG = (94.0, 66.0)


class StereoOptions(Options):
    """Options of the RealSense D4xx stereo depth sensors."""

    resolution: Literal["1280x720", "848x480", "640x360"] = "848x480"
    """The depth stream's size (the sizes the device offers)."""
    min_depth_m: float | None = Field(None, gt=0.0, le=10.0)
    """Nearest depth reported, m (default: the device's minimum; not below it)."""
    max_depth_m: float | None = Field(None, gt=0.0, le=10.0)
    """Farthest depth reported, m (default: the device's range; not beyond it)."""
    ambient: float = Field(0.25, ge=0.0, le=10.0)
    """The room's light on the imagers, as the radiance of a white surface (1: full scale)."""
    projector_power: float = Field(0.6, ge=0.0, le=100.0)
    """The projector's dots on a white surface 1 m away, as radiance (1: full scale)."""
    noise: float = Field(1.0, ge=0.0, le=10.0)
    """Scale of the imagers' noise (shot noise of a full well of 2,000 electrons at full scale,
    and 2 electrons of read noise); 0: none."""
    speckle: float = Field(0.15, ge=0.0, le=1.0)
    """Contrast of the projector's laser speckle (independent on the two imagers); 0: none."""
    supersample: int = Field(2, ge=1, le=6)
    """Rays per pixel side of the infrared images (a pixel integrates the light on its area)."""
    block_size: int = Field(7, ge=3, le=15)
    """The matching window's side, pixels (odd)."""
    texture_difference: int = Field(6, ge=0, le=255)
    """The texture filter's step: a neighbour in the 7x7 window around a pixel counts as texture
    when it differs from the pixel by more than this, in 8-bit levels (the ASIC's texture
    difference threshold; 0 with ``texture_count`` 0: no filter)."""
    texture_count: int = Field(10, ge=0, le=48)
    """The texture filter's count: a pixel with fewer textured neighbours than this in its 7x7
    window is dropped (the ASIC's texture count threshold; 0: no filter)."""
    seed: int = Field(0, ge=0, le=2**32 - 1)
    """Seed of the imagers' noise (mixed with the view)."""
    variant: Literal["auto", "cuda", "llvm"] = "auto"
    """Where Dr.Jit traces the rays (``auto``: the variant the process already uses, else CUDA
    when a GPU is usable, else LLVM)."""


def min_depth(device: Device, resolution: str) -> float:
    """The nearest depth the device measures at ``resolution``, m. The datasheet's minimum is at
    1280 x 720, where the ASIC's search of 126 disparities ends (min-Z = f b / 126); the same
    126 pixels reach nearer on a smaller image, in proportion to its focal length in pixels."""
    return device.min_z_m * RESOLUTIONS[resolution][0] / 1280


def depth_range(device: Device, options: StereoOptions) -> tuple[float, float]:
    """(nearest, farthest) depth reported; a ConfigError naming the device's range when the
    options ask for depth outside it."""
    nearest = min_depth(device, options.resolution)
    lo = nearest if options.min_depth_m is None else options.min_depth_m
    hi = device.max_z_m if options.max_depth_m is None else options.max_depth_m
    if lo < nearest or hi > device.max_z_m or lo >= hi:
        raise ConfigError(
            f"depth sensor {device.name!r}: depth {lo:g}-{hi:g} m is outside its range "
            f"{nearest:.3g}-{device.max_z_m:g} m at {options.resolution} (min_depth_m, max_depth_m)"
        )
    return lo, hi


def texture(image: np.ndarray, step: int, radius: int = 3) -> np.ndarray:
    """Per pixel of an 8-bit image, how many of the neighbours in its (2 radius + 1)^2 window
    differ from it by more than ``step`` levels: the ASIC's texture measure. Where the image
    holds only noise (a far wall the dots barely reach), few neighbours pass a step above the
    noise, and a match there would be a guess."""
    img = image.astype(np.int16)
    pad = np.pad(img, radius, mode="edge")
    H, W = img.shape
    count = np.zeros((H, W), np.uint8)
    for dy in range(2 * radius + 1):
        for dx in range(2 * radius + 1):
            if dy != radius or dx != radius:
                count += np.abs(pad[dy : dy + H, dx : dx + W] - img) > step
    return count


def imager(device: Device, resolution: str) -> CameraModel:
    """An imager of ``device`` at ``resolution``: a pinhole of the device's depth field of view."""
    w, h = RESOLUTIONS[resolution]
    fx = (w / 2) / np.tan(np.radians(device.hfov_deg) / 2)
    fy = (h / 2) / np.tan(np.radians(device.vfov_deg) / 2)
    return CameraModel(w, h, float(fx), float(fy), (w - 1) / 2, (h - 1) / 2)


def pattern(seed: int = 0) -> np.ndarray:
    """The projector's dot pattern, float32 (PATTERN_SIZE[1], PATTERN_SIZE[0]) in [0, 1]."""
    w, h = PATTERN_SIZE
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(0, w, PATTERN_DOTS), rng.uniform(0, h, PATTERN_DOTS)
    img = np.zeros((h, w), np.float32)
    r = 3
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            cx, cy = np.floor(x).astype(int) + dx, np.floor(y).astype(int) + dy
            ok = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
            g = np.exp(-((cx + 0.5 - x) ** 2 + (cy + 0.5 - y) ** 2) / 2.0).astype(np.float32)
            np.add.at(img, (cy[ok], cx[ok]), g[ok])
    return np.clip(img, 0.0, 1.0)


class StereoSensor(TracedSensor):
    """Stereo depth as a RealSense D4xx computes it, aligned to the colour camera (see the module)."""

    def __init__(
        self, scene: Scene, cell: Cell | None, settings: RenderConfig, options: StereoOptions, device: str
    ) -> None:
        self.device = DEVICES[device]
        self.near, self.far = depth_range(self.device, options)
        super().__init__(scene, cell, settings, options)
        self._pattern = self.tracer.mi.Float(pattern().ravel())
        self.camera = imager(self.device, options.resolution)
        self.camera_T_sensor = np.eye(4)
        if self.device.projector:  # the colour camera beside the left imager; the D405's is the left imager
            self.camera_T_sensor[0, 3] = -COLOUR_OFFSET_M

    def _left_T_right(self) -> np.ndarray:
        T = np.eye(4)
        T[0, 3] = self.device.baseline_m
        return T

    def infrared(self, world_T_imager: np.ndarray, world_T_projector: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The radiance an imager at ``world_T_imager`` sees (float32 H x W, 1 = full scale),
        noise-free, in two parts: the room's light on the texture and the projector's dots, each pixel the
        mean of ``supersample`` x ``supersample`` rays over its area (a pixel integrates the
        light on it: dots narrower than a pixel are not point-sampled)."""
        s = self.options.supersample
        passive = np.zeros((self.camera.height, self.camera.width), np.float32)
        active = np.zeros_like(passive)
        for i in range(s):
            for j in range(s):
                offset = ((j + 0.5) / s - 0.5, (i + 0.5) / s - 0.5)
                a, b = self._radiance(world_T_imager, world_T_projector, offset)
                passive += a
                active += b
        return passive / (s * s), active / (s * s)

    def _radiance(
        self, world_T_imager: np.ndarray, world_T_projector: np.ndarray, offset: tuple[float, float]
    ) -> tuple[np.ndarray, np.ndarray]:
        import drjit as dr

        tracer, mi, opts = self.tracer, self.tracer.mi, self.options
        e, cam = tracer.engine, self.camera
        o, d = tracer.camera_rays(cam, world_T_imager, offset=offset)
        s = tracer.trace(o, d)
        hit = s.face >= 0
        p = o + d * s.t
        mat = e.material(s.face, hit)
        p0, p1 = e.plant_faces
        uv = e.uv(s.face, s.b, hit & (s.face >= p0) & (s.face < p1))
        albedo = e.m.albedo(uv, mat, True, hit) * e.color(s.face, s.b, hit)
        luminance = albedo[0] * 0.2126 + albedo[1] * 0.7152 + albedo[2] * 0.0722
        radiance = dr.select(hit, luminance * opts.ambient, 0.0)
        dots_radiance = dr.zeros(mi.Float, dr.width(radiance))
        if self.device.projector and opts.projector_power > 0:
            P = np.asarray(world_T_projector, np.float64)
            # the projector's pose opaque: one kernel for every pose (as literals, one a view)
            q = mi.Point3f(*(dr.opaque(mi.Float, float(x)) for x in P[:3, 3]))
            w = p - q
            dist2 = dr.squared_norm(w)
            # the point in the projector's frame, then its texel of the pattern
            R = [[dr.opaque(mi.Float, float(x)) for x in row] for row in P[:3, :3]]
            local = [w[0] * R[0][k] + w[1] * R[1][k] + w[2] * R[2][k] for k in range(3)]
            pw, ph = PATTERN_SIZE
            tx, ty = (np.tan(np.radians(a) / 2) for a in PROJECTOR_FOV_DEG)
            front = local[2] > 1e-6
            u = (local[0] / dr.select(front, local[2], 1.0) / tx * 0.5 + 0.5) * pw
            v = (local[1] / dr.select(front, local[2], 1.0) / ty * 0.5 + 0.5) * ph
            inside = hit & front & (u >= 0) & (u < pw - 1) & (v >= 0) & (v < ph - 1)
            x0, y0 = dr.floor(u), dr.floor(v)
            ax, ay = u - x0, v - y0
            i00 = mi.UInt32(dr.select(inside, y0 * pw + x0, 0))
            c = [dr.gather(mi.Float, self._pattern, i00 + k, inside) for k in (0, 1, pw, pw + 1)]
            dots = (c[0] * (1 - ax) + c[1] * ax) * (1 - ay) + (c[2] * (1 - ax) + c[3] * ax) * ay
            n = e.normal(s.face, hit)
            cosine = dr.abs(dr.dot(n, w)) / dr.sqrt(dr.maximum(dist2, 1e-12))
            rho = dr.gather(mi.Float, self._nir, mat, hit)
            lit = inside & ~tracer.occluded(p + n * dr.sign(dr.dot(n, -w)) * 1e-4, q - p, inside)
            dots_radiance = dr.select(lit, rho * dots * cosine * opts.projector_power / dist2, 0.0)
        dr.eval(radiance, dots_radiance)
        shape = (cam.height, cam.width)
        return np.asarray(radiance, np.float32).reshape(shape), np.asarray(dots_radiance, np.float32).reshape(shape)

    def _exposed(self, radiance: np.ndarray, gain: float, rng: np.random.Generator) -> np.ndarray:
        """8-bit pixel values of ``radiance`` exposed with ``gain``, with shot and read noise."""
        full_well, read = 2000.0, 2.0
        electrons = np.clip(radiance * gain, 0.0, 1.0) * full_well
        sigma = self.options.noise * np.sqrt(electrons + read**2)
        noisy = electrons + sigma * rng.standard_normal(electrons.shape)
        return np.clip(np.round(noisy / full_well * 255.0), 0, 255).astype(np.uint8)

    def pair(self, world_T_camera: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """The left and right 8-bit infrared images of the view (the arms already placed)."""
        world_T_left = np.asarray(world_T_camera, np.float64) @ self.camera_T_sensor
        world_T_right = world_T_left @ self._left_T_right()
        world_T_projector = world_T_left.copy()
        world_T_projector[:3, 3] = (world_T_left @ np.array([self.device.baseline_m / 2, 0, 0, 1.0]))[:3]
        rng = np.random.default_rng(seed)
        images = []
        for T in (world_T_left, world_T_right):
            passive, active = self.infrared(T, world_T_projector)
            # laser speckle: the dots' coherent light seen from each imager's own viewpoint,
            # a grain of its own on each (contrast ``speckle``)
            grain = np.clip(1.0 + self.options.speckle * rng.standard_normal(active.shape), 0.0, None)
            images.append(passive + active * grain.astype(np.float32))
        left, right = images
        # auto exposure, as the imagers run by default: the left image's 99th percentile at 80%
        # of full scale (within 1/8 to 16 times the nominal exposure)
        bright = float(np.percentile(left, 99))
        gain = float(np.clip(0.8 / bright, 1 / 8, 16.0)) if bright > 0 else 16.0
        return self._exposed(left, gain, rng), self._exposed(right, gain, rng)

    def disparity_range(self) -> tuple[int, int]:
        """(minDisparity, numDisparities): from 0, so that surfaces beyond the range match
        where they are (and are then dropped) instead of wherever the search ends, to the
        nearest depth of the range."""
        fb = self.camera.fx * self.device.baseline_m
        span = int(np.ceil(fb / self.near)) + 1
        return 0, max(16, int(np.ceil(span / 16)) * 16)

    def match(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        """Planar depth (float32 H x W, m; 0 = none) on the left imager from the pair."""
        import cv2

        bs = self.options.block_size | 1
        lo, count = self.disparity_range()
        sgbm = cv2.StereoSGBM_create(
            minDisparity=lo,
            numDisparities=count,
            blockSize=bs,
            P1=8 * bs * bs,
            P2=32 * bs * bs,
            disp12MaxDiff=1,
            uniquenessRatio=10,
            speckleWindowSize=100,
            speckleRange=2,
            mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
        )
        disparity = sgbm.compute(left, right).astype(np.float32) / 16.0
        valid = (disparity > max(lo, 0)) & (
            texture(left, self.options.texture_difference) >= self.options.texture_count
        )
        depth = np.where(valid, self.camera.fx * self.device.baseline_m / np.maximum(disparity, 1e-6), 0.0)
        depth[(depth < self.near) | (depth > self.far)] = 0.0
        return depth.astype(np.float32)

    def measure_native(
        self, world_T_camera: np.ndarray, link_poses: Mapping[str, Mapping[str, np.ndarray]], seed: int
    ) -> np.ndarray:
        """The device's own depth image on its left imager (float32, m; 0 = none)."""
        if self.tracer.arms:
            # (every link: the right imager and the projector see past the left one's frustum)
            self.tracer.place_arms(link_poses)
        left, right = self.pair(world_T_camera, seed)
        return self.match(left, right)
