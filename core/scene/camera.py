"""Camera models and presets (the paper's RobotCam and CineCamera, and lenses as they are)."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.scene.lens import Distortion, check_unfolded


@dataclass
class CameraModel:
    """A camera in OpenCV's conventions (pixel centres at integer coordinates): the pinhole
    ``K`` and, optionally, its lens's ``distortion``. Depth is always z along the optical
    axis, through a lens as through a pinhole."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: Distortion | None = None

    def __post_init__(self) -> None:
        if self.distortion is not None:
            corners = np.array([[-0.5, -0.5], [self.width - 0.5, -0.5], [-0.5, self.height - 0.5]])
            corners = np.vstack([corners, [[self.width - 0.5, self.height - 0.5]]])
            reach = float(np.max(np.hypot((corners[:, 0] - self.cx) / self.fx, (corners[:, 1] - self.cy) / self.fy)))
            check_unfolded(self.distortion, reach)

    @property
    def K(self) -> np.ndarray:  # noqa: N802 - the field's name for it
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def pinhole(self) -> bool:
        return self.distortion is None

    @property
    def hfov_deg(self) -> float:
        """The angle between the rays of the left and right image edges through the principal
        point's row (half the width each side of it)."""
        half = self.width / (2.0 * self.fx)
        if self.distortion is None:
            return float(np.degrees(2.0 * np.arctan(half)))
        x, _ = self.distortion.undistort(np.array([-half, half]), np.zeros(2))
        return float(np.degrees(np.arctan(-x[0]) + np.arctan(x[1])))

    def rays(self, u: Any, v: Any) -> tuple[Any, Any]:
        """Slopes (X / Z, Y / Z) of the rays that land on pixel coordinates (u, v) (NumPy or
        Dr.Jit arrays): ``K^-1`` then the lens's inverse."""
        x, y = (u - self.cx) * (1.0 / self.fx), (v - self.cy) * (1.0 / self.fy)
        return (x, y) if self.distortion is None else self.distortion.undistort(x, y)

    def project(self, x: Any, y: Any) -> tuple[Any, Any]:
        """Pixel coordinates (u, v) where the rays of slopes (x, y) land: the lens, then ``K``."""
        if self.distortion is not None:
            x, y = self.distortion.distort(x, y)
        return x * self.fx + self.cx, y * self.fy + self.cy


def from_fov(hfov_deg: float, width: int, height: int) -> CameraModel:
    """An ideal pinhole from its horizontal field of view (the paper's Eq. 1)."""
    if not (0.0 < hfov_deg < 180.0) or width <= 0 or height <= 0:
        raise UserError(
            f"camera: hfov must be in (0, 180) degrees and sizes positive, got {hfov_deg}, {width}x{height}"
        )
    f = width / (2.0 * math.tan(math.radians(hfov_deg) / 2.0))
    return CameraModel(width, height, f, f, width / 2.0, height / 2.0)


def from_sensor(
    sensor_w_mm: float, sensor_h_mm: float, focal_mm: float, width: int, height: int, fstop: float | None = None
) -> CameraModel:
    """A camera from its sensor and lens (the paper's CineCamera); the sensor width sets hfov.

    ``fstop`` is accepted for completeness: a pinhole renderer has no depth of field.
    """
    if min(sensor_w_mm, sensor_h_mm, focal_mm) <= 0:
        raise UserError("camera: sensor size and focal length must be positive")
    hfov = math.degrees(2.0 * math.atan(sensor_w_mm / (2.0 * focal_mm)))
    return from_fov(hfov, width, height)


@dataclass(frozen=True)
class Preset:
    """A camera as its maker publishes it: the pinhole its sensor and lens give (square pixels,
    the principal point at the centre) and, where its field of view says it, the lens's
    distortion; ``source`` names where the figures come from."""

    sensor_w_mm: float
    sensor_h_mm: float
    focal_mm: float
    distortion: Distortion | None
    source: str

    def camera(self, width: int, height: int) -> CameraModel:
        pinhole = from_sensor(self.sensor_w_mm, self.sensor_h_mm, self.focal_mm, width, height)
        return CameraModel(
            pinhole.width, pinhole.height, pinhole.fx, pinhole.fy, pinhole.cx, pinhole.cy, self.distortion
        )


def barrel_for_fov(half_width: float, hfov_deg: float) -> Distortion:
    """The one-coefficient barrel lens (Brown-Conrady k1) under which the image's half width
    ``half_width`` (normalised: sensor half width over focal length) sees ``hfov_deg``: the ray
    at tan(hfov / 2) lands on the edge, x (1 + k1 x^2) = half_width."""
    x = math.tan(math.radians(hfov_deg) / 2.0)
    return Distortion("brown-conrady", ((half_width / x - 1.0) / (x * x), 0.0, 0.0, 0.0, 0.0))


#: the Camera Module 3's IMX708 (4608 x 2592 pixels of 1.4 um) behind its 2.75 mm wide lens
_IMX708_W_MM, _IMX708_H_MM, _WIDE_FOCAL_MM = 4608 * 1.4e-3, 2592 * 1.4e-3, 2.75


def _fov_preset(hfov_deg: float, source: str) -> Preset:
    """A 16:9 pinhole given by its horizontal field of view (a unit focal length)."""
    width = 2 * math.tan(math.radians(hfov_deg) / 2)
    return Preset(width, width * 9 / 16, 1.0, None, source)


PRESETS: dict[str, Preset] = {
    "rpi3-wide-1080p": Preset(
        6.45, 3.63, 2.75, None, "the paper's RaspPi3Wide (UE5 CineCamera): 6.45 x 3.63 mm sensor, 2.75 mm; a pinhole"
    ),
    "rpi-camera-3-wide": Preset(
        _IMX708_W_MM,
        _IMX708_H_MM,
        _WIDE_FOCAL_MM,
        barrel_for_fov(_IMX708_W_MM / 2 / _WIDE_FOCAL_MM, 102.0),
        "Raspberry Pi Camera Module 3 Wide product brief: IMX708 4608 x 2592 at 1.4 um, 2.75 mm, 102 degrees "
        "horizontal (the pinhole of sensor and focal length has 99.1); k1 fitted to the 102 degrees (it gives 67.6 "
        "vertical against the published 67; the brief's 120 diagonal no unfolded k1 reaches)",
    ),
    "realsense-d435-colour": _fov_preset(
        69.0,
        "Intel RealSense D400 datasheet: OV2740 colour camera, 69 x 42 degrees at 16:9 (42.2 with square pixels); "
        "Intel publishes no distortion (each unit's is in its calibration: pass it with --camera-calibration)",
    ),
    "azure-kinect-colour": _fov_preset(
        90.0,
        "Azure Kinect DK hardware specification: colour camera 90 x 59 degrees at 16:9 (58.7 with square pixels); "
        "distortion per unit (the SDK's calibration: pass it with --camera-calibration)",
    ),
}


def parse_resolution(text: str) -> tuple[int, int]:
    """``"1920x1080"`` -> (1920, 1080)."""
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise ValueError(f"resolution must look like WxH (e.g. 1920x1080), got {text!r}")
    w, h = int(parts[0]), int(parts[1])
    if not (8 <= w <= 8192 and 8 <= h <= 8192):
        raise ValueError(f"resolution {text!r}: width and height must be between 8 and 8192")
    return w, h


def preset(name: str, resolution: str | None = None) -> CameraModel:
    """A named preset, optionally at another resolution (same field of view)."""
    if name not in PRESETS:
        raise UserError(f"unknown camera preset {name!r}; available: {', '.join(PRESETS)}")
    w, h = parse_resolution(resolution) if resolution else (1920, 1080)
    return PRESETS[name].camera(w, h)


def view_seed(camera: CameraModel, world_T_camera: np.ndarray, seed: int) -> int:
    """A 64-bit seed of one view: the run's ``seed`` mixed with the camera and its pose, so every
    view samples its own noise and the same view always the same."""
    h = hashlib.blake2b(digest_size=8)
    h.update(np.asarray(world_T_camera, np.float64).tobytes())
    intrinsics = [camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy]
    h.update(np.array(intrinsics, np.float64).tobytes())
    h.update(int(seed).to_bytes(8, "little"))
    return int.from_bytes(h.digest(), "little")
