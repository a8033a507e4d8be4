"""``agrisim_lens``: a Mitsuba sensor that sees through a lens, each sample's ray the lens's
inverse of the film point it falls on (:mod:`agrisim.scene.lens`, Newton's method in the
kernel, in double precision), so the path tracer's samples anywhere in a pixel leave along the
rays the lens gives them. Mitsuba's own ``perspective`` sensor is a pinhole.

Its frame is Mitsuba's camera frame, as ``perspective``'s (x left, y up, looking along +z:
``to_world = world_T_camera @ CV_TO_MITSUBA``), so the renderer moves it the same way, through
``mi.traverse``'s ``to_world``. A film point (s, t) in [0, 1)^2 is OpenCV's pixel coordinate
(s W - 0.5, t H - 0.5): Mitsuba's pixel i spans [i, i + 1), OpenCV's centre is the integer.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from agrisim.scene.camera import CameraModel
from agrisim.scene.lens import COEFFICIENTS, Distortion

NAME = "agrisim_lens"
_registered: set[str] = set()


def register(mi: Any) -> None:
    """Make ``agrisim_lens`` loadable in Mitsuba's current variant (once per variant)."""
    if mi.variant() in _registered:
        return
    cls = _sensor_class(mi)
    mi.register_sensor(NAME, lambda props: cls(props))
    _registered.add(mi.variant())


def sensor_fields(camera: CameraModel) -> dict[str, Any]:
    """The sensor's own properties of ``camera``: its pinhole and its lens by name."""
    assert camera.distortion is not None
    lens = camera.distortion
    names = COEFFICIENTS[lens.model]
    return {
        "type": NAME,
        "fx": camera.fx,
        "fy": camera.fy,
        "cx": camera.cx,
        "cy": camera.cy,
        "near_clip": 1e-3,
        "lens_model": lens.model,
        **dict(zip(names, lens.coefficients, strict=True)),
    }


def _sensor_class(mi: Any) -> type:
    import drjit as dr

    class LensSensor(mi.Sensor):  # type: ignore[misc,name-defined]
        """A camera through a lens (see the module)."""

        def __init__(self, props: Any) -> None:
            super().__init__(props)
            self.to_world = mi.Transform4f(np.asarray(props.get("to_world").matrix, np.float32))
            self.near_clip = float(props.get("near_clip"))
            model = props.get("lens_model")
            self.camera = CameraModel(
                1,
                1,
                *(float(props.get(k)) for k in ("fx", "fy", "cx", "cy")),
                Distortion(model, tuple(float(props.get(k)) for k in COEFFICIENTS[model])),
            )

        def traverse(self, callback: Any) -> None:
            callback.put("to_world", self.to_world, mi.ParamFlags.NonDifferentiable)

        def parameters_changed(self, keys: Any) -> None:
            pass  # (nothing is derived from to_world)

        def sample_ray(self, time: Any, wavelength: Any, position: Any, aperture: Any, active: Any = True) -> Any:
            size = self.film().crop_size()
            F64 = dr.float64_array_t(mi.Float)
            x, y = self.camera.rays(F64(position.x) * size.x - 0.5, F64(position.y) * size.y - 0.5)
            # OpenCV's (x, y, 1) in Mitsuba's camera frame: x and y flipped
            slope = mi.Vector3f(-mi.Float(x), -mi.Float(y), 1.0)
            wavelengths, weight = self.sample_wavelengths(dr.zeros(mi.SurfaceInteraction3f), wavelength, active)
            # from the near plane, as ``perspective``'s rays (the camera's own housing is behind it)
            origin = self.to_world @ mi.Point3f(slope * self.near_clip)
            return mi.Ray3f(origin, self.to_world @ dr.normalize(slope), time, wavelengths), weight

        def sample_ray_differential(
            self, time: Any, wavelength: Any, position: Any, aperture: Any, active: Any = True
        ) -> Any:
            ray, weight = self.sample_ray(time, wavelength, position, aperture, active)
            return mi.RayDifferential3f(ray), weight  # (no differentials: textures are not mip-mapped)

        def bbox(self) -> Any:
            return mi.ScalarBoundingBox3f()

        def to_string(self) -> str:
            return f"LensSensor[{self.camera.distortion}]"

    return LensSensor
