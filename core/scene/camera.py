"""Camera models and presets (the paper's RobotCam and CineCamera)."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

from agrisim.errors import UserError


@dataclass
class CameraModel:
    """A pinhole camera (OpenCV conventions; pixel centres at integer coordinates)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> np.ndarray:  # noqa: N802 - the field's name for it
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def hfov_deg(self) -> float:
        return float(np.degrees(2.0 * np.arctan(self.width / (2.0 * self.fx))))


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


PRESETS: dict[str, tuple[float, float, float]] = {
    # name: sensor width mm, sensor height mm, focal mm (the paper's RaspPi3Wide)
    "rpi3-wide-1080p": (6.45, 3.63, 2.75),
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
    return from_sensor(*PRESETS[name], w, h)


def view_seed(camera: CameraModel, world_T_camera: np.ndarray, seed: int) -> int:
    """A 64-bit seed of one view: the run's ``seed`` mixed with the camera and its pose, so every
    view samples its own noise and the same view always the same."""
    h = hashlib.blake2b(digest_size=8)
    h.update(np.asarray(world_T_camera, np.float64).tobytes())
    intrinsics = [camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy]
    h.update(np.array(intrinsics, np.float64).tobytes())
    h.update(int(seed).to_bytes(8, "little"))
    return int.from_bytes(h.digest(), "little")
