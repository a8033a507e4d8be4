"""The Azure Kinect's depth camera (time of flight, NFOV unbinned), simulated from its physics.

Geometry (Azure Kinect DK hardware specification, "Depth camera supported operating modes"):
640 x 576 pixels over 75 x 65 degrees, operating range 0.5-3.86 m. The depth camera is tilted
6 degrees down from the colour camera (same specification, "Coordinate systems"); it sits about
32 mm beside it, a typical factory calibration (each device has its own, which the SDK reads).

Each pixel integrates the returns of ``subsamples`` x ``subsamples`` rays over its footprint,
traced exactly into the scene (:class:`~agrisim.plugins.render.raycast.tracing.SceneTracer`,
cut-out texels and culled faces as the renderer has them). A return is a phasor: amplitude
``rho cos(theta) / r^2`` (the scene is lit by the camera's own emitter: near-infrared
reflectance ``rho``, :mod:`agrisim.plugins.sensors.nir`; incidence ``theta``; range ``r``) and phase
``4 pi f r / c``. The pixel measures the phase of their sum: where a pixel straddles a depth
edge, foreground and background mix into a range between them, the flying pixels of real ToF
cameras, and their amplitudes partly cancel. The phase is unwrapped to the interval nearest the
returns' amplitude-weighted mean range (what the device's multi-frequency unwrapping settles).

Noise is shot noise: the range's standard deviation grows as one over the square root of the
pixel's amplitude, scaled so that the specification's worst case, a 15%-reflective surface at
the far end of the range (3.86 m) facing the camera, has its published random error, 17 mm (the
specification's footnote: 15-95% reflectivity at 850 nm). On a surface of fixed reflectance the
error then grows in proportion to the range. Pixels are invalidated, as the depth engine does,
where the amplitude is too low (an error over twice the published one) or saturates (over four
times a 95%-reflective surface's at 0.5 m), and where a pixel's depth lies between its
neighbours' on both sides of a depth edge (the flying-pixel filter). Left out: multipath
(light bouncing between surfaces before it returns), ambient light, the illumination mask of
the corners, and temporal effects.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, Literal

import numpy as np
from pydantic import Field

from agrisim.config import RenderConfig
from agrisim.options import Options
from agrisim.plugins.sensors.traced import TracedSensor
from agrisim.robot.cell import Cell
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import Scene

#: speed of light, m/s
C = 299_792_458.0
#: NFOV unbinned (hardware specification)
WIDTH, HEIGHT = 640, 576
HFOV_DEG, VFOV_DEG = 75.0, 65.0
RANGE_M = (0.5, 3.86)
#: the published random error (standard deviation) and the conditions it holds in
RANDOM_ERROR_M = 0.017
WORST_REFLECTANCE = 0.15
BEST_REFLECTANCE = 0.95
#: downward tilt of the depth camera against the colour camera, degrees
TILT_DEG = 6.0
#: where the depth camera sits in the colour camera's frame (OpenCV axes), m
OFFSET_M = (-0.032, 0.0, 0.0)
#: the modulation frequency whose phase a pixel measures, Hz (the device's highest is 320 MHz;
#: this one's ambiguity interval, c / 2f = 0.75 m, sets how far mixed pixels can fly)
MODULATION_HZ = 200e6


def _signal(reflectance: float, distance: float) -> float:
    return reflectance / distance**2


#: the worst case the random error is published for: its signal sets the noise's scale
REFERENCE_SIGNAL = _signal(WORST_REFLECTANCE, RANGE_M[1])
#: below this the error would exceed twice the published one: invalid (low signal)
MIN_SIGNAL = REFERENCE_SIGNAL / 4.0
#: above this the pixel saturates: invalid
MAX_SIGNAL = 4.0 * _signal(BEST_REFLECTANCE, RANGE_M[0])


class AzureKinectOptions(Options):
    """Options of the Azure Kinect time-of-flight depth sensor."""

    mode: Literal["nfov-unbinned"] = "nfov-unbinned"
    """Depth mode: NFOV unbinned, 640 x 576 over 75 x 65 degrees, 0.5-3.86 m (the one modelled)."""
    subsamples: int = Field(3, ge=1, le=8)
    """Rays per pixel side: each pixel integrates s x s returns over its footprint, so that
    surfaces mix at depth edges into flying pixels (1: every pixel one ray, no mixing)."""
    noise: float = Field(1.0, ge=0.0, le=10.0)
    """Scale of the shot noise: 1, the published random error; 0, none (the mixing and the
    invalidation stay)."""
    flying_pixel_filter: bool = True
    """Invalidate pixels whose depth lies between their neighbours' across a depth edge, as the
    SDK's depth engine does."""
    edge_m: float = Field(0.05, gt=0.0, le=10.0)
    """Per metre of range: the depth gap between two neighbours of a pixel that counts as an edge
    for the flying-pixel filter (5 cm at 1 m)."""
    seed: int = Field(0, ge=0, le=2**32 - 1)
    """Seed of the noise (mixed with the view: every view has its own)."""
    variant: Literal["auto", "cuda", "llvm"] = "auto"
    """Where Dr.Jit traces the rays (``auto``: the variant the process already uses, else CUDA
    when a GPU is usable, else LLVM)."""


def sensor_camera() -> CameraModel:
    """The NFOV-unbinned imager as a pinhole camera."""
    fx = (WIDTH / 2) / np.tan(np.radians(HFOV_DEG) / 2)
    fy = (HEIGHT / 2) / np.tan(np.radians(VFOV_DEG) / 2)
    return CameraModel(WIDTH, HEIGHT, float(fx), float(fy), (WIDTH - 1) / 2, (HEIGHT - 1) / 2)


def camera_T_sensor() -> np.ndarray:
    """The depth camera's pose in the colour camera's frame: tilted down, beside it."""
    a = np.radians(TILT_DEG)
    T = np.eye(4)
    # OpenCV axes (y down): tilting the optical axis down turns it towards +y
    T[:3, :3] = [[1.0, 0.0, 0.0], [0.0, np.cos(a), np.sin(a)], [0.0, -np.sin(a), np.cos(a)]]
    T[:3, 3] = OFFSET_M
    return T


def random_error(reflectance: np.ndarray | float, distance: np.ndarray | float, cosine: float = 1.0) -> np.ndarray:
    """The model's range standard deviation, m, for a surface of ``reflectance`` at
    ``distance`` seen at incidence cosine ``cosine`` (the shot-noise law it draws from)."""
    signal = np.asarray(reflectance) * cosine / np.asarray(distance, np.float64) ** 2
    return RANDOM_ERROR_M * np.sqrt(REFERENCE_SIGNAL / signal)


def mix(ranges: np.ndarray, amplitudes: np.ndarray, frequency: float = MODULATION_HZ) -> tuple[np.ndarray, np.ndarray]:
    """(range, amplitude) each pixel measures from its returns (S x N: ``ranges`` in m and
    ``amplitudes``, 0 for a ray that hit nothing): the phase of the summed phasors, unwrapped to
    the interval nearest the amplitude-weighted mean range; the amplitude of their mean."""
    k = 4.0 * np.pi * frequency / C
    phase = k * ranges
    re, im = (amplitudes * np.cos(phase)).mean(axis=0), (amplitudes * np.sin(phase)).mean(axis=0)
    amplitude = np.hypot(re, im)
    total = amplitudes.sum(axis=0)
    mean = np.divide((amplitudes * ranges).sum(axis=0), total, out=np.zeros_like(total), where=total > 0)
    wrap = 2.0 * np.pi / k
    phase_range = np.mod(np.arctan2(im, re), 2.0 * np.pi) / k
    measured = phase_range + wrap * np.round((mean - phase_range) / wrap)
    return measured, amplitude


def flying_pixels(depth: np.ndarray, edge_per_m: float, margin: np.ndarray) -> np.ndarray:
    """Bool H x W: pixels lying between two opposite neighbours (left-right, up-down or either
    diagonal) across a depth edge (their gap over ``edge_per_m`` times the range), farther from
    both than those neighbours' ``margin`` (H x W, m: their noise): mixed returns, not a
    surface. (The neighbours' margin, not the pixel's own: a mixed pixel's returns cancel in
    part, so its own noise is larger than either surface's.)"""
    H, W = depth.shape
    pad = np.pad(depth, 1, constant_values=0.0)
    wide = np.pad(margin, 1, constant_values=0.0)
    out = np.zeros((H, W), bool)
    centre = depth
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = pad[1 + dy : 1 + dy + H, 1 + dx : 1 + dx + W]
        b = pad[1 - dy : 1 - dy + H, 1 - dx : 1 - dx + W]
        m = np.maximum(wide[1 + dy : 1 + dy + H, 1 + dx : 1 + dx + W], wide[1 - dy : 1 - dy + H, 1 - dx : 1 - dx + W])
        valid = (a > 0) & (b > 0) & (centre > 0)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        edge = (hi - lo) > edge_per_m * centre
        out |= valid & edge & (centre > lo + m) & (centre < hi - m)
    return out


class AzureKinectSensor(TracedSensor):
    """Time-of-flight depth as the Azure Kinect's NFOV-unbinned mode measures it, aligned to the
    colour camera (see the module)."""

    def __init__(self, scene: Scene, cell: Cell | None, settings: RenderConfig, options: AzureKinectOptions) -> None:
        super().__init__(scene, cell, settings, options)
        self.camera = sensor_camera()
        self.camera_T_sensor = camera_T_sensor()

    def _returns(self, world_T_sensor: np.ndarray) -> Iterator[tuple[Any, Any]]:
        """Each sub-sample's (range, amplitude) of every pixel, as Dr.Jit arrays (amplitude 0
        and range 0 where a ray hits nothing)."""
        import drjit as dr

        tracer, mi, s = self.tracer, self.tracer.mi, self.options.subsamples
        cam, near, e = self.camera, tracer.options.near, tracer.engine
        for i in range(s):
            for j in range(s):
                offset = ((j + 0.5) / s - 0.5, (i + 0.5) / s - 0.5)
                o, d = tracer.camera_rays(cam, world_T_sensor, offset=offset)
                hit = tracer.trace(o, d)
                length = dr.norm(d)
                r = (hit.t + near) * length  # d has unit camera z: t + near is planar depth
                on = hit.face >= 0
                n = e.normal(hit.face, on)
                cosine = dr.abs(dr.dot(n, d / length))
                rho = dr.gather(mi.Float, self._nir, e.material(hit.face, on), on)
                yield dr.select(on, r, 0.0), dr.select(on, rho * cosine / dr.square(r), 0.0)

    def _per_range(self) -> np.ndarray:
        """Each pixel centre's planar depth per metre of range (row-major)."""
        cam = self.camera
        u, v = np.meshgrid(np.arange(cam.width), np.arange(cam.height))
        return (1.0 / np.sqrt(((u - cam.cx) / cam.fx) ** 2 + ((v - cam.cy) / cam.fy) ** 2 + 1.0)).reshape(-1)

    def returns(self, world_T_sensor: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ranges, amplitudes, planar-per-range) of the sensor's rays: ``ranges`` and
        ``amplitudes`` S x N (S = subsamples^2 rays per pixel, N pixels, row-major; amplitude 0
        where a ray hits nothing), and each pixel centre's planar depth per metre of range."""
        import drjit as dr

        ranges, amplitudes = [], []
        for r, a in self._returns(world_T_sensor):
            dr.eval(r, a)
            ranges.append(np.asarray(r, np.float64))
            amplitudes.append(np.asarray(a, np.float64))
        return np.stack(ranges), np.stack(amplitudes), self._per_range()

    def mixed(self, world_T_sensor: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(range, amplitude, planar-per-range) each pixel measures, as :func:`mix` of
        :meth:`returns`, summed on Dr.Jit in the kernels that trace the rays (on a GPU, the
        returns never reach the host)."""
        import drjit as dr

        mi, s = self.tracer.mi, self.options.subsamples
        k = mi.Float(4.0 * np.pi * MODULATION_HZ / C)
        re, im, total, weighted = (dr.zeros(mi.Float, self.camera.width * self.camera.height) for _ in range(4))
        for r, a in self._returns(world_T_sensor):
            sin, cos = dr.sincos(k * r)
            re, im, total, weighted = re + a * cos, im + a * sin, total + a, weighted + a * r
            dr.eval(re, im, total, weighted)  # (one sub-sample's rays at a time: bounded memory)
        re, im = re / s**2, im / s**2
        amplitude = dr.sqrt(dr.square(re) + dr.square(im))
        mean = dr.select(total > 0, weighted / dr.maximum(total, 1e-30), 0.0)
        wrap = 2.0 * np.pi / k
        phase = dr.atan2(im, re)
        phase_range = dr.select(phase < 0, phase + 2.0 * np.pi, phase) / k
        measured = phase_range + wrap * dr.round((mean - phase_range) / wrap)
        dr.eval(measured, amplitude)
        return np.asarray(measured, np.float64), np.asarray(amplitude, np.float64), self._per_range()

    def measure_native(
        self, world_T_camera: np.ndarray, link_poses: Mapping[str, Mapping[str, np.ndarray]], seed: int
    ) -> np.ndarray:
        """The sensor's own depth image (float32 576 x 640 planar metres in its frame, 0 = invalid)."""
        opts = self.options
        world_T_sensor = np.asarray(world_T_camera, np.float64) @ self.camera_T_sensor
        if self.tracer.arms:
            self.tracer.place_arms(link_poses, (self.camera, world_T_sensor))
        measured, amplitude, per_range = self.mixed(world_T_sensor)
        valid = (amplitude >= MIN_SIGNAL) & (amplitude <= MAX_SIGNAL)
        sigma = RANDOM_ERROR_M * np.sqrt(REFERENCE_SIGNAL / np.maximum(amplitude, 1e-30))
        rng = np.random.default_rng(seed)
        measured = measured + opts.noise * sigma * rng.standard_normal(measured.shape)
        depth = np.where(valid & (measured > 0), measured * per_range, 0.0).reshape(
            self.camera.height, self.camera.width
        )
        if opts.flying_pixel_filter:
            margin = 3.0 * opts.noise * sigma.reshape(depth.shape) + 1e-3
            depth[flying_pixels(depth, opts.edge_m, margin)] = 0.0
        return depth.astype(np.float32)
