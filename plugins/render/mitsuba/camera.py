"""OpenCV's pinhole (K, world_T_camera) as Mitsuba's ``perspective`` sensor, exactly; a camera
with a lens as agrisim's ``agrisim_lens`` sensor (:mod:`.lens_sensor`).

Mitsuba's camera looks along +z with +x to the left and +y up; OpenCV's along +z with +x right
and +y down: the same optical axis with x and y flipped, so ``to_world = world_T_camera @
diag(-1, -1, 1, 1)``. Mitsuba's film puts pixel i over [i, i + 1), its centre at i + 0.5, where
OpenCV's pixel centres are the integers: the principal point (cx, cy) is film point (cx + 0.5,
cy + 0.5), and ``principal_point_offset_x/y`` are the offsets of the film centre from it as
fractions of the film's width and height (signs as Mitsuba's flipped x and y make them). The
field of view is along x (``fov_axis = "x"``: ``tan(fov / 2) = (W / 2) / fx``); Mitsuba's pixels
are square, so fx must equal fy.
"""

from __future__ import annotations

import math

import numpy as np

from agrisim.errors import ConfigError
from agrisim.scene.camera import CameraModel

#: OpenCV camera frame -> Mitsuba camera frame (x and y flipped)
CV_TO_MITSUBA = np.diag([-1.0, -1.0, 1.0, 1.0])


def check_square_pixels(camera: CameraModel) -> None:
    """Mitsuba's perspective camera has square pixels: refuse fx != fy."""
    if not math.isclose(camera.fx, camera.fy, rel_tol=1e-9):
        raise ConfigError(
            f"renderer 'mitsuba' needs square pixels (fx == fy); this camera has fx {camera.fx}, fy {camera.fy}"
        )


def sensor_dict(camera: CameraModel, world_T_camera: np.ndarray, spp: int, sampler: str = "independent") -> dict:
    """Mitsuba's ``perspective`` sensor of ``camera`` at ``world_T_camera`` (OpenCV optical
    frame) as a dict for ``mitsuba.load_dict``, with an ``hdrfilm`` of the camera's size and a
    box filter (each pixel averages its own area, nothing of its neighbours') and ``sampler``
    placing the ``spp`` samples. The transform is a 4 x 4 array: Mitsuba takes it as such."""
    W, H = camera.width, camera.height
    if camera.distortion is not None:  # through a lens: agrisim's own sensor (any fx, fy)
        from .lens_sensor import sensor_fields

        optics = sensor_fields(camera)
    else:
        check_square_pixels(camera)
        optics = {
            "type": "perspective",
            "fov_axis": "x",
            "fov": math.degrees(2.0 * math.atan(W / (2.0 * camera.fx))),
            "principal_point_offset_x": (W / 2.0 - (camera.cx + 0.5)) / W,
            "principal_point_offset_y": (H / 2.0 - (camera.cy + 0.5)) / H,
            "near_clip": 1e-3,
            "far_clip": 1e4,
        }
    return {
        **optics,
        "to_world": np.asarray(world_T_camera, np.float64) @ CV_TO_MITSUBA,
        "film": {
            "type": "hdrfilm",
            "width": W,
            "height": H,
            "pixel_format": "rgb",
            "rfilter": {"type": "box"},
            "sample_border": False,
        },
        "sampler": {"type": sampler, "sample_count": int(spp)},
    }


def load_sensor(mi, camera: CameraModel, world_T_camera: np.ndarray, spp: int, sampler: str = "independent"):  # noqa: ANN001, ANN201 - mitsuba's types
    """:func:`sensor_dict` loaded; ``mi`` is the mitsuba module, its variant set."""
    d = sensor_dict(camera, world_T_camera, spp, sampler)
    d["to_world"] = mi.ScalarTransform4f(d["to_world"])
    if camera.distortion is not None:
        from .lens_sensor import register

        register(mi)
    return mi.load_dict(d)
